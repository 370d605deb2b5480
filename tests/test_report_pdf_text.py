"""What a person reads in the demo reports (issue 13): the PDF text, read back with pdfplumber.

Expected values come from the example deliveries' own README (aerial-fail: block B02 RMSEy 0.64 m
against the 0.5 m tolerance of JRC §12.7; one image file missing), not from our output.
"""

from __future__ import annotations

import io
import json
import re
from pathlib import Path
from typing import Any

import pdfplumber
import pytest
import yaml
from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.qcr import all_records
from orthospec.reports.findings import findings

ROOT = Path(__file__).resolve().parents[1]


def _check(tmp: Path, name: str, *extra: str) -> dict[str, Any]:
    out = tmp / name
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(ROOT / "examples" / "deliveries" / name),
            "--profile",
            "jrc-v3",
            "--out",
            str(out),
            "--date",
            "2026-11-21",
            "--format",
            "terminal,json,pdf,csv,junit",
            "--checker",
            str(ROOT / "examples" / "checker" / name),
            *extra,
        ],
    )
    assert res.exit_code in (0, 1), res.output + repr(res.exception)
    with pdfplumber.open(io.BytesIO((out / "report.pdf").read_bytes())) as pdf:
        pages = [p.extract_text() or "" for p in pdf.pages]
    return {
        "out": out,
        "pages": pages,
        "doc": json.loads((out / "qcr.json").read_text(encoding="utf-8")),
        "terminal": res.output,
    }


@pytest.fixture(scope="module")
def fail(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return _check(tmp_path_factory.mktemp("fail"), "aerial-fail", "--operator", "A. Auditor")


@pytest.fixture(scope="module")
def passed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return _check(tmp_path_factory.mktemp("pass"), "aerial-pass")


def test_page1_states_b02_measured_against_required_before_any_error(fail: dict[str, Any]) -> None:
    page1 = fail["pages"][0]
    line = next(ln for ln in page1.splitlines() if "B02" in ln and "RMSEy" in ln)
    assert re.search(r"0\.64\d? m > 0\.5 m", line), line
    assert "§12.7" in page1
    b02 = page1.index(line)
    for marker in ("could not be evaluated", "error"):
        if marker in page1:
            assert page1.index(marker) > b02
    # consequence order: the delivery-level return before the block, the block before an item
    assert (
        page1.index("returns the delivery")
        < page1.index("rejects a block")
        < page1.index("rejects an item")
    )


def test_failures_table_states_values_and_one_root_cause(fail: dict[str, Any]) -> None:
    text = "\n".join(fail["pages"])
    section = text[
        text.index("1. Failures and missing evidence") : text.index("2. Quality control records")
    ]
    assert re.search(r"0\.64\d? m > 0\.5 m", section)
    # the missing image F03_0202 is one finding naming the checks it affects, not nine error rows
    flat = re.sub(r"\s+", "", section)
    assert flat.count("images/F03_0202.tif") == 1, section
    recs = [
        r
        for r in list(all_records(fail["doc"]))
        if r["item"] == "F03_0202"
        and "not found" in r["message"]
        and r["verdict"] != "not_applicable"
    ]  # an aerial item of a satellite-only rule is no finding
    assert len(recs) >= 5
    root = [
        f
        for f in findings(list(all_records(fail["doc"])))
        if "F03_0202" in f.items and "not found" in f.what
    ]
    assert len(root) == 1 and set(root[0].rules) == {r["rule"] for r in recs}


def test_no_page_lists_not_applicable_rows(fail: dict[str, Any], passed: dict[str, Any]) -> None:
    for run in (fail, passed):
        n_na = run["doc"]["summary"]["not_applicable"]
        assert n_na > 100  # the records stay in qcr.json
        text = "\n".join(run["pages"])
        assert text.count("not applicable:") == 0
        assert "Not applicable to this delivery" in text
        assert "applies only when the sensor type is 'satellite'" in text


def test_aerial_pass_report_is_at_most_14_pages(passed: dict[str, Any]) -> None:
    # 12 until issues 25/26 added rules (measured-vs-declared GSD, location, cloud, statistics, DEM, camera;
    # acquisition window, point ids, QCR set...) and their parameters
    # 14 once both rule sets met on main; 15 with the map of the findings (issue 30), one page of its own
    assert len(passed["pages"]) <= 15


def test_checker_and_contractor_operator_are_separate(
    fail: dict[str, Any], passed: dict[str, Any]
) -> None:
    assert fail["doc"]["operator"] == "A. Auditor"
    assert fail["doc"]["delivery"]["operator"]["role"] == "contractor QA manager"
    page1 = fail["pages"][0]
    assert "A. Auditor (contractor QA manager)" not in page1.replace("\n", " ")
    assert re.search(r"Checker \(ran orthospec,.*A\. Auditor", page1.replace("\n", " "))
    # without --operator the checker is the party of the checker's folder (examples/checker/aerial-pass/),
    # named with that file and its SHA-256; the contractor's operator is never named as the checker
    assert passed["doc"]["operator"] is None
    p1 = passed["pages"][0].replace("\n", " ")
    contractor_op = passed["doc"]["delivery"]["operator"]["name"]
    party = yaml.safe_load(
        (ROOT / "examples" / "checker" / "aerial-pass" / "checker.yaml").read_text(encoding="utf-8")
    )["checker"]
    assert re.search(
        rf"Checker \(ran orthospec,.*{re.escape(party['name'])}.*checker's folder aerial-pass, "
        r"checker\.yaml",
        p1,
    )
    assert contractor_op in p1 and contractor_op != party["name"]
    assert not re.search(rf"Checker \(generated the QCRs\) {re.escape(contractor_op)}", p1)
    assert f"checker: {party['name']}" in passed["terminal"]
    # with --operator both are named: who ran the check, and whose file decided the manual checks
    assert f"A. Auditor; {party['name']}" in fail["pages"][0].replace("\n", " ")


def test_terminal_states_reasons_and_is_not_cut(fail: dict[str, Any]) -> None:
    out = fail["terminal"]
    assert re.search(
        r"B02: Block RMSEy within the tolerance: 0\.64\d? m > 0\.5 m", out.replace("\n", " ")
    )
    assert not re.search(r"…\s*$", out, re.M)  # nothing cut at the line end


def test_csv_and_junit_of_the_demo_are_well_formed(fail: dict[str, Any]) -> None:
    import csv
    import xml.dom.minidom

    rows = list(csv.reader(io.StringIO((fail["out"] / "qcr.csv").read_text(encoding="utf-8"))))
    assert len(rows) == fail["doc"]["summary"]["records"] + 1
    xml.dom.minidom.parseString((fail["out"] / "junit.xml").read_bytes())


def test_one_checkpoint_map_page_per_block_with_outline_and_scales(passed: dict[str, Any]) -> None:
    """Issue 13 item 2: several blocks, one page each: its statistics and its map with both scales."""
    blocks = sorted(passed["doc"]["details"]["checkpoints"])
    assert len(blocks) == 3  # aerial-pass has B01..B03 (its delivery.yaml)
    flat = [re.sub(r"\s+", "", p) for p in passed["pages"]]
    map_pages = []
    for b in blocks:
        assert passed["doc"]["details"]["checkpoints"][b]["polygon"]  # the outline is in qcr.json
        hits = [i for i, p in enumerate(flat) if f"Block{b}:checkpointsanddiscrepancies" in p]
        assert len(hits) == 1, (b, hits)
        page = flat[hits[0]]
        assert f"Block{b}" in page and "RMSE" in page  # the block's statistics on the same page
        assert not any(f"Block{o}:checkpointsanddiscrepancies" in page for o in blocks if o != b)
        assert re.search(r"\d+mdiscrepancy\(vectors×[\d.]+\)", page)  # vectors to a stated scale
        assert (
            re.search(r"\)\d+(\.\d+)?m", page) and "blockoutline" in page
        )  # ground scale bar, outline
        map_pages.append(hits[0])
    assert map_pages == sorted(set(map_pages))


def _splits(text: str, name: str) -> list[str]:
    """Places where ``name`` appears in ``text`` broken by a line end/space at a non-separator."""
    pat = "(?<![\\w.-])" + "".join(
        re.escape(c) + (r"(\s*)" if k < len(name) - 1 else "") for k, c in enumerate(name)
    )
    return [
        f"{name[: k + 1]}|{name[k + 1 :]}"
        for m in re.finditer(pat, text)
        for k, g in enumerate(m.groups())
        if g and name[k] not in "-_."
    ]


def test_identifiers_break_only_after_separators(
    fail: dict[str, Any], passed: dict[str, Any]
) -> None:
    """Issue 13: `reported_rmse_toler ance`. Rule ids, measure and parameter names break only after _ . -"""
    for run in (fail, passed):
        doc, text = run["doc"], "\n".join(run["pages"])
        names = {r["rule"] for r in all_records(doc)} | {
            r["measure"] for r in all_records(doc) if r.get("measure")
        }
        names |= set(doc["profile"].get("parameters") or {})
        assert {"camera_calibration_max_age_digital", "reported_rmse_tolerance"} <= names
        bad = [s for n in sorted(names) if len(n) > 3 for s in _splits(text, n)]
        assert not bad, bad
        # every rule id of the findings is printed (whole, or split only at a separator)
        flat = re.sub(r"\s+", "", text)
        for f in findings(list(all_records(doc))):
            for rule in f.rules[:8]:
                assert rule in flat, rule
