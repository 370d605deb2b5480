"""``orthospec measure radiometry``: JSON and terminal output, bad files exit 2."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from click.testing import CliRunner

from orthospec.cli.main import cli

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
RGB = REAL / "RGB.byte.tif"
BAND_KEYS = {"min", "max", "mean", "std", "histogram", "saturation_low_pct",
             "saturation_high_pct", "cv_percent", "nodata_fraction", "bit_depth"}


def test_json_has_band_measures_and_file_checks(tmp_path):
    img = Path(shutil.copy(RGB, tmp_path / "rgb.tif"))
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(img), "--json",
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
    res = CliRunner().invoke(cli(), ["measure", "radiometry", str(RGB)], terminal_width=120)
    assert res.exit_code == 0, res.output
    assert "saturation high pct" in res.output and "luminosity" in res.output
    assert "nodata excluded per band, as GDAL" in res.output


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
