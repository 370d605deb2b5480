"""The tender author's side of issue 26 and issue 25 item 7, one test per observation.

- The contract wins: a tender's value is not replaced by the checker's file or --param unless the
  tender marks the parameter `checker_may_set`; a value in force that is not the profile's is printed
  on page 1 and in the terminal header (observation: a tender's mandatory 5 % cloud cap was checked
  at 10 % with no warning).
- A tender cannot disable a mandatory rule silently: removal, `level: recommended`, a new `when`, a
  swapped measure need a justification, and spec diff, the annex's first page and page 1 of the
  report list the change.
- Shipped profile ids are reserved (a file `id: jrc-v3` that switched RMSEy off was reported as jrc-v3).
- Annex and report details: the satellite tender's annex without --sensor, unset ITT parameters on
  page 1, `spec render` never writing into a checkout or a delivery, the PDF findings table, the
  terminal's advice when the checker's file was given, internal notes never printed.
"""

from __future__ import annotations

import contextlib
import io
import itertools
import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pdfplumber
import pytest
import yaml

from checking import resigned
from orthospec.profile.loader import load_profile
from orthospec.reports.annex import annex_filename, render_annex
from orthospec.reports.findings import unsigned_manual_note

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
DATE = "2026-11-21"


@dataclass
class Ran:
    exit_code: int
    output: str


def run(*args: Any) -> Ran:
    """`orthospec ARGS` through the real entry point (its error mapping and exit codes), in-process."""
    from orthospec.cli.main import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
    return Ran(code, buf.getvalue())


TENDER = """\
orthospec_profile: 1
id: itt-cloud
version: 1.0.0
title: ITT 2026/26 - aerial orthoimagery, contractual 5 % cloud cap
source: {title: Invitation to tender 2026/26, identifier: ITT-2026-26}
extends: {id: jrc-v3, version: 3.0.0}
parameters:
  tolerance_xy: {value: 0.5}
  map_crs: {value: "EPSG:25832"}
  cloud_cover_max:
    value: 5
    description: "ITT §5.3: no image with more than 5 % cloud cover."{mark}
remove_rules:
  - {id: JRC-12.4-T12-ORTHO-OWN-FILE, justification: "ITT §7.2: tiles are checked by the agency's own tool"}
rules:
  - id: JRC-6.3-CLOUD-COVER
    override: true
    level: mandatory
    consequence: reject_item
  - id: JRC-12.7-RMSEX
    override: true
    when: "manifest.sensor.digital == true"
    justification: "ITT §4.1: film imagery is not bought under this lot"
"""


def tender(folder: Path, *, checker_may_set: bool) -> Path:
    path = folder / "itt-cloud.yaml"
    mark = "\n    checker_may_set: true" if checker_may_set else ""
    path.write_text(TENDER.replace("{mark}", mark), encoding="utf-8")
    return path


def checker_with_cloud(folder: Path, value: float) -> Path:
    """The aerial-fail checker's file stating a cloud cap (the ITT values it had, plus this one)."""
    base = yaml.safe_load(
        (EXAMPLES / "checker" / "aerial-fail" / "checker.yaml").read_text(encoding="utf-8")
    )
    params = {**base["parameters"], "cloud_cover_max": {"value": value, "unit": "%"}}
    return resigned(
        EXAMPLES / "checker" / "aerial-fail",
        EXAMPLES / "deliveries" / "aerial-fail",
        folder / "checker-cloud.yaml",
        parameters=params,
    )


# --- the contract wins -------------------------------------------------------------------------------


def test_the_checkers_file_cannot_loosen_a_tender_value(tmp_path: Path) -> None:
    """Observation: the tender made the 5 % cap mandatory; the checker's file said 10 % and the check
    ran at 10 % without a word. Now: exit 2 naming both values and the tender's line."""
    prof = tender(tmp_path, checker_may_set=False)
    res = run(
        "check",
        EXAMPLES / "deliveries" / "aerial-fail",
        "-p",
        prof,
        "--checker",
        checker_with_cloud(tmp_path, 10),
        "--out",
        tmp_path / "out",
        "--date",
        DATE,
    )
    assert res.exit_code == 2, res.output
    assert "parameters.cloud_cover_max: 10 % differs from 5 %" in res.output
    assert "itt-cloud.yaml:11" in res.output and "checker_may_set: true" in res.output
    assert not (tmp_path / "out").exists()
    res = run(
        "check",
        EXAMPLES / "deliveries" / "aerial-fail",
        "-p",
        prof,
        "--checker",
        EXAMPLES / "checker" / "aerial-fail",
        "--param",
        "cloud_cover_max=10",
        "--out",
        tmp_path / "out",
        "--date",
        DATE,
    )
    assert (
        res.exit_code == 2 and "--param cloud_cover_max=10: 10 % differs from 5 %" in res.output
    ), res.output
    # the same value stated again is no conflict: 5 % from the checker's file runs
    res = run(
        "check",
        EXAMPLES / "deliveries" / "aerial-fail",
        "-p",
        prof,
        "--checker",
        checker_with_cloud(tmp_path, 5.0),
        "--out",
        tmp_path / "same",
        "--date",
        DATE,
        "--format",
        "json",
    )
    assert res.exit_code == 1, res.output


@pytest.fixture(scope="module")
def allowed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """aerial-fail under a tender that leaves cloud_cover_max to the checker, whose file says 10 %,
    and that removed one mandatory rule and gated another, both justified."""
    tmp = tmp_path_factory.mktemp("allowed")
    prof = tender(tmp, checker_may_set=True)
    out = tmp / "out"
    res = run(
        "check",
        EXAMPLES / "deliveries" / "aerial-fail",
        "-p",
        prof,
        "--checker",
        checker_with_cloud(tmp, 10),
        "--out",
        out,
        "--date",
        DATE,
        "--format",
        "terminal,json,html,pdf",
    )
    assert res.exit_code == 1, res.output + repr(res.exception)
    with pdfplumber.open(io.BytesIO((out / "report.pdf").read_bytes())) as pdf:
        pages = [p.extract_text() or "" for p in pdf.pages]
        words = [p.extract_words() for p in pdf.pages]
    return {
        "terminal": res.output,
        "doc": json.loads((out / "qcr.json").read_text(encoding="utf-8")),
        "pages": pages,
        "words": words,
        "html": (out / "report.html").read_text(encoding="utf-8"),
        "profile": prof,
    }


def test_a_value_the_tender_leaves_to_the_checker_is_used_and_shown_beside_the_tenders(
    allowed: dict,
) -> None:
    p = allowed["doc"]["profile"]["parameters"]["cloud_cover_max"]
    assert (p["value"], p["source"], p["profile_value"]) == (10.0, "checker", 5.0)
    line = "cloud_cover_max = 10 % from the checker's file, instead of the tender's 5 %"
    assert line in allowed["terminal"].replace("\n", " ")
    head = allowed["terminal"].split("verdict:")[0]
    assert head.index(line[:20]) < head.index("rules,")  # header, before the findings and counts
    page1 = " ".join(allowed["pages"][0].split())
    assert line in page1


def test_mandatory_rules_the_tender_weakened_are_on_page_1_and_in_the_terminal(
    allowed: dict,
) -> None:
    weakened = {w["id"]: w for w in allowed["doc"]["profile"]["weakened"]}
    assert weakened["JRC-12.4-T12-ORTHO-OWN-FILE"]["changes"] == ["removed"]
    assert weakened["JRC-12.7-RMSEX"]["changes"] == [
        "condition added: when manifest.sensor.digital == true"
    ]
    assert weakened["JRC-12.7-RMSEX"]["justification"].startswith("ITT §4.1")
    page1 = " ".join(allowed["pages"][0].split())
    terminal = " ".join(allowed["terminal"].split())
    for text in (page1, terminal):
        assert (
            "JRC-12.4-T12-ORTHO-OWN-FILE" in text
            and "tiles are checked by the agency's own tool" in text
        )
        assert "JRC-12.7-RMSEX" in text and "film imagery is not bought under this lot" in text


def test_pdf_findings_table_consequence_stays_in_its_column(allowed: dict) -> None:
    """Observation: "returns the delivery" ran over the item column of the findings table. No two
    words of any page overlap (positions read back with pdfplumber)."""
    assert any("returns the delivery" in " ".join(p.split()) for p in allowed["pages"])
    for n, words in enumerate(allowed["words"], 1):
        rows: dict[int, list[dict]] = {}
        for w in words:
            rows.setdefault(round(w["top"]), []).append(w)
        for row in rows.values():
            row.sort(key=lambda w: w["x0"])
            for a, b in itertools.pairwise(row):
                assert a["x1"] <= b["x0"] + 0.5, f"page {n}: {a['text']!r} runs into {b['text']!r}"


def test_qcr_names_the_profile_by_id_version_and_resolved_sha256(allowed: dict) -> None:
    p = allowed["doc"]["profile"]
    prof = load_profile(allowed["profile"])
    assert (p["id"], p["version"], p["sha256"]) == ("itt-cloud", "1.0.0", prof.sha256)
    assert p["extends"] == [{"id": "jrc-v3", "version": "3.0.0"}]


def test_without_a_tender_the_checkers_itt_values_are_shown_as_filled_in(tmp_path: Path) -> None:
    from orthospec.reports.contract import parameter_lines

    doc = {
        "profile": {
            "parameters": {
                "tolerance_xy": {"value": 0.5, "unit": "m", "source": "checker"},
                "cloud_cover_max": {"value": 10.0, "unit": "%", "source": "standard"},
                "min_checkpoints": {
                    "value": 10.0,
                    "unit": "1",
                    "source": "cli",
                    "profile_value": 20.0,
                },
            }
        }
    }
    assert parameter_lines(doc) == [
        "min_checkpoints = 10 from --param, instead of the profile's 20",
        "tolerance_xy = 0.5 m from the checker's file (the profile leaves it to the ITT)",
    ]


# --- weakening a mandatory rule: spec diff and the annex --------------------------------------------

WEAK = """\
orthospec_profile: 1
id: itt-weak
version: 1.0.0
title: ITT weakening four mandatory rules, each with its reason
source: {title: ITT, identifier: ITT-W}
extends: {id: jrc-v3, version: 3.0.0}
parameters:
  tolerance_xy: {value: 0.5}
remove_rules:
  - {id: JRC-12.7-RMSEY, justification: "ITT §4.1: only X is contracted"}
rules:
  - id: JRC-12.7-RMSEX
    override: true
    level: recommended
    justification: "ITT §4.2: X is advisory"
  - id: JRC-12.4-T12-ORTHO-OWN-FILE
    override: true
    when: "1 == 1 and manifest.sensor.digital == false"
    justification: "ITT §7: only film copies are compared"
  - id: JRC-DEF-CHECKPOINT-ACCURACY
    override: true
    measure: checkpoints.count
    scope: delivery
    requirement: {op: ">=", value: 0, unit: "1"}
    justification: "ITT §4.3: the checker's survey is trusted"
"""


def test_spec_diff_lists_each_weakened_mandatory_rule_with_its_justification(
    tmp_path: Path,
) -> None:
    f = tmp_path / "weak.yaml"
    f.write_text(WEAK, encoding="utf-8")
    text = run("spec", "diff", "jrc-v3", f)
    assert text.exit_code == 0, text.output
    lines = [x for x in text.output.splitlines() if x.startswith("! mandatory rule")]
    assert len(lines) == 4, text.output
    assert any("JRC-12.7-RMSEY checks less: removed (justification: ITT §4.1" in x for x in lines)
    assert any("JRC-12.7-RMSEX checks less: level mandatory -> recommended" in x for x in lines)
    assert any("JRC-12.4-T12-ORTHO-OWN-FILE checks less: condition when " in x for x in lines)
    assert any(
        "JRC-DEF-CHECKPOINT-ACCURACY checks less: measure checkpoints.rmse_xy" in x
        or "JRC-DEF-CHECKPOINT-ACCURACY checks less: measure " in x
        for x in lines
    )
    js = run("spec", "diff", "jrc-v3", f, "--json")
    got = {w["id"]: w for w in json.loads(js.output)["weakened"]}
    assert set(got) == {
        "JRC-12.7-RMSEY",
        "JRC-12.7-RMSEX",
        "JRC-12.4-T12-ORTHO-OWN-FILE",
        "JRC-DEF-CHECKPOINT-ACCURACY",
    }
    assert (
        got["JRC-DEF-CHECKPOINT-ACCURACY"]["justification"]
        == "ITT §4.3: the checker's survey is trusted"
    )
    assert any(c.startswith("measure ") for c in got["JRC-DEF-CHECKPOINT-ACCURACY"]["changes"])
    # the annex's first page lists them (before the parameters chapter)
    md = render_annex(load_profile(f), formats=["md"], day=DATE)[
        annex_filename(load_profile(f), "md")
    ]
    cover = md.split("## 1. Parameters")[0]
    assert "Mandatory requirements of the standard that this ITT removes or relaxes" in cover
    for rid in got:
        assert f"`{rid}`" in cover
    assert "only X is contracted" in cover and "level mandatory -> recommended" in cover


def test_an_unrelated_pair_is_compared_too_and_says_nobody_justified_it(tmp_path: Path) -> None:
    from orthospec.profile.diff import weakened

    mini = load_profile(ROOT / "tests" / "data" / "profiles" / "mini.yaml")
    other = tmp_path / "mini2.yaml"
    other.write_text(
        (ROOT / "tests" / "data" / "profiles" / "mini.yaml")
        .read_text(encoding="utf-8")
        .replace("id: mini", "id: mini2")
        .replace(
            "    consequence: reject_item\n", "    level: recommended\n    consequence: warn\n"
        ),
        encoding="utf-8",
    )
    got = weakened(mini, load_profile(other, check_measures=False))
    assert got and all(w["justification"] is None for w in got)
    assert [w["changes"] for w in got] == [
        ["level mandatory -> recommended", "consequence reject_item -> warn"]
    ] * 2


# --- reserved ids -------------------------------------------------------------------------------------


def test_a_file_claiming_a_shipped_id_is_refused_naming_the_file(tmp_path: Path) -> None:
    """Observation (issue 25): `id: jrc-v3, version: 3.0.1` extending jrc-v3 with RMSEy switched off
    was reported as jrc-v3 and ACCEPTED."""
    fake = tmp_path / "fake.yaml"
    fake.write_text(
        "orthospec_profile: 1\nid: jrc-v3\nversion: 3.0.1\ntitle: JRC\nsource: {title: x}\n"
        "extends: {id: jrc-v3, version: 3.0.0}\nparameters:\n  tolerance_xy: {value: 0.5}\n"
        "remove_rules: [{id: JRC-12.7-RMSEY, justification: x}]\n",
        encoding="utf-8",
    )
    res = run("spec", "validate", fake)
    assert res.exit_code == 2 and "fake.yaml:2:5: id 'jrc-v3' is reserved" in res.output, res.output
    res = run(
        "check",
        EXAMPLES / "deliveries" / "aerial-pass",
        "-p",
        fake,
        "--checker",
        EXAMPLES / "checker" / "aerial-pass",
        "--out",
        tmp_path / "out",
    )
    assert res.exit_code == 2 and "fake.yaml" in res.output and "reserved" in res.output
    # a copy that is the shipped profile (same resolved content, other bytes) is that profile
    copy = tmp_path / "copy.yaml"
    copy.write_text(
        yaml.safe_dump(
            yaml.safe_load((ROOT / "specs" / "jrc-v3.yaml").read_text(encoding="utf-8")),
            sort_keys=False,
            allow_unicode=True,
        ),
        encoding="utf-8",
    )
    assert load_profile(copy).sha256 == load_profile("jrc-v3").sha256


# --- the annex ----------------------------------------------------------------------------------------

SATELLITE = """\
orthospec_profile: 1
id: itt-sat
version: 1.0.0
title: ITT satellite orthoimagery
source: {title: ITT, identifier: ITT-SAT}
extends: {id: jrc-v3, version: 3.0.0}
parameters:
  tolerance_xy: {value: 2.5}
  map_crs: {value: "EPSG:32633"}
  ortho_pixel_size: {value: 0.5}
rules:
  - id: ITT-1-SATELLITE
    title: Satellite imagery
    clause: {document: ITT-SAT, section: "1"}
    quote: "Satellite imagery shall be delivered."
    scope: delivery
    measure: manifest.sensor.type
    requirement: {op: "==", value: satellite}
    consequence: return_delivery
"""


def test_a_satellite_tender_annex_holds_satellite_rules_without_being_told(tmp_path: Path) -> None:
    """Observation: without --sensor, aerial rules landed in the body of a satellite tender's annex."""
    f = tmp_path / "sat.yaml"
    f.write_text(SATELLITE, encoding="utf-8")
    prof = load_profile(f)
    name = annex_filename(prof, "md")
    told = render_annex(prof, formats=["md"], day=DATE, sensor="satellite")[name]
    untold = render_annex(prof, formats=["md"], day=DATE)[name]
    assert untold == told
    body = untold.split("## 2. Requirements")[1].split("## Appendix A")[0]
    aerial_only = [
        r.id for r in prof.rules if r.when and "manifest.sensor.type == 'aerial'" in r.when
    ]
    assert aerial_only and not [r for r in aerial_only if f"`{r}`" in body]
    assert "JRC-T9-MASTER-IDENTIFIED" in body


def test_annex_page_1_warns_about_itt_parameters_left_unset(tmp_path: Path) -> None:
    """Observation: tolerance_z and master_images left unset rendered without a warning."""
    f = tmp_path / "sat.yaml"
    f.write_text(SATELLITE, encoding="utf-8")
    prof = load_profile(f)
    files = render_annex(prof, formats=["md", "pdf"], day=DATE)
    cover = files[annex_filename(prof, "md")].split("## 1. Parameters")[0]
    assert "parameter(s) the ITT must fix have no value" in cover
    assert "`tolerance_z` (m)" in cover and "`master_images`" in cover
    with pdfplumber.open(io.BytesIO(files[annex_filename(prof, "pdf")])) as pdf:
        page1 = " ".join((pdf.pages[0].extract_text() or "").split())
    assert (
        "the ITT must fix have no value" in page1
        and "tolerance_z" in page1
        and "master_images" in page1
    )
    # an aerial tender that fixed what it uses gets no warning, and master_images (satellite) is not its
    aerial = load_profile(ROOT / "examples" / "specs" / "tender-example.yaml")
    md = render_annex(aerial, formats=["md"], day=DATE)[annex_filename(aerial, "md")]
    assert "must fix have no value" not in md


def test_a_tender_in_metres_prints_numbers_not_formulas(tmp_path: Path) -> None:
    """Observation: with `unit: meters` the annex printed `tolerance_xy / gcp_accuracy_factor`; the
    spelling is refused now (tests/test_tender_mistakes.py) and `m` gives the number."""
    prof = load_profile(ROOT / "examples" / "specs" / "tender-example.yaml")
    md = render_annex(prof, formats=["md"], day=DATE)[annex_filename(prof, "md")]
    row = next(x for x in md.splitlines() if x.startswith("| `JRC-7.1-GCP-ACCURACY-3X`"))
    assert "0.166667 m" in row and "gcp_accuracy_factor" not in row


def _checkout(tmp_path: Path) -> Path:
    root = tmp_path / "checkout"
    (root / ".git").mkdir(parents=True)
    (root / "pyproject.toml").write_text('[project]\nname = "orthospec"\n', encoding="utf-8")
    (root / "specs").mkdir()
    return root


def test_spec_render_without_out_never_writes_into_the_current_folder(
    tmp_path: Path, monkeypatch
) -> None:
    """Observation: `spec render` without --out wrote into the current folder (a checkout)."""
    root = _checkout(tmp_path)
    monkeypatch.chdir(root / "specs")
    res = run("spec", "render", "jrc-v3", "--format", "md", "--date", DATE)
    assert res.exit_code == 0, res.output
    assert (root / "reports" / "annex" / "annex-jrc-v3-3.0.0.md").is_file()
    assert [p.name for p in (root / "specs").iterdir()] == []
    # inside a delivery: refused, nothing written
    d = tmp_path / "delivery"
    shutil.copytree(EXAMPLES / "deliveries" / "aerial-pass", d)
    monkeypatch.chdir(d / "tables")
    before = sorted(p.name for p in d.rglob("*"))
    res = run("spec", "render", "jrc-v3", "--format", "md", "--date", DATE)
    assert res.exit_code == 2 and "inside the delivery" in res.output and "--out" in res.output
    assert sorted(p.name for p in d.rglob("*")) == before
    # anywhere else: reports/annex/ under the current folder
    elsewhere = tmp_path / "work"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert run("spec", "render", "jrc-v3", "--format", "md", "--date", DATE).exit_code == 0
    assert [p.name for p in elsewhere.iterdir()] == ["reports"]
    assert (elsewhere / "reports" / "annex" / "annex-jrc-v3-3.0.0.md").is_file()


# --- notes: public and internal -----------------------------------------------------------------------

NOTES = """\
orthospec_profile: 1
id: itt-notes
version: 1.0.0
title: ITT notes
source: {title: ITT, identifier: ITT-N}
extends: {id: jrc-v3, version: 3.0.0}
parameters:
  tolerance_xy: {value: 0.5}
rules:
  - id: JRC-12.7-RMSEX
    override: true
    note: "Public: the block's RMSEx from every independent check point. A disagreement rejects the block."
    internal_note: "INTERNAL-7f3a: red team R4 asked for this; see issue 12 and tests/test_x.py."
"""


def test_an_internal_note_is_never_printed_and_a_public_note_is_printed_whole(
    tmp_path: Path,
) -> None:
    f = tmp_path / "notes.yaml"
    f.write_text(NOTES, encoding="utf-8")
    prof = load_profile(f)
    files = render_annex(prof, formats=["md", "html"], day=DATE)
    explain = run("explain", "JRC-12.7-RMSEX", "--profile", f)
    assert explain.exit_code == 0, explain.output
    for text in (*files.values(), explain.output):
        assert "INTERNAL-7f3a" not in text and "R4 asked" not in text
        assert "A disagreement rejects the block." in " ".join(str(text).split())


def test_the_terminal_does_not_ask_for_the_checkers_file_when_one_was_given() -> None:
    """Observation: "give the checker's file" was printed although --checker was given."""
    records = [{"manual": True, "verdict": "missing", "rule": "JRC-5.3-IDQA", "item": "*"}]
    given = unsigned_manual_note(records, checker={"file": "qc-lot2.yaml", "name": "M. Keller"})
    assert given is not None and "give the checker's file" not in given
    assert "qc-lot2.yaml has no manual_checks entry" in given
    assert "give the checker's file with --checker FILE" in (unsigned_manual_note(records) or "")


def test_the_guides_say_truly_which_parameters_need_a_justification(tmp_path: Path) -> None:
    """Observation: docs/PROFILES.md said cloud_cover_max needs a justification to change; it does not
    (jrc-v3 leaves it to the ITT). Every such remark in the guides names a parameter of that kind."""
    import re

    jrc = load_profile("jrc-v3")
    seen = 0
    for doc in (ROOT / "docs" / "PROFILES.md", ROOT / "README.md"):
        for name, remark in re.findall(
            r"(?m)^\s+(\w+):[^#\n]*#\s*(.*)$", doc.read_text(encoding="utf-8")
        ):
            if name not in jrc.parameters:
                continue
            if "needs a justification" in remark:
                assert jrc.parameters[name].authority() == "standard", (doc.name, name)
                seen += 1
            elif "left to the ITT" in remark:
                assert jrc.parameters[name].authority() == "itt", (doc.name, name)
                seen += 1
    assert seen >= 3
    # and validation agrees: a constant of the standard changed without a reason is refused, a value
    # left to the ITT is not
    from orthospec.profile.loader import validate_file

    head = (
        "orthospec_profile: 1\nid: itt-j\nversion: 1.0.0\ntitle: t\nsource: {title: t}\n"
        "extends: {id: jrc-v3, version: 3.0.0}\nparameters:\n  tolerance_xy: {value: 0.5}\n"
    )
    f = tmp_path / "j.yaml"
    f.write_text(head + "  cloud_cover_max: {value: 5}\n", encoding="utf-8")
    assert validate_file(f) == []
    f.write_text(head + "  sun_elevation_min: {value: 35}\n", encoding="utf-8")
    assert ["justification" in p.message for p in validate_file(f)] == [True]
