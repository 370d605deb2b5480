"""Edge-target figures in the auditor's report: curves stored in qcr.json, drawn from it alone.

A real check of a small delivery (synthetic slanted-edge GeoTIFFs written with rasterio) writes
qcr.json, report.html and report.pdf; the report is re-rendered from qcr.json and compared.
"""

from __future__ import annotations

import base64
import io
import json
import re
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pdfplumber
import pytest
import rasterio
import yaml
from click.testing import CliRunner
from rasterio.transform import from_origin

from orthospec.cli.main import cli
from orthospec.engine.providers.edge import MAX_ESF_SAMPLES, MAX_FIT_POINTS, MAX_LINES
from orthospec.measures.edge import PSF_FITS, measure_edge
from orthospec.measures.synthetic import slanted_edge
from orthospec.qcr import all_records, dumps
from orthospec.reports.fetcher import data_uri
from orthospec.reports.html import ReportOptions, render_html

PROFILE = textwrap.dedent("""\
    orthospec_profile: 1
    id: edge-report-test
    version: 1.0.0
    title: Edge report test
    source: {title: CEOS WGCV IVOS edge target}
    rules:
      - id: E-RER
        title: Relative edge response at least 0.3
        clause: {document: CEOS WGCV IVOS, section: "9"}
        quote: "RER"
        scope: edge
        measure: edge.rer
        requirement: {op: ">=", value: 0.3, unit: "1"}
        consequence: reject_item
    """)

SIGMA = {"E1": 0.7, "E2": 1.6}  # two valid edges of different sharpness; E3 has no edge


def _write_tif(path: Path, arr: np.ndarray) -> None:
    with rasterio.open(path, "w", driver="GTiff", height=arr.shape[0], width=arr.shape[1], count=1,
                       dtype=arr.dtype, crs="EPSG:25832",
                       transform=from_origin(500000.0, 5400000.0, 0.25, 0.25)) as ds:
        ds.write(arr, 1)


def _delivery(root: Path) -> Path:
    (root / "tables").mkdir(parents=True)
    (root / "images").mkdir()
    rows = ["image_id,file,block"]
    targets = []
    for i, (tid, sigma) in enumerate(SIGMA.items()):
        arr = slanted_edge(
            (100, 120),
            angle_deg=7.0 + i,
            sigma_px=sigma,
            dark=40,
            bright=200,
            snr=200,
            bit_depth=8,
            rng=np.random.default_rng(11 + i),
        )
        if i == 1:
            arr = np.ascontiguousarray(arr.T[::-1])  # a horizontal edge, bright on top
        _write_tif(root / "images" / f"{tid}.tif", arr)
        rows.append(f"{tid},images/{tid}.tif,B1")
        targets.append(
            {"id": tid, "image": tid, "roi": [0, 0, arr.shape[1], arr.shape[0]], "band": 1}
        )
    noise = np.random.default_rng(3).integers(100, 140, (60, 60)).astype(np.uint8)  # no edge at all
    _write_tif(root / "images" / "flat.tif", noise)
    rows.append("flat,images/flat.tif,B1")
    targets.append({"id": "E3", "image": "flat", "roi": [0, 0, 60, 60], "band": 1})
    (root / "tables" / "images.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
    manifest = {
        "orthospec_delivery": 1,
        "id": "D-EDGE-1",
        "project": {"id": "P1", "name": "Edge project", "crs": "EPSG:25832"},
        "contractor": {"name": "ACME Mapping"},
        "operator": {"name": "Jane Doe", "role": "QA"},
        "sensor": {"type": "aerial", "digital": True},
        "product": {"gsd": {"value": 0.25, "unit": "m"}, "bit_depth": 8},
        "blocks": [{"id": "B1"}],
        "tables": {"images": "tables/images.csv"},
        "edge_targets": targets,
    }
    (root / "delivery.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")
    return root


def _svgs(html: str) -> list[str]:
    return [
        base64.b64decode(b).decode("utf-8")
        for b in re.findall(r'src="data:image/svg\+xml;base64,([A-Za-z0-9+/=]+)"', html)
    ]


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("edge-report")
    delivery = _delivery(tmp / "delivery")
    (tmp / "profile.yaml").write_text(PROFILE, encoding="utf-8")
    out = tmp / "out"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(delivery),
            "--profile",
            str(tmp / "profile.yaml"),
            "--out",
            str(out),
            "--date",
            "2026-01-01",
            "--format",
            "json,html,pdf",
        ],
    )
    assert res.exit_code in (0, 1), res.output + str(res.exception)
    text = (out / "qcr.json").read_text(encoding="utf-8")
    pdf = (out / "report.pdf").read_bytes()
    with pdfplumber.open(io.BytesIO(pdf)) as p:
        pdf_text = "\n".join(page.extract_text() or "" for page in p.pages)
    return {
        "out": out,
        "text": text,
        "doc": json.loads(text),
        "pdf": pdf,
        "pdf_text": pdf_text,
        "html": (out / "report.html").read_text(encoding="utf-8"),
        "delivery": delivery,
    }


def test_qcr_json_carries_bounded_curves(checked: dict[str, Any]) -> None:
    edges = checked["doc"]["details"]["edges"]
    assert set(edges) == {"E1", "E2", "E3"}
    for tid in SIGMA:
        c = edges[tid]["curves"]
        assert edges[tid]["valid"] is True
        assert (
            0 < len(c["esf"]["d"]) == len(c["esf"]["v"]) <= MAX_ESF_SAMPLES < c["esf"]["n_samples"]
        )
        assert 20 <= len(c["lines"]["kept_x"]) == len(c["lines"]["kept_y"]) <= MAX_LINES
        # primary first, then the model-free spline to compare it with
        assert list(c["fits"]) == [edges[tid]["primary_fit"], "spline"]
        assert edges[tid]["primary_fit"] in PSF_FITS
        for f in c["fits"].values():
            assert len(f["esf"]) == len(f["lsf"]) <= MAX_FIT_POINTS and f["dx"] >= 0.05
            assert len(f["mtf"]) == len(c["mtf_freq"]) == 51 and c["mtf_freq"][-1] == 1.0
            assert all(len(re.sub(r"[-.]|e.*", "", repr(x)).lstrip("0")) <= 6 for x in f["lsf"])
        # the stored curves agree with the chain run on the same image (and ROI frame)
        spline = c["fits"]["spline"]
        primary = c["fits"][edges[tid]["primary_fit"]]
        assert primary["fwhm_px"] == pytest.approx(edges[tid]["fwhm_px"], rel=1e-5)
        assert primary["mtf_nyquist"] == pytest.approx(edges[tid]["mtf_nyquist"], rel=1e-5)
        assert spline["fwhm_px"] == pytest.approx(edges[tid]["fwhm_px.spline"], rel=1e-5)
        freq = np.array(c["mtf_freq"])
        assert np.interp(0.5, freq, spline["mtf"]) == pytest.approx(spline["mtf_nyquist"], abs=1e-5)
        assert max(spline["esf"]) > 0.95 and min(spline["esf"]) < 0.05
    # the blurrier edge has the wider LSF
    fw = {t: edges[t]["curves"]["fits"]["spline"]["fwhm_px"] for t in SIGMA}
    assert fw["E2"] > 1.5 * fw["E1"]
    # horizontal edge E2: the fitted line runs along x, the ROI is 120 rows x 100 columns
    c2 = edges["E2"]["curves"]
    assert c2["direction"] == "along" and c2["shape"] == [120, 100]
    assert np.ptp(c2["lines"]["fit_x"]) > 5 * np.ptp(c2["lines"]["fit_y"])
    assert (
        edges["E3"]["valid"] is False and edges["E3"]["curves"]["lines"]["kept_x"]
    )  # drawn, marked invalid


def test_curves_cost_less_than_30_kb_per_edge(checked: dict[str, Any]) -> None:
    assert dumps(checked["doc"]) == checked["text"]  # the round trip is exact: sizes compare
    size = len(checked["text"].encode())
    for tid in checked["doc"]["details"]["edges"]:
        bare = json.loads(checked["text"])
        bare["details"]["edges"][tid].pop("curves")
        cost = size - len(dumps(bare).encode())
        assert 500 < cost < 30_000, (tid, cost)


def test_curves_are_deterministic(checked: dict[str, Any]) -> None:
    from orthospec.engine.providers.edge import edge_curves

    arr = slanted_edge(
        (100, 120),
        angle_deg=7.0,
        sigma_px=0.7,
        dark=40,
        bright=200,
        snr=200,
        bit_depth=8,
        rng=np.random.default_rng(11),
    )
    c = edge_curves(measure_edge(arr.astype(float), gsd=0.25))
    assert json.dumps(c) == json.dumps(edge_curves(measure_edge(arr.astype(float), gsd=0.25)))
    assert c == checked["doc"]["details"]["edges"]["E1"]["curves"]


def test_html_shows_edge_figures(checked: dict[str, Any]) -> None:
    html = checked["html"]
    section = html[html.index('id="edges"') : html.index('id="manual"')]
    for tid in SIGMA:
        for what in ("edge detection", "ESF:", "LSF:", "MTF:"):
            assert f"Edge target {tid}, {what}" in section
    assert "Edge target E3, edge detection" in section and "E3: edge detection" in "".join(
        _svgs(section)
    )
    svgs = _svgs(section)
    assert all(s.lstrip().startswith("<?xml") and "<svg" in s for s in svgs)
    joined = "".join(svgs)
    assert "Nyquist" in joined and "FWHM" in joined and "edge location per line" in joined
    fwhm = checked["doc"]["details"]["edges"]["E1"]["curves"]["fits"]["spline"]["fwhm_px"]
    assert f"FWHM {fwhm:.3f} px" in joined


def test_pdf_mentions_edge_figures(checked: dict[str, Any]) -> None:
    text = re.sub(r"\s+", " ", checked["pdf_text"])
    assert "Edge targets (spatial resolution)" in text
    for tid in SIGMA:
        assert f"Edge target {tid}, ESF" in text and f"Edge target {tid}, MTF" in text
    # the figures' own text stays text in the PDF (pdfplumber drops its spaces)
    assert "E1:modulationtransferfunction(MTF)" in text.replace(" ", "")


def test_rerender_from_qcr_json_is_identical(checked: dict[str, Any], tmp_path: Path) -> None:
    res = CliRunner().invoke(
        cli(), ["report", str(checked["out"] / "qcr.json"), "--out", str(tmp_path)]
    )
    assert res.exit_code == 0, res.output
    assert (tmp_path / "report.html").read_text(encoding="utf-8") == checked["html"]
    assert (tmp_path / "report.pdf").read_bytes() == checked["pdf"]


def test_edge_figures_are_bounded_failing_first(checked: dict[str, Any]) -> None:
    doc = checked["doc"]
    verdicts = {r["item"]: r["verdict"] for r in all_records(doc) if r["rule"] == "E-RER"}
    assert verdicts == {"E1": "pass", "E2": "fail", "E3": "error"}  # E2 is blurred below RER 0.3
    html = render_html(doc, ReportOptions(max_figure_edges=2), figure=data_uri)
    section = html[html.index('id="edges"') : html.index('id="manual"')]
    assert (
        "Edge figures are drawn for 2 of 3 edge targets (failing or erring targets first)"
        in section
    )
    assert "Edge target E2, MTF" in section and "Edge target E3, edge detection" in section
    assert "Edge target E1, " not in section
    full = checked["html"][
        checked["html"].index('id="edges"') : checked["html"].index('id="manual"')
    ]
    assert len(_svgs(section)) == len(_svgs(full)) - 4  # E1's four figures left out
    assert "Edge figures are drawn" not in full


def test_document_without_curves_keeps_the_tables(checked: dict[str, Any]) -> None:
    """An older qcr.json (no ``curves``) still renders: values tabulated, no edge figures, no note."""
    doc = json.loads(checked["text"])
    for d in doc["details"]["edges"].values():
        d.pop("curves")
    html = render_html(doc, ReportOptions(), figure=data_uri)
    section = html[html.index('id="edges"') : html.index('id="manual"')]
    assert "Edge target E1 " in section and "fwhm_px" in section
    assert not _svgs(section) and "Edge figures are drawn" not in section


COMBINED_PROFILE = textwrap.dedent("""\
    orthospec_profile: 1
    id: edge-combined-test
    version: 1.0.0
    title: Edge combined RER test
    source: {title: USGS in-situ}
    rules:
      - id: C-RER
        title: USGS two-direction RER at least 0.3
        clause: {document: USGS in-situ, section: Spatial Results}
        quote: "RER is a geometric mean"
        scope: delivery
        measure: edge.rer_combined
        requirement: {op: ">=", value: 0.3, unit: "1"}
        consequence: warn
      - id: C-NIIRS
        title: GIQE 4 NIIRS recorded
        clause: {document: Leachtenauer et al. 1997, section: eq. 1}
        quote: "NIIRS"
        scope: delivery
        measure: edge.giqe4_niirs
        requirement: {op: ">=", value: 0, unit: "1"}
        consequence: warn
    """)


def test_delivery_combined_rer_is_the_usgs_geometric_mean(tmp_path: Path) -> None:
    """Issue 16: E1 is profiled along x, E2 (transposed) along y; the delivery-scope
    edge.rer_combined = sqrt(RER_x RER_y) (USGS seed 000), and GIQE 4 is computed from it
    (Leachtenauer et al. 1997, with GSD 0.25 m = 9.8425 in, H, G = 1, the edge SNR)."""
    from orthospec.measures.giqe import giqe4

    delivery = _delivery(tmp_path / "delivery")
    (tmp_path / "profile.yaml").write_text(COMBINED_PROFILE, encoding="utf-8")
    out = tmp_path / "out"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(delivery),
            "--profile",
            str(tmp_path / "profile.yaml"),
            "--out",
            str(out),
            "--date",
            "2026-01-01",
            "--format",
            "json",
        ],
    )
    assert res.exit_code in (0, 1), res.output + str(res.exception)
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    rec = {r["rule"]: r for r in all_records(doc)}
    e1 = measure_edge(rasterio.open(delivery / "images" / "E1.tif").read(1), gsd=0.25)
    e2 = measure_edge(rasterio.open(delivery / "images" / "E2.tif").read(1), gsd=0.25)
    assert (e1.direction, e2.direction) == ("across", "along")
    want = (e1.rer * e2.rer) ** 0.5
    assert rec["C-RER"]["measured"]["value"] == pytest.approx(want, rel=1e-6)
    assert rec["C-RER"]["verdict"] == "pass"
    h = (e1.estimate("overshoot_h").value * e2.estimate("overshoot_h").value) ** 0.5
    snr = float(np.median([e1.check("snr").value, e2.check("snr").value]))
    niirs = giqe4(gsd_m=0.25, rer=want, overshoot=h, noise_gain=1.0, snr=snr).niirs
    assert rec["C-NIIRS"]["measured"]["value"] == pytest.approx(niirs, rel=1e-6)
