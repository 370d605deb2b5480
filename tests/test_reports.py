"""Auditor reports (HTML, PDF/A-3b) rendered from real checks, read back with pypdf/pdfplumber."""

from __future__ import annotations

import hashlib
import io
import json
import re
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pdfplumber
import pytest
import yaml
from click.testing import CliRunner
from pypdf import PdfReader

from orthospec.cli.main import cli
from orthospec.errors import ReportError
from orthospec.qcr import all_records, point_rows
from orthospec.reports import document as reportdoc
from orthospec.reports.fetcher import SafeFetcher, data_uri
from orthospec.reports.html import ReportOptions, document_sha256, render_html
from orthospec.reports.pdf import write_pdf
from orthospec.resources import templates_dir

PROFILE = """\
orthospec_profile: 1
id: report-test
version: 1.2.0
title: Report test profile
source: {title: JRC Guidelines, identifier: EUR 23638 EN, seed: 002_7421c4ca450e31c6.txt}
parameters:
  tolerance_xy: {unit: m, required: true, description: Tolerable planimetric RMSE per axis}
  max_roll: {unit: deg, default: 3, description: Maximum roll}
rules:
  - id: R-ROLL
    title: Roll within limit
    clause: {document: JRC EUR 23638 EN, section: "5.2.4"}
    quote: "Roll and drift"
    scope: image
    measure: images.roll
    requirement: {op: "<=", value: max_roll, unit: deg}
    consequence: reject_item
  - id: R-RMSEX
    title: Block RMSEx within the tolerance
    clause: {document: JRC EUR 23638 EN, section: "12.7"}
    quote: "The planimetric threshold will be applied independently in X, and Y."
    scope: block
    measure: checkpoints.rmse_x
    requirement: {op: "<=", value: tolerance_xy, unit: m}
    consequence: reject_block
  - id: R-RMSEY
    title: Block RMSEy within the tolerance
    clause: {document: JRC EUR 23638 EN, section: "12.7"}
    quote: "Failure to meet the specification in either of these two dimensions will reject the block."
    scope: block
    measure: checkpoints.rmse_y
    requirement: {op: "<=", value: tolerance_xy, unit: m}
    consequence: reject_block
  - id: R-NPTS
    title: At least 20 check points per block
    clause: {document: JRC EUR 23638 EN, section: "12.5"}
    quote: "a minimum of 20 points"
    scope: block
    measure: checkpoints.n
    requirement: {op: ">=", value: 20, unit: "1"}
    consequence: reject_block
  - id: R-SEAM
    title: Seamlines visually inspected
    clause: {document: JRC EUR 23638 EN, section: "6.4", table: "11"}
    quote: "Seamlines should be checked visually"
    scope: delivery
    measure: manual.R-SEAM
    manual: true
    requirement: {op: "==", value: pass}
    consequence: return_delivery
"""

IMAGES = """\
image_id,file,block,roll
I1,images/i1.tif,B1,0.5
I2,images/i2.tif,B1,4.5
I3,images/i3.tif,B2,1.0
"""


def _manifest(**over: Any) -> dict[str, Any]:
    m: dict[str, Any] = {
        "orthospec_delivery": 1,
        "id": "D-REP-1",
        "project": {"id": "P1", "name": "Report project", "crs": "EPSG:25832"},
        "contractor": {"name": "ACME Mapping"},
        "operator": {"name": "Jane Doe", "role": "QA"},
        "sensor": {"type": "aerial", "digital": True},
        "product": {"gsd": {"value": 0.25, "unit": "m"}},
        "tender": {
            "reference": "ITT-1",
            "parameters": {"tolerance_xy": {"value": 0.5, "unit": "m"}},
        },
        "blocks": [{"id": "B1"}, {"id": "B2"}],
        "tables": {
            "images": "tables/images.csv",
            "checkpoints": "tables/checkpoints.csv",
            "gcps": "tables/gcps.csv",
        },
    }
    m.update(over)
    return m


def write_delivery(root: Path, **manifest: Any) -> Path:
    """Two blocks of 22 check points: B1 within 0.5 m with one blunder, B2 well outside."""
    rng = np.random.default_rng(7)
    (root / "tables").mkdir(parents=True)
    (root / "delivery.yaml").write_text(
        yaml.safe_dump(_manifest(**manifest), sort_keys=False), encoding="utf-8"
    )
    (root / "tables" / "images.csv").write_text(IMAGES, encoding="utf-8")
    cp = ["point_id,block,x,y,x_ref,y_ref"]
    gcp = ["point_id,block,x,y"]
    for b, (x0, sigma) in {"B1": (500000.0, 0.12), "B2": (510000.0, 0.9)}.items():
        xs = x0 + rng.uniform(0, 5000, 22)
        ys = 5400000.0 + rng.uniform(0, 5000, 22)
        dx, dy = rng.normal(0, sigma, 22), rng.normal(0, sigma, 22)
        if b == "B1":
            dx[5] = 1.6  # a blunder: beyond three times the RMSE
        for i in range(22):
            cp.append(
                f"{b}-C{i + 1:02d},{b},{xs[i] + dx[i]:.3f},{ys[i] + dy[i]:.3f},{xs[i]:.3f},{ys[i]:.3f}"
            )
        for j, (gx, gy) in enumerate([(0, 0), (5000, 0), (0, 5000), (5000, 5000)]):
            gcp.append(f"{b}-G{j + 1},{b},{x0 + gx:.3f},{5400000.0 + gy:.3f}")
    (root / "tables" / "checkpoints.csv").write_text("\n".join(cp) + "\n", encoding="utf-8")
    (root / "tables" / "gcps.csv").write_text("\n".join(gcp) + "\n", encoding="utf-8")
    return root


def run_check(tmp: Path, delivery: Path, fmts: str = "json,html,pdf") -> Path:
    profile = tmp / "profile.yaml"
    profile.write_text(PROFILE, encoding="utf-8")
    out = tmp / "out"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(delivery),
            "--profile",
            str(profile),
            "--out",
            str(out),
            "--date",
            "2026-01-01",
            "--format",
            fmts,
            "--param",
            "tolerance_xy=0.5m",
        ],
    )  # the ITT value (manifest: evidence only)
    assert res.exit_code in (0, 1), res.output + str(res.exception)
    return out


def pdf_pages(data: bytes) -> list[str]:
    with pdfplumber.open(io.BytesIO(data)) as pdf:
        return [page.extract_text() or "" for page in pdf.pages]


def pdf_text(data: bytes) -> str:
    return "\n".join(pdf_pages(data))


def attachments(data: bytes) -> dict[str, bytes]:
    return {name: contents[0] for name, contents in PdfReader(io.BytesIO(data)).attachments.items()}


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One real check of the two-block delivery with qcr.json, report.html and report.pdf written."""
    tmp = tmp_path_factory.mktemp("report")
    out = run_check(tmp, write_delivery(tmp / "delivery"))
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    pdf = (out / "report.pdf").read_bytes()
    pages = pdf_pages(pdf)
    return {
        "out": out,
        "doc": doc,
        "pdf": pdf,
        "pages": pages,
        "text": "\n".join(pages),
        "html": (out / "report.html").read_text(encoding="utf-8"),
    }


# --- content --------------------------------------------------------------------------------------


def test_pdf_states_verdict_failures_and_clauses(checked: dict[str, Any]) -> None:
    doc, text = checked["doc"], checked["text"]
    assert doc["verdict"] == "rejected"
    assert "REJECTED" in text
    failing = {
        r["rule"]: r for r in all_records(doc) if r["verdict"] in ("fail", "missing", "error")
    }
    assert {"R-ROLL", "R-SEAM"} <= set(failing)  # the fixture does fail and lack evidence
    for rid, rec in failing.items():
        assert rid in text
        assert f"§{rec['clause']['section']}" in text
        assert rec["item"] in text
    assert "ACME Mapping" in text and "D-REP-1" in text
    assert doc["profile"]["sha256"] in text.replace("\n", "")


def test_pdf_lists_manual_checks_to_sign(checked: dict[str, Any]) -> None:
    text = checked["text"]
    section = text[text.index("4. Manual checks") :]
    assert "have no verdict from the checker" in section
    assert "R-SEAM" in section and "Seamlines visually" in section


def test_pdf_checkpoint_table_matches_json(checked: dict[str, Any]) -> None:
    doc, text = checked["doc"], checked["text"]
    assert "Check point analysis (JRC §12.6)" in text
    for bid, block in doc["details"]["checkpoints"].items():
        st = block["stats"]
        assert f"Block {bid}" in text
        assert f"{st['rmse_x']:.3f}" in text and f"{st['rmse_y']:.3f}" in text
        assert f"{st['mean_x']:.3f}" in text and f"{st['max_dr']:.3f}" in text
        for p in point_rows(
            block["points"]
        ):  # the PDF lists the failing points (all are in checkpoints.csv)
            if p["status"] == "fail":
                assert re.search(
                    rf"{re.escape(p['point_id'])} .*{p['dx']:.3f} {p['dy']:.3f}", text
                ), p
            assert f">{p['point_id']}<" in checked["html"]  # the HTML lists every point
    statuses = [
        p["status"] for b in doc["details"]["checkpoints"].values() for p in point_rows(b["points"])
    ]
    assert "fail" in statuses and "Fail" in text  # the B1 blunder is flagged


def test_pages_have_page_x_of_y_and_checksum_footer(checked: dict[str, Any]) -> None:
    sha = hashlib.sha256((checked["out"] / "qcr.json").read_bytes()).hexdigest()
    assert document_sha256(checked["doc"]) == sha
    n = len(checked["pages"])
    assert n >= 4
    for i, t in enumerate(checked["pages"], start=1):
        assert f"page {i} of {n}" in t
        assert sha in t.replace(" ", "")


def test_figures_are_embedded_data_uris(checked: dict[str, Any]) -> None:
    html = checked["html"]
    n_blocks = len(checked["doc"]["details"]["checkpoints"])
    assert (
        html.count('src="data:image/svg+xml;base64,') == 3 * n_blocks
    )  # map, histograms, quadrants
    assert "http://" not in html.split("<body>", 1)[1].replace("http://www.w3.org", "")


# --- archival PDF ----------------------------------------------------------------------------------


def test_embedded_qcr_json_equals_the_file_beside_it(checked: dict[str, Any]) -> None:
    att = attachments(checked["pdf"])
    assert att["qcr.json"] == (checked["out"] / "qcr.json").read_bytes()
    rows = att["checkpoints.csv"].decode().splitlines()
    n = sum(len(point_rows(b["points"])) for b in checked["doc"]["details"]["checkpoints"].values())
    assert len(rows) == n + 1 and rows[0].startswith("block,point_id,")


def test_pdf_declares_pdfa_3b(checked: dict[str, Any]) -> None:
    reader = PdfReader(io.BytesIO(checked["pdf"]))
    xmp = reader.trailer["/Root"]["/Metadata"].get_object().get_data().decode("utf-8")
    assert re.search(r'pdfaid:part="3"|<pdfaid:part>3</pdfaid:part>', xmp)
    assert re.search(r'pdfaid:conformance="B"|<pdfaid:conformance>B</pdfaid:conformance>', xmp)
    assert "2026-01-01T00:00:00" in xmp  # dates come from the QCR date, not the clock
    assert "/OutputIntents" in reader.trailer["/Root"]


def test_report_command_rerenders_stored_json_byte_identically(
    checked: dict[str, Any], tmp_path: Path
) -> None:
    """Renderable from qcr.json alone, and deterministic: a second render (another process
    path, other temp folder) reproduces the check's report.pdf and report.html byte for byte."""
    res = CliRunner().invoke(
        cli(), ["report", str(checked["out"] / "qcr.json"), "--out", str(tmp_path)]
    )
    assert res.exit_code == 0, res.output
    assert (tmp_path / "report.pdf").read_bytes() == checked["pdf"]
    assert (tmp_path / "report.html").read_text(encoding="utf-8") == checked["html"]
    assert document_sha256(checked["doc"]) in res.output


def test_report_command_rejects_non_qcr_json(tmp_path: Path) -> None:
    bad = tmp_path / "x.json"
    bad.write_text('{"hello": 1}', encoding="utf-8")
    res = CliRunner().invoke(cli(), ["report", str(bad), "--out", str(tmp_path)])
    assert res.exit_code != 0
    assert isinstance(res.exception, ReportError) and "missing key" in str(res.exception)
    assert not (tmp_path / "report.pdf").exists()
    with pytest.raises(ReportError, match="unknown report format"):
        reportdoc.render({}, formats=["docx"])


# --- sign-offs and bounded tables -------------------------------------------------------------------


def test_signoffs_appear_in_countersignature_without_changing_checksum(
    checked: dict[str, Any],
) -> None:
    doc = {
        **checked["doc"],
        "signoffs": [
            {
                "by": "Ada Inspector",
                "role": "EC auditor",
                "date": "2026-01-05",
                "note": "countersigned after review",
            }
        ],
    }
    assert document_sha256(doc) == document_sha256(checked["doc"])
    html = render_html(doc, ReportOptions(figures=False))
    block = html[
        html.index("Countersignature") : html.index("</table>", html.index("Countersignature"))
    ]
    assert (
        "Ada Inspector" in block and "EC auditor" in block and "countersigned after review" in block
    )
    assert "Ada Inspector" not in render_html(checked["doc"], ReportOptions(figures=False))


def test_bounded_report_summarises_passing_items(checked: dict[str, Any]) -> None:
    doc = checked["doc"]
    passing = [r for r in all_records(doc) if r["verdict"] == "pass" and r["scope"] == "image"]
    assert passing
    full = render_html(doc, ReportOptions(bounded=False, figures=False))
    short = render_html(doc, ReportOptions(bounded=True, figures=False))
    for r in passing:
        assert f"<td>{r['item']}</td>" in full
        assert f"<td>{r['item']}</td>" not in short
    assert "passing values:" in short
    assert "pass: " in short  # counts per rule stay visible


# --- safety -----------------------------------------------------------------------------------------


class CountingServer:
    """A TCP listener on 127.0.0.1 that only counts connections (it must see none)."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.connections = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            self.connections += 1
            conn.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.sock.close()


@pytest.fixture
def server() -> Iterator[CountingServer]:
    s = CountingServer()
    yield s
    s.close()


def test_hostile_metadata_is_text_and_fetches_nothing(
    tmp_path: Path, server: CountingServer
) -> None:
    url = f"http://127.0.0.1:{server.port}"
    contractor = f'<img src="{url}/x.png">'
    project = "<script>alert(1)</script>"
    operator = f"<style>@import url({url}/i.css);</style>"
    delivery = write_delivery(
        tmp_path / "d",
        contractor={"name": contractor},
        project={"id": "P1", "name": project, "crs": "EPSG:25832"},
        operator={"name": operator},
        waivers=[
            {
                "rule": "R-ROLL",
                "items": ["I2"],
                "approver": "Chief",
                "justification": f'<link rel="stylesheet" href="{url}/s.css"><a href="{url}">x</a>',
            }
        ],
    )
    out = run_check(tmp_path, delivery, "json")
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    assert doc["delivery"]["contractor"]["name"] == contractor

    html = render_html(doc, ReportOptions(figures=False))
    assert "<script>" not in html and '<img src="http' not in html and "<link rel" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert f"&lt;img src=&#34;{url}/x.png&#34;&gt;" in html

    fetcher = SafeFetcher(templates_dir())
    pdf = write_pdf(
        render_html(doc, ReportOptions(figures=False), pdf=True),
        fetcher=fetcher,
        day=doc["date"],
        identifier="t",
    )
    text = pdf_text(pdf)
    assert project in text and contractor in text  # shown literally, as text
    assert fetcher.calls == []  # no resource was even asked for
    assert server.connections == 0


def test_fetcher_is_the_second_wall(tmp_path: Path, server: CountingServer) -> None:
    """Even raw markup with external URLs (bypassing the templates) reaches no network or file."""
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"not for the report")
    mine = data_uri(
        "<svg xmlns='http://www.w3.org/2000/svg' width='10' height='10'/>", "image/svg+xml"
    )
    foreign = data_uri(
        "<svg xmlns='http://www.w3.org/2000/svg' width='9' height='9'/>", "image/svg+xml"
    )
    html = (
        f'<html><head><link rel="stylesheet" href="http://127.0.0.1:{server.port}/s.css"></head><body>'
        f'<img src="http://127.0.0.1:{server.port}/a.png"><img src="https://127.0.0.1:{server.port}/b">'
        f'<img src="{secret.as_uri()}"><img src="report.css"><img src="{mine}"><img src="{foreign}">'
        f"</body></html>"
    )
    fetcher = SafeFetcher(templates_dir())
    fetcher.allow(mine)
    write_pdf(html, fetcher=fetcher, day="2026-01-01", identifier="t")
    assert server.connections == 0
    refused = set(fetcher.refused)
    assert f"http://127.0.0.1:{server.port}/s.css" in refused
    assert f"http://127.0.0.1:{server.port}/a.png" in refused
    assert secret.as_uri() in refused and foreign in refused
    assert (
        mine not in refused and (templates_dir() / "report.css").resolve().as_uri() not in refused
    )
    assert len(fetcher.calls) == 7


def test_edge_target_results_are_tabulated(checked: dict[str, Any]) -> None:
    from orthospec.measures.edge import measure_edge
    from orthospec.measures.synthetic import slanted_edge
    from orthospec.qcr import stable

    result = stable(measure_edge(slanted_edge(angle_deg=5.0, sigma_px=0.7)).to_dict())
    doc = {**checked["doc"], "details": {**checked["doc"]["details"], "edges": {"E1": result}}}
    html = render_html(doc, ReportOptions(figures=False))
    section = html[html.index('id="edges"') : html.index('id="manual"')]
    assert "Edge target E1" in section and "valid" in section
    assert f">{result['rer']:.5g}<" in section and f">{result['rer.fermi3']:.5g}<" in section
    assert "fermi3" in section and "straightness" in section
    assert 'id="edges"' not in render_html(checked["doc"], ReportOptions(figures=False))


def _rec(item: str, verdict: str, value: Any, message: str) -> dict[str, Any]:
    return {
        "rule": "R",
        "item": item,
        "verdict": verdict,
        "measured": {"value": value, "unit": "m"},
        "requirement": {"text": "<= 1 m"},
        "message": message,
        "evidence": [{"file": "t.csv", "rows": [int(item[1:])], "sha256": "0" * 64}],
    }


def test_rows_without_values_are_grouped_and_nothing_is_dropped() -> None:
    from orthospec.reports.html import group_rows

    recs = [
        _rec("I1", "fail", 2.0, "x = 2"),
        _rec("I2", "missing", None, "no value"),
        _rec("I3", "missing", None, "no value"),
        _rec("I4", "missing", None, "no file"),
        _rec("I5", "fail", 3.0, "x = 3"),
    ]
    rows = group_rows(recs)
    assert [r["item_list"] for r in rows] == [["I1"], ["I2", "I3"], ["I4"], ["I5"]]
    assert [e["rows"] for e in rows[1]["evidence"]] == [[2], [3]]
    assert sorted(i for r in rows for i in r["item_list"]) == [r["item"] for r in recs]


@pytest.mark.parametrize(
    ("rows", "text"),
    [([1, 2, 3, 7], "1–3, 7"), ([5], "5"), ([], ""), ([4, 2, 3, 3, 9, 10], "2–4, 9–10")],
)
def test_evidence_rows_are_compressed_to_ranges(rows: list[int], text: str) -> None:
    from orthospec.reports.html import fmt_rows

    assert fmt_rows(rows) == text


def test_bounded_report_folds_quiet_rules_into_one_table(checked: dict[str, Any]) -> None:
    short = render_html(checked["doc"], ReportOptions(bounded=True, figures=False))
    full = render_html(checked["doc"], ReportOptions(bounded=False, figures=False))
    quiet = [
        r["rule"] for r in checked["doc"]["rules"] if r["verdict"] in ("pass", "not_applicable")
    ]
    assert "R-NPTS" in quiet
    table = short[short.index("Blocks: rules passed") :]
    table = table[: table.index("</table>")].replace("<wbr>", "")  # identifiers carry break hints
    assert '<span class="mono ident">R-NPTS</span>' in table and "pass: 2" in table
    assert "R-RMSEX" not in table  # a failing rule keeps its full block
    assert "rules passed</h4>" not in full


def test_block_polygon_is_stored_and_drawn(tmp_path: Path) -> None:
    """Issue 13 item 2: the manifest's block outline reaches qcr.json and the report's map."""
    b1 = [
        [499900.0, 5399900.0],
        [505100.0, 5399900.0],
        [505100.0, 5405100.0],
        [499900.0, 5405100.0],
    ]
    blocks = [{"id": "B1", "polygon": b1}, {"id": "B2"}]
    out = run_check(
        tmp_path, write_delivery(tmp_path / "delivery", blocks=blocks), fmts="json,html"
    )
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    cps = doc["details"]["checkpoints"]
    assert cps["B1"]["polygon"] == b1  # the manifest's vertices, unchanged (metres in, metres out)
    assert cps["B2"]["polygon"] is None  # no outline given: null, not invented
    import base64

    html = (out / "report.html").read_text(encoding="utf-8")
    svgs = [
        base64.b64decode(u).decode("utf-8")
        for u in re.findall(r'src="data:image/svg\+xml;base64,([A-Za-z0-9+/=]+)"', html)
    ]
    maps = [s for s in svgs if 'id="checkpoints"' in s and 'id="discrepancy-vectors"' in s]
    assert sum('id="block-outline' in s for s in maps) == 1  # B1's map only
    # same inputs, same bytes
    out2 = run_check(
        tmp_path / "again",
        write_delivery(tmp_path / "again" / "delivery", blocks=blocks),
        fmts="json",
    )
    assert (out2 / "qcr.json").read_bytes() == (out / "qcr.json").read_bytes()


def test_ident_filter_escapes_and_breaks_only_after_separators() -> None:
    from orthospec.reports.html import ident

    assert str(ident("JRC-12.7-RMSEY")) == "JRC-<wbr>12.<wbr>7-<wbr>RMSEY"
    assert str(ident("reported_rmse_tolerance")) == "reported_<wbr>rmse_<wbr>tolerance"
    assert str(ident("<b>a_b</b>")) == "&lt;b&gt;a_<wbr>b&lt;/b&gt;"  # delivery text stays text
    assert str(ident("x - y")) == "x - y" and str(ident(None)) == ""


def test_a_capped_point_table_is_labelled_and_draws_no_distribution(
    checked: dict[str, Any],
) -> None:
    """B's cap (flagged points + largest residuals) is not a sample: no histogram/quadrants from it."""
    import copy

    from orthospec.qcr import point_rows

    doc = copy.deepcopy(checked["doc"])
    blocks = doc["details"]["checkpoints"]
    capped, other = sorted(blocks)[:2]
    n = len(point_rows(blocks[capped]["points"]))
    blocks[capped].update(points_total=n + 1000, points_omitted=1000)
    html = render_html(doc, ReportOptions(bounded=False), figure=data_uri)
    assert f"Shown: {n:,} of {n + 1000:,} points" in html
    assert "1000 point(s) with small residuals are not in qcr.json" in html
    assert f"Block {capped}: distribution of the discrepancies" not in html
    assert f"Block {other}: distribution of the discrepancies" in html


def test_checker_verdicts_on_nothing_delivered_are_listed(checked: dict[str, Any]) -> None:
    import copy

    doc = copy.deepcopy(checked["doc"])
    assert doc["manual_unused"] == []  # qcr.json always carries the list (red team R15)
    doc["manual_unused"] = [
        {
            "check": "R-SEAM",
            "item": "IMG_GONE",
            "date": "2026-01-02",
            "verdict": "pass",
            "entry": 3,
            "checker_file": "checker.yaml",
            "reason": "the delivery no longer lists IMG_GONE",
        }
    ]
    html = render_html(doc, ReportOptions(bounded=True, figures=False))
    assert "Checker verdicts on nothing delivered" in html
    assert "IMG_GONE" in html and "the delivery no longer lists IMG_GONE" in html
