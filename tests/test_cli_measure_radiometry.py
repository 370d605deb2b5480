"""``orthospec measure radiometry``: JSON and terminal output, bad files exit 2."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from orthospec.cli.main import cli

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
RGB = REAL / "RGB.byte.tif"
BAND_KEYS = {"min", "max", "mean", "std", "histogram", "saturation_low_pct",
             "saturation_high_pct", "cv_percent", "nodata_fraction", "bit_depth"}


def test_json_has_band_measures_and_file_checks(tmp_path):
    img = Path(shutil.copy(RGB, tmp_path / "rgb.tif"))
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(img), "--json", "--full",
                                     "--expect-epsg", "32618", "--expect-gsd", "300"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["radiometry"]["statistics"].startswith("exact, population std")
    bands = doc["radiometry"]["bands"]
    assert len(bands) == 3 and all(b.keys() >= BAND_KEYS for b in bands)
    assert bands[0]["min"] == 1.0 and bands[0]["bit_depth"] == 8
    assert doc["checks"]["crs_ok"] is True and doc["checks"]["gsd_ok"] is True
    assert doc["radiometry"]["luminosity"]["valid"] > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rgb.tif"]  # nothing written


def test_bit_depth_option_and_epsg_mismatch(tmp_path):
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(RGB), "--json",
                                     "--bit-depth", "7", "--expect-epsg", "25832"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    b = doc["radiometry"]["bands"][0]
    assert (b["bit_depth"], b["bit_depth_source"], b["range_high"]) == (7, "argument", 127)
    assert b["above_range"] > 0
    assert doc["checks"]["crs_ok"] is False


def test_terminal_table():
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(RGB), "--full"],
                             terminal_width=120)
    assert res.exit_code == 0, res.output
    assert "saturation high pct" in res.output and "luminosity" in res.output
    assert "nodata excluded per band, as GDAL" in res.output
    plain = CliRunner().invoke(cli(), ["measure", "radiometry", str(RGB)], terminal_width=120)
    assert plain.exit_code == 0, plain.output
    assert "saturation high pct" in plain.output and "luminosity" not in plain.output


def _gdalinfo_stats_hist(path: Path) -> list[dict]:
    """GDAL's own ``gdalinfo -stats -hist`` bands (run on a copy: it may write .aux.xml)."""
    import subprocess

    out = subprocess.run(["gdalinfo", "-stats", "-hist", "-json", str(path)],
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out)["bands"]


@pytest.mark.skipif(shutil.which("gdalinfo") is None, reason="gdalinfo (gdal-bin) not installed")
def test_default_is_the_job_of_gdalinfo_stats_hist_and_full_adds_the_6_3_scan(tmp_path):
    """Issue 14: by default exactly ``gdalinfo -stats -hist`` (+ file checks, SHA-256);
    ``--full`` adds noise, luminosity and misregistration without changing those numbers."""
    import hashlib

    import numpy as np
    import rasterio
    from affine import Affine

    # textured RGB with nodata 0 in a corner (no statistics tags: gdalinfo must compute them)
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:300, 0:420]
    base = (np.sin(xx / 17.0) + np.cos(yy / 11.0) + 2) * 55
    data = np.clip(base[None] * [[[0.8]], [[0.9]], [[1.0]]]
                   + rng.normal(0, 6, (3, 300, 420)) + 8, 1, 255).astype(np.uint8)
    data[:, :20, :30] = 0
    img = tmp_path / "rgb.tif"
    with rasterio.open(img, "w", driver="GTiff", width=420, height=300, count=3, dtype="uint8",
                       nodata=0, tiled=True, blockxsize=128, blockysize=128, crs="EPSG:25832",
                       transform=Affine(0.2, 0, 500000, 0, -0.2, 5600000)) as ds:
        ds.write(data)
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(img), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["sha256"] == hashlib.sha256(img.read_bytes()).hexdigest()
    assert doc["checks"]["width"] == 420 and doc["checks"]["crs"] and doc["findings"] == []
    rad = doc["radiometry"]
    assert rad["luminosity"] is None and rad["misregistration"] == {}
    assert all(b["noise_sigma_immerkaer"] is None for b in rad["bands"])
    (tmp_path / "gdal").mkdir()
    gdal_copy = Path(shutil.copy(img, tmp_path / "gdal" / "rgb.tif"))
    for ours, gb in zip(rad["bands"], _gdalinfo_stats_hist(gdal_copy), strict=True):
        md = gb["metadata"][""]  # full precision (the top-level keys are rounded)
        assert (ours["min"], ours["max"]) == (float(md["STATISTICS_MINIMUM"]),
                                              float(md["STATISTICS_MAXIMUM"]))
        assert ours["mean"] == pytest.approx(float(md["STATISTICS_MEAN"]), rel=1e-12)
        assert ours["std"] == pytest.approx(float(md["STATISTICS_STDDEV"]), rel=1e-12)
        h, hist = gb["histogram"], ours["histogram"]
        assert (h["count"], h["min"], h["max"]) == (256, -0.5, 255.5)  # one bucket per DN
        buckets = [0] * 256
        buckets[hist["first_dn"]:hist["first_dn"] + len(hist["counts"])] = hist["counts"]
        assert buckets == h["buckets"] and buckets[0] == 0  # nodata excluded
    full = CliRunner().invoke(cli(), ["measure", "radiometry", str(img), "--json", "--full"])
    assert full.exit_code == 0, full.output
    frad = json.loads(full.output)["radiometry"]
    assert frad["luminosity"]["valid"] == 300 * 420 - 20 * 30
    assert set(frad["misregistration"]) == {"1", "3"}  # against the green band
    assert all(b["noise_sigma_immerkaer"] > 0 for b in frad["bands"])
    # the pixel facts `check` compares declarations with come with --full only (the default is
    # gdalinfo's job, timed against it in benchmarks/radiometry.py)
    assert rad["pixels_hash"] is None and rad["thumbnail"] is None
    assert len(frad["pixels_hash"]) == 32 and frad["thumbnail"] and frad["cloud_samples"] > 0
    for b, fb in zip(rad["bands"], frad["bands"], strict=True):
        assert {k: b[k] for k in ("min", "max", "mean", "std", "histogram")} == {
            k: fb[k] for k in ("min", "max", "mean", "std", "histogram")}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gdal", "rgb.tif"]  # nothing written


def test_bad_file_exits_2_with_clear_error(tmp_path):
    bad = tmp_path / "bad.tif"
    bad.write_text("not a tiff")
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(bad)])
    assert res.exit_code == 2
    assert "error:" in res.output and "bad.tif" in res.output
    assert "not a readable raster" in res.output
    res2 = CliRunner().invoke(cli(), ["measure", "radiometry", str(tmp_path / "none.tif")])
    assert res2.exit_code == 2 and "none.tif" in res2.output


def _write_plain_tiff(path: Path, data) -> None:
    """A GeoTIFF with no CRS and no geotransform (a scan straight off a sensor, say)."""
    import warnings

    import rasterio

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=data.shape[2], height=data.shape[1],
                           count=data.shape[0], dtype=str(data.dtype)) as ds:
            ds.write(data)


def test_image_without_crs_is_measured_and_reported_as_a_finding(tmp_path):
    """Issue 14: radiometry needs no georeference; the missing CRS is a file-check finding."""
    import hashlib

    import numpy as np

    data = np.random.default_rng(7).integers(3, 251, (3, 40, 56), dtype=np.uint8)
    img = tmp_path / "nocrs.tif"
    _write_plain_tiff(img, data)
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(img), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["findings"] == [f"{img}: no georeference (no CRS)"]
    assert doc["checks"]["crs"] is None
    assert doc["sha256"] == hashlib.sha256(img.read_bytes()).hexdigest()
    for k, b in enumerate(doc["radiometry"]["bands"]):  # known truth: the pixels written
        assert (b["min"], b["max"]) == (float(data[k].min()), float(data[k].max()))
        assert abs(b["mean"] - float(data[k].mean())) < 1e-9
        assert abs(b["std"] - float(data[k].std())) < 1e-9
    text = CliRunner().invoke(cli(), ["measure", "radiometry", str(img)], terminal_width=200)
    assert text.exit_code == 0 and "file check:" in text.output and "no georeference" in text.output
    assert "Warning" not in text.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nocrs.tif"]  # nothing written


def test_big_image_hash_in_a_thread_equals_the_file_hash(tmp_path):
    """The SHA-256 computed alongside the pixel scan is the file's (hashlib, independently)."""
    import hashlib

    import numpy as np

    from orthospec.raster.parallel import HASH_THREAD_BYTES

    side = int((HASH_THREAD_BYTES / 3) ** 0.5) + 64
    data = np.random.default_rng(1).integers(0, 256, (3, side, side), dtype=np.uint8)
    img = tmp_path / "big.tif"
    _write_plain_tiff(img, data)
    assert img.stat().st_size >= HASH_THREAD_BYTES
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(img), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["sha256"] == hashlib.sha256(img.read_bytes()).hexdigest()
    assert doc["radiometry"]["bands"][2]["max"] == float(data[2].max())
