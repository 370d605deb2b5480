"""DN-0 saturation under nodata 0 counted from the histograms and validity masks the scan already has
(issue 26's count, made cheaper for issue 25's timing): the counts equal a direct numpy count on the
file's pixels, over many chunks, with bands whose zeros occur in some chunks only."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from orthospec.raster.reading import ScanSettings, scan_raster


@pytest.mark.parametrize(
    "full", [False, True]
)  # True: the validity masks built for the noise are reused
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_low_nodata_counts_equal_a_direct_count(tmp_path: Path, seed: int, full: bool) -> None:
    rng = np.random.default_rng(seed)
    h, w = 600, 700
    px = rng.integers(1, 256, (3, h, w), dtype=np.uint8)
    for band in range(3):  # zeros in a few row ranges of each band, some shared by every band
        r0 = int(rng.integers(0, h - 50))
        px[band, r0 : r0 + 40][rng.random((40, w)) < 0.3] = 0
    px[:, 100:110, 200:260] = 0  # nodata in every band: not told apart
    for band in range(
        3
    ):  # and scattered zeros in every chunk of every band, some shared by two bands
        px[band][rng.random((h, w)) < 0.01 * (band + 1)] = 0
    px[:2, 300:305, :] = 0
    path = tmp_path / "zeros.tif"
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=w,
        height=h,
        count=3,
        dtype="uint8",
        nodata=0,
        crs="EPSG:25832",
        transform=from_origin(500000, 5400000, 0.25, 0.25),
        tiled=True,
        blockxsize=256,
        blockysize=256,
    ) as ds:
        ds.write(px)
    r = scan_raster(
        path,
        ScanSettings(
            noise=full,
            luminosity=full,
            misregistration=False,
            noise_max_pixels=0,
            chunk_bytes=3 * 256 * 700,
        ),
    )
    at = px == 0
    every = int(np.count_nonzero(at.all(axis=0)))
    rest = h * w - every
    assert r.low_nodata is not None
    assert r.low_nodata["pixels_nodata_in_every_band"] == every
    for band in range(3):
        told = int(np.count_nonzero(at[band])) - every
        assert r.low_nodata["saturation_low_told_pct"][str(band + 1)] == pytest.approx(
            100.0 * told / rest
        )
