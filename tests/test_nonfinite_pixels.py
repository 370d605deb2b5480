"""Float rasters with NaN / +/-Inf pixels (issue 28 item 7): counted as non-finite, excluded from
every statistic, never a crash and never a warning on stderr."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

from orthospec.raster.parallel import ScanOptions, scan_image
from orthospec.raster.reading import ScanSettings, scan_raster


def _write(path: Path, a: np.ndarray, **profile: object) -> Path:
    prof = dict(
        driver="GTiff",
        width=a.shape[2],
        height=a.shape[1],
        count=a.shape[0],
        dtype=a.dtype,
        crs="EPSG:25832",
        transform=Affine(0.5, 0, 500000, 0, -0.5, 5600000),
    )
    prof.update(profile)
    with rasterio.open(path, "w", **prof) as ds:
        ds.write(a)
    return path


@pytest.fixture()
def inf_tif(tmp_path: Path) -> tuple[Path, np.ndarray]:
    a = np.random.default_rng(7).normal(1000, 50, (3, 300, 260)).astype(np.float32)
    a[0, :10] = -9999  # nodata: not non-finite
    a[0, 50, :7] = np.inf
    a[1, 90, :3] = -np.inf
    a[2, 11, :4] = np.nan  # NaN while the nodata value is -9999: non-finite
    a[2, 12, :2] = np.inf
    return _write(
        tmp_path / "inf.tif", a, nodata=-9999, tiled=True, blockxsize=64, blockysize=64
    ), a


def test_inf_and_nan_are_counted_and_excluded(inf_tif):
    f, a = inf_tif
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning (inf - inf) anywhere in the scan
        stats = scan_raster(
            f,
            ScanSettings(
                noise=True, luminosity=True, misregistration=True, chunk_bytes=64 * 64 * 3 * 4 * 2
            ),
        )
    assert [b.nonfinite for b in stats.bands] == [7, 3, 6]
    for b, band in zip(stats.bands, a, strict=True):
        ok = band[np.isfinite(band) & (band != -9999)].astype(np.float64)
        assert b.valid == ok.size
        assert (b.min, b.max) == (ok.min(), ok.max())
        assert b.mean == pytest.approx(ok.mean(), rel=1e-12)
        assert b.std == pytest.approx(ok.std(), rel=1e-9)
        assert b.noise_sigma_immerkaer is not None and np.isfinite(b.noise_sigma_immerkaer)
        assert sum(b.histogram.counts) == b.valid
        assert b.to_dict()["nonfinite_pixels"] == b.nonfinite


def test_nan_nodata_is_not_nonfinite(tmp_path):
    a = np.full((1, 40, 40), 5.0, np.float32)
    a[0, :5] = np.nan
    a[0, 6, :2] = -np.inf
    b = scan_raster(_write(tmp_path / "n.tif", a, nodata=float("nan"))).bands[0]
    assert (b.nonfinite, b.valid, b.min, b.max) == (2, 40 * 40 - 5 * 40 - 2, 5.0, 5.0)


def test_integer_bands_carry_no_count(tmp_path):
    a = np.arange(30 * 30, dtype=np.uint16).reshape(1, 30, 30)
    b = scan_raster(_write(tmp_path / "u.tif", a)).bands[0]
    assert b.nonfinite is None and "nonfinite_pixels" not in b.to_dict()


def test_image_report_has_the_measure_and_no_error(inf_tif):
    f, _ = inf_tif
    rep = scan_image(f, ScanOptions(settings=ScanSettings(noise=True)))
    assert rep.error is None
    assert rep.to_dict()["image.nonfinite_pixels"] == 16


def test_measure_radiometry_command_is_silent_on_stderr(inf_tif):
    f, _ = inf_tif
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "orthospec.cli.main",
            "measure",
            "radiometry",
            "--full",
            "--json",
            str(f),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""
    bands = json.loads(run.stdout)["radiometry"]["bands"]
    assert [b["nonfinite_pixels"] for b in bands] == [7, 3, 6]
