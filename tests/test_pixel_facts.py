"""Pixel facts of the one scan (issue 25) and DN-0 saturation under nodata 0 (issue 26).

Real GeoTIFFs written in tmp_path: the same pixels under several compressions, tilings and
georeferences must give the same content hash and thumbnail; one changed pixel must not.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

from orthospec.measures.copies import (
    NEAR_COPY,
    SAME_PIXELS,
    Content,
    aligned_correlation,
    find_copies,
)
from orthospec.measures.signature import (
    CloudCounter,
    PixelHash,
    Thumbnail,
    cloud_mask,
    thumbnail_geometry,
)
from orthospec.raster.reading import ScanSettings, scan_raster

T0 = Affine(0.25, 0, 500_000.0, 0, -0.25, 5_400_000.0)


def _write(path: Path, data: np.ndarray, *, transform: Affine = T0, **opts: object) -> Path:
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=data.shape[2],
        height=data.shape[1],
        count=data.shape[0],
        dtype=data.dtype,
        crs="EPSG:25832",
        transform=transform,
        **opts,
    ) as ds:
        ds.write(data)
    return path


@pytest.fixture
def pixels() -> np.ndarray:
    return np.random.default_rng(7).integers(1, 255, (4, 301, 517), dtype=np.uint8)


LAYOUTS = [
    {},
    {"tiled": True, "blockxsize": 256, "blockysize": 256, "compress": "deflate"},
    {"tiled": True, "blockxsize": 128, "blockysize": 16, "compress": "lzw", "nodata": 0},
    {"compress": "zstd", "interleave": "band"},
]


@pytest.mark.parametrize("chunk_bytes", [8 << 20, 40_000])
def test_hash_and_thumbnail_do_not_depend_on_the_file(
    tmp_path: Path, pixels: np.ndarray, chunk_bytes: int
) -> None:
    """Compression, tiling, interleave, nodata tag, georeference and chunking change every byte of the
    file and the windows of the scan, never the decoded-pixel facts."""
    s = ScanSettings(chunk_bytes=chunk_bytes)
    got = []
    for k, opts in enumerate(LAYOUTS):
        t = Affine(0.5, 0, 600_000.0 + k, 0, -0.5, 5_500_000.0) if k % 2 else T0
        r = scan_raster(_write(tmp_path / f"{k}.tif", pixels, transform=t, **opts), s)
        got.append((r.pixels_hash, r.thumbnail))
    assert len({h for h, _ in got}) == 1 and all(t == got[0][1] for _, t in got)
    # the thumbnail is the band mean per cell, here 17 x 17 px cells sampled every 8th px
    thumb = np.array(got[0][1], dtype=float)
    assert thumbnail_geometry(517, 301) == (17, 8, 18, 31) and thumb.shape == (18, 31)
    mean = pixels.astype(float).mean(axis=0)
    assert thumb[0, 0] == pytest.approx(mean[0:17:8, 0:17:8].mean(), abs=1e-3)
    assert thumb[17, 30] == pytest.approx(
        mean[296:301:8, 512:517:8].mean(), abs=1e-3
    )  # the global 8 px grid


def test_one_changed_pixel_changes_the_hash(tmp_path: Path, pixels: np.ndarray) -> None:
    base = scan_raster(_write(tmp_path / "a.tif", pixels)).pixels_hash
    seen = {base}
    for band, row, col, delta in [
        (0, 0, 0, 1),
        (3, 300, 516, 1),
        (2, 150, 257, 128),
        (1, 7, 8, 255),
    ]:
        changed = pixels.copy()
        changed[band, row, col] = np.uint8((int(changed[band, row, col]) + delta) % 256)
        seen.add(scan_raster(_write(tmp_path / f"c{band}.tif", changed)).pixels_hash)
    assert len(seen) == 5
    # moving two pixels (same values, other places) changes it too: the keys are positional
    swapped = pixels.copy()
    swapped[0, 0, 0], swapped[0, 0, 1] = pixels[0, 0, 1], pixels[0, 0, 0]
    if pixels[0, 0, 0] != pixels[0, 0, 1]:
        assert scan_raster(_write(tmp_path / "s.tif", swapped)).pixels_hash != base


def test_pixel_hash_is_linear_over_any_split() -> None:
    """A word split between two chunks (a window starting mid-word) adds up to the whole."""
    data = np.random.default_rng(1).integers(0, 65535, (2, 9, 23), dtype=np.uint16)
    whole = PixelHash(width=23, height=9, count=2, dtype="uint16")
    whole.add(data, 0, 0)
    parts = PixelHash(width=23, height=9, count=2, dtype="uint16")
    for c0, c1, r0, r1 in [(0, 5, 0, 4), (5, 23, 0, 4), (0, 3, 4, 9), (3, 23, 4, 9)]:
        parts.add(np.ascontiguousarray(data[:, r0:r1, c0:c1]), c0, r0)
    assert parts.value == whole.value and parts.hexdigest() == whole.hexdigest()
    other = PixelHash(width=23, height=9, count=2, dtype="int16")  # same bytes, another type
    other.add(data.view(np.int16), 0, 0)
    assert other.hexdigest() != whole.hexdigest()


def test_float_thumbnail_ignores_nan() -> None:
    data = np.full((1, 8, 8), 10.0, dtype=np.float32)
    data[0, :4, :4] = np.nan
    th = Thumbnail(width=8, height=8, dtype="float32", cells=2)
    th.add(data, 0, 0)
    assert th.result() == [[None, 10.0], [10.0, 10.0]]


@pytest.mark.parametrize("dtype", ["int16", "int8", "uint8", "uint16"])
def test_integer_thumbnail_is_the_exact_mean_signed_too(dtype: str) -> None:
    """Narrow integer sums: a negative DN must not wrap (int16 DEM-like data, uint8 imagery)."""
    info = np.iinfo(dtype)
    data = np.random.default_rng(5).integers(info.min, int(info.max) + 1, (3, 40, 37)).astype(dtype)
    th = Thumbnail(width=37, height=40, dtype=dtype, cells=4)  # 10 px cells sampled every 5th px
    for r0, r1 in [(0, 13), (13, 40)]:  # two chunks, the cut inside a cell
        th.add(np.ascontiguousarray(data[:, r0:r1]), 0, r0)
    mean = data.astype(float).mean(axis=0)
    got = np.array(th.result(), dtype=float)
    assert got.shape == (4, 4)
    assert got[0, 0] == pytest.approx(mean[0:10:5, 0:10:5].mean(), abs=1e-3)
    assert got[3, 3] == pytest.approx(mean[30:40:5, 30:37:5].mean(), abs=1e-3)


@pytest.mark.parametrize(
    ("dtype", "top"), [("uint8", 255.0), ("uint16", 4095.0), ("uint16", 65535.0)]
)
def test_integer_cloud_test_decides_as_the_float_one(dtype: str, top: float) -> None:
    """The integer path of CloudCounter gives the float cloud_mask's decisions, boundaries included."""
    rng = np.random.default_rng(9)
    base = rng.integers(int(0.6 * top), int(top) + 1, (1, 64, 64))
    data = np.clip(
        base + rng.integers(-int(0.06 * top), int(0.06 * top) + 1, (3, 64, 64)), 0, top
    ).astype(dtype)
    data[:, 0, 0] = 0  # nodata
    counts = []
    for fast in (True, False):
        cc = CloudCounter(rgb=(0, 1, 2), scale=(1.0 / top,) * 3, nodata=(0.0, 0.0, 0.0), sub=1)
        if fast:
            cc.add(data, 0, 0)
        else:  # the float path: scales that differ in the last bit keep it off the integer branch
            cc.scale = (1.0 / top, 1.0 / top, np.nextafter(1.0 / top, 1.0))
            cc.add(data, 0, 0)
        counts.append((cc.cloudy, cc.valid))
    planes = data.astype(np.float32) / np.float32(top)
    expected = int(np.count_nonzero(cloud_mask(*planes)))
    assert counts[0][1] == 64 * 64 - 1
    assert counts[0][0] == expected and 0 < expected < 64 * 64
    assert abs(counts[1][0] - expected) <= 2  # the float path (last-bit scale) agrees


def test_cloud_grey_range_beyond_the_type_is_never_bright() -> None:
    data = np.full((3, 4, 4), 255, dtype=np.uint8)
    cc = CloudCounter(rgb=(0, 1, 2), scale=(1.0 / 65535.0,) * 3, nodata=(None, None, None), sub=1)
    cc.add(data, 0, 0)
    assert (cc.cloudy, cc.valid) == (0, 16)


# --------------------------------------------------------------------------- issue 26: DN 0 under nodata 0


def _zeros(
    pixels: np.ndarray, share: float, bands: list[int], seed: int = 3
) -> tuple[np.ndarray, float]:
    rng = np.random.default_rng(seed)
    hit = rng.random(pixels.shape[1:]) < share
    out = pixels.copy()
    out[bands] = np.where(hit, 0, out[bands])
    return out, 100.0 * hit.mean()


def test_dark_saturation_told_apart_under_nodata_zero(tmp_path: Path, pixels: np.ndarray) -> None:
    """10.2 % of the pixels at DN 0 in the red band while the others are valid: saturated black, not no-data
    (issue 26 measured 0.000 % here, since the band's nodata 0 hid them)."""
    data, pct = _zeros(pixels, 0.102, [0])
    r = scan_raster(_write(tmp_path / "z.tif", data, nodata=0))
    low = r.low_nodata
    assert low is not None and low["pixels_nodata_in_every_band"] == 0
    assert low["saturation_low_told_pct"]["1"] == pytest.approx(pct, abs=1e-9)
    assert low["saturation_low_told_pct"]["2"] == 0.0
    # GDAL's per-band statistics still exclude them (the band's own saturation reads 0)
    assert r.bands[0].saturation_low_pct == 0.0


def test_dark_saturation_ambiguous_where_every_band_is_zero(
    tmp_path: Path, pixels: np.ndarray
) -> None:
    data, pct = _zeros(pixels, 0.05, [0, 1, 2, 3])
    data2, _ = _zeros(data, 0.03, [2], seed=9)
    r = scan_raster(_write(tmp_path / "z.tif", data2, nodata=0))
    low = r.low_nodata
    assert low is not None
    assert low["pixels_nodata_in_every_band_pct"] == pytest.approx(pct, abs=1e-9)
    # band 3's extra zeros (where the other bands are valid) are still told apart
    told = low["saturation_low_told_pct"]["3"]
    every = (data2 == 0).all(axis=0)
    expect = 100.0 * ((data2[2] == 0) & ~every).sum() / (~every).sum()
    assert told == pytest.approx(expect, abs=1e-9) and told > 0


def test_single_band_nodata_zero_cannot_be_told_apart(tmp_path: Path, pixels: np.ndarray) -> None:
    data, pct = _zeros(pixels[:1], 0.02, [0])
    r = scan_raster(_write(tmp_path / "p.tif", data, nodata=0))
    assert r.low_nodata is not None and r.low_nodata[
        "pixels_nodata_in_every_band_pct"
    ] == pytest.approx(pct)


def test_no_nodata_means_no_hidden_saturation(tmp_path: Path, pixels: np.ndarray) -> None:
    data, pct = _zeros(pixels, 0.02, [0])
    r = scan_raster(_write(tmp_path / "n.tif", data))
    assert r.low_nodata is None and r.bands[0].saturation_low_pct == pytest.approx(pct)


# --------------------------------------------------------------------------- copies (measures/copies.py)


def _field(seed: int, n: int = 160, sigma: float = 6.0) -> np.ndarray:
    from scipy.ndimage import gaussian_filter

    return gaussian_filter(np.random.default_rng(seed).standard_normal((n, n)), sigma) * 400 + 120


def _thumb(img: np.ndarray, cell: int = 4) -> np.ndarray:
    h, w = img.shape
    return (
        img[: h // cell * cell, : w // cell * cell]
        .reshape(h // cell, cell, w // cell, cell)
        .mean(axis=(1, 3))
    )


def _content(
    name: str, img: np.ndarray, left: float, top: float, *, h: str | None = None
) -> Content:
    th = _thumb(img)
    size = img.shape[0] * 0.25
    return Content(
        name, h or name, th, 4, 4, (left, top - size, left + size, top), (0.25, 0.25), "EPSG:25832"
    )


def test_aligned_correlation_finds_the_shift() -> None:
    big = _field(1)
    a, b = _thumb(big[:128, :128]), _thumb(big[8:136, 12:140])
    r, shift = aligned_correlation(a, b)  # type: ignore[misc]
    assert r == pytest.approx(1.0, abs=1e-9) and shift == (2, 3)
    other = aligned_correlation(a, _thumb(_field(2)[:128, :128]))
    assert other is not None and other[0] < 0.9


def test_copies_equal_pixels_near_copies_and_legitimate_overlap() -> None:
    big = _field(1)
    a = big[:128, :128]
    changed = a.copy()
    changed[60, 60] += 50  # one pixel changed
    imgs = [
        _content("A", a, 500_000, 5_400_032, h="same"),
        _content("B", a, 510_000, 5_400_032, h="same"),  # A's pixels, 10 km away
        _content("C", changed, 520_000, 5_400_032),  # one pixel changed, elsewhere
        _content("D", big[8:136, 12:140], 500_003, 5_400_030),  # overlaps A where the maps say
        _content("E", big[8:136, 12:140], 530_000, 5_400_032),  # A shifted, far away: a copy
        _content("F", _field(2)[:128, :128], 540_000, 5_400_032),  # another picture
        _content("G", np.full((128, 128), 7.0), 550_000, 5_400_032, h="flat"),
        _content(
            "H", np.full((128, 128), 7.0), 560_000, 5_400_032, h="flat"
        ),  # equal but flat: no finding
    ]
    got = find_copies(imgs)
    kinds = {k: {(m.other, m.kind) for m in v} for k, v in got.items()}
    assert ("B", SAME_PIXELS) in kinds["A"] and ("A", SAME_PIXELS) in kinds["B"]
    assert any(o in ("A", "B") and kind == NEAR_COPY for o, kind in kinds["C"])
    assert any(kind == NEAR_COPY for _, kind in kinds["E"])
    # D overlaps A where both georeferences put the common ground: not a copy of A (E, A's picture placed
    # far away, is a copy of both)
    assert "D" not in {o for o, _ in kinds["A"]} and {o for o, _ in kinds["D"]} == {"E"}
    assert "F" not in kinds and "G" not in kinds and "H" not in kinds
    # the same picture delivered twice on the same ground is a copy, not an overlap
    twice = find_copies(
        [_content("P", a, 500_000, 5_400_032), _content("Q", changed, 500_000, 5_400_032)]
    )
    assert {m.other for m in twice["P"]} == {"Q"}


def test_different_band_counts_are_not_compared() -> None:
    a = _field(1)[:128, :128]
    x = _content("X", a, 500_000, 5_400_032)
    y = Content(
        "Y",
        "y",
        _thumb(a + 0.1),
        4,
        1,
        (600_000, 5_400_000, 600_032, 5_400_032),
        (0.25, 0.25),
        "EPSG:25832",
    )
    assert find_copies([x, y]) == {}


# --------------------------------------------------------------------------- photo lay-down headings


@pytest.mark.parametrize("nudge", [0.0, 0.5])
def test_a_copied_station_does_not_turn_the_strip(nudge: float) -> None:
    """A row copied with its exposure station (as is, or nudged 0.5 m east) is the same station, not the
    photo's along-track neighbour: the heading stays along the strip (north-south here)."""
    from orthospec.measures.mosaic import strip_headings

    x = [1000.0, 1000.0, 1000.0, 1000.0 + nudge]
    y = [0.0, 1250.0, 2500.0, 1250.0]
    h = np.degrees(strip_headings(x, y, ["F"] * 4, min_distance=150.0))
    assert np.allclose(np.abs(h), 90.0, atol=0.1), h
    # without the minimum distance a nudged copy is taken for the neighbour (the old behaviour)
    if nudge:
        assert np.degrees(strip_headings(x, y, ["F"] * 4))[1] == pytest.approx(0.0, abs=0.1)
