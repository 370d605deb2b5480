"""``orthospec measure edge``: windowed read, JSON/terminal output, SVGs, bad input exits 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine
from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.measures.synthetic import edge_truth, slanted_edge


@pytest.fixture
def edge_tif(tmp_path: Path) -> Path:
    """A 2-band uint16 GeoTIFF: band 2 holds a slanted edge in x 20..100, y 10..110."""
    edge = slanted_edge((100, 80), angle_deg=6.0, sigma_px=0.7, snr=300, bit_depth=16,
                        supersample=9, rng=np.random.default_rng(1))
    band2 = np.full((130, 140), 5000, dtype=np.uint16)
    band2[10:110, 20:100] = edge
    band1 = np.random.default_rng(2).integers(900, 1100, size=(130, 140)).astype(np.uint16)
    path = tmp_path / "edge.tif"
    with rasterio.open(path, "w", driver="GTiff", width=140, height=130, count=2,
                       dtype="uint16", crs="EPSG:25832",
                       transform=Affine(0.2, 0.0, 500000.0, 0.0, -0.2, 5600000.0)) as ds:
        ds.write(band1, 1)
        ds.write(band2, 2)
    return path


def _run(*args: str):
    return CliRunner().invoke(cli(), ["measure", "edge", *args], terminal_width=120)


def test_json_valid_edge(edge_tif):
    res = _run(str(edge_tif), "--roi", "20,10,100,110", "--band", "2", "--gsd", "0.2", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    truth = edge_truth(sigma_px=0.7, angle_deg=6.0)
    assert doc["valid"] is True and doc["roi"] == [20, 10, 100, 110] and doc["band"] == 2
    assert doc["fwhm_px"] == pytest.approx(truth.fwhm_px, rel=0.02)
    assert doc["fwhm_m"] == pytest.approx(doc["fwhm_px"] * 0.2)
    assert doc["fwhm_px.unit"] == "px" and doc["fwhm_m.unit"] == "m"
    assert doc["fwhm_px.fit"] == doc["primary_fit"] == "gauss"
    assert "rer.fermi3" in doc and doc["fwhm_px.spline"] == pytest.approx(truth.fwhm_px, rel=0.03)
    assert abs(doc["angle_deg"] - 6.0) < 0.1
    assert doc["check.snr.passed"] is True and doc["check.angle.unit"] == "deg"


def test_terminal_tables_and_plots(edge_tif, tmp_path):
    out = tmp_path / "plots" / "sub"
    res = _run(str(edge_tif), "--roi", "20,10,100,110", "--band", "2", "--gsd", "0.2",
               "--plots", str(out))
    assert res.exit_code == 0, res.output
    assert "Health checks" in res.output and "Estimators" in res.output
    assert "fwhm_m" in res.output and "gauss (primary)" in res.output
    assert "lack-of-fit" in res.output
    names = sorted(p.name for p in out.iterdir())
    assert names == ["edge_detection.svg", "edge_esf.svg", "edge_lsf.svg", "edge_mtf.svg"]
    assert "Nyquist" in (out / "edge_mtf.svg").read_text()


def test_failed_health_checks_exit_1_with_values(edge_tif):
    res = _run(str(edge_tif), "--roi", "0,0,20,40", "--band", "1", "--json")
    assert res.exit_code == 1, res.output
    doc = json.loads(res.output)
    assert doc["valid"] is False and doc["reasons"]
    assert doc.get("fwhm_px") is None and doc["check.contrast.passed"] is False
    assert doc["check.contrast.value"] is not None


@pytest.mark.parametrize("args,message", [
    (["--band", "3"], "band 3 does not exist"),
    (["--band", "0"], "band 0 does not exist"),
    (["--roi", "20,10,100"], "expected four integers"),
    (["--roi", "a,b,c,d"], "expected four integers"),
    (["--roi", "50,10,20,110"], "x0 < x1"),
    (["--roi", "20,10,200,110"], "exceeds the image"),
])
def test_bad_roi_or_band_exits_2(edge_tif, args, message):
    res = _run(str(edge_tif), *args)
    assert res.exit_code == 2, res.output
    assert "error:" in res.output and message in res.output
    assert "Traceback" not in res.output


def test_bad_file_exits_2(tmp_path):
    bad = tmp_path / "bad.tif"
    bad.write_text("not a tiff")
    res = _run(str(bad))
    assert res.exit_code == 2 and "bad.tif" in res.output and "Traceback" not in res.output
    res = _run(str(tmp_path / "missing.tif"))
    assert res.exit_code == 2 and "missing.tif" in res.output


def test_too_small_roi_exits_2(edge_tif):
    res = _run(str(edge_tif), "--roi", "20,10,23,110", "--band", "2")
    assert res.exit_code == 2 and "too small" in res.output


def test_help_text():
    res = CliRunner().invoke(cli(), ["measure", "edge", "--help"])
    assert res.exit_code == 0 and "--roi" in res.output and "Exit code" in res.output


def test_no_roi_finds_the_edge_automatically(edge_tif):
    """Issue 16: without --roi the edges are found; band 2 holds one near-vertical edge
    (6 deg) inside a flat frame, so one X edge and no combined RER (no Y edge), with the
    reason. --whole keeps the old whole-image measurement."""
    res = _run(str(edge_tif), "--band", "2", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["mode"] == "auto" and doc["roi"] is None
    valid = [e for e in doc["edges"] if e["valid"]]
    assert [e["axis"] for e in valid] == ["x"]
    e = valid[0]
    assert e["angle_deg"] == pytest.approx(6.0, abs=0.1)
    t = edge_truth(sigma_px=0.7, angle_deg=6.0)
    assert e["fwhm_px"] == pytest.approx(t.fwhm_px, rel=0.03)
    assert doc["rer_combined"] is None and "Y (northing)" in doc["rer_combined.reason"]
    text = _run(str(edge_tif), "--band", "2")
    assert text.exit_code == 0 and "combined" in text.output and "automatic search" in text.output
    whole = json.loads(_run(str(edge_tif), "--band", "2", "--whole", "--json").output)
    assert "mode" not in whole and "valid" in whole


def test_no_roi_writes_figures_per_found_edge(edge_tif, tmp_path):
    res = _run(str(edge_tif), "--band", "2", "--json", "--plots", str(tmp_path / "figs"))
    doc = json.loads(res.output)
    n = len(doc["edges"])
    assert n >= 1 and len(doc["plots"]) == 4 * n
    first = [p for p in doc["plots"] if Path(p).name.startswith("edge1_")]
    assert {Path(p).name.split("_", 2)[2] for p in first} == {"detection.svg", "esf.svg", "lsf.svg",
                                                             "mtf.svg"}
    assert all(Path(p).read_text(encoding="utf-8").lstrip().startswith("<?xml") for p in doc["plots"])


def test_map_roi_reads_the_same_pixels_and_gsd_comes_from_the_transform(edge_tif):
    """The fixture's transform: 0.2 m pixels from (500000, 5600000); pixels 20,10,100,110 are
    x 500004..500020, y 5599978..5599998. Without --gsd the metre values use the 0.2 m pixel."""
    px = json.loads(_run(str(edge_tif), "--roi", "20,10,100,110", "--band", "2", "--json").output)
    res = _run(str(edge_tif), "--map-roi", "500004,5599978,500020,5599998", "--band", "2", "--json")
    assert res.exit_code == 0, res.output
    mp = json.loads(res.output)
    assert mp["roi"] == px["roi"] == [20, 10, 100, 110]
    assert mp["fwhm_px"] == px["fwhm_px"] and mp["rer"] == px["rer"]
    assert px["gsd_m"] == pytest.approx(0.2) and px["fwhm_m"] == pytest.approx(px["fwhm_px"] * 0.2)
    both = _run(
        str(edge_tif), "--roi", "20,10,100,110", "--map-roi", "500004,5599978,500020,5599998"
    )
    assert both.exit_code == 2 and "not both" in both.output
    bad = _run(str(edge_tif), "--map-roi", "1,2,3")
    assert bad.exit_code == 2 and "four numbers" in bad.output
