"""The streaming scan recycles its chunk buffers and work arrays (issue 14, radiometry at the
physical limit): the numbers must be those of the whole image read at once.

A chunk's buffer receives a later chunk once it is counted, and the luminosity and darkest-value
temporaries are per-thread arrays reused for every chunk. A buffer handed back too early (while
a counting thread or the misregistration capture still reads it) would mix two chunks: these
tests compare a many-chunk scan, ragged last chunks included, with numpy over the whole image
(exact histograms, GDAL's population statistics, the Rec. 601 luma formula) and with the
misregistration windows read directly from the file.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.windows import Window
from scipy import ndimage
from tests.test_raster_reading import write_tif

from orthospec.measures import radiometry as rad
from orthospec.raster.reading import ScanSettings, _MisregistrationWindows, band_infos, scan_raster


def _write(path: Path, data: np.ndarray, mask: np.ndarray | None = None, **profile) -> Path:
    """An RGB GeoTIFF in 64 x 64 tiles (many chunks per scan)."""
    return write_tif(
        path,
        data,
        mask=mask,
        **{"photometric": "RGB", "tiled": True, "blockxsize": 64, "blockysize": 64, **profile},
    )


def _textured(rng: np.random.Generator, dtype: str, shape: tuple[int, int]) -> np.ndarray:
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    top = 255 if dtype == "uint8" else 2047
    base = (np.sin(xx / 13.0) + np.cos(yy / 7.0) + 2) * top / 4.5
    a = base[None] * np.array([0.8, 0.9, 1.0])[:, None, None] + rng.normal(0, top / 50, (3, h, w))
    return np.clip(a, 1, top).astype(dtype)


#: 8 x 8 tiles of 64 px, partial tiles at the right and bottom edges; three tiles (of three
#: bands) per chunk: chunks of a row of tiles are two of 3 tiles and a narrower last one
SHAPE = (470, 455)
CHUNK = 64 * 64 * 3 * 3


@pytest.mark.parametrize("dtype", ["uint8", "uint16"])
@pytest.mark.parametrize("invalid", ["nodata", "mask"])
def test_many_chunk_full_scan_equals_the_whole_image_at_once(tmp_path, dtype, invalid):
    rng = np.random.default_rng(14)
    a = _textured(rng, dtype, SHAPE)
    if invalid == "nodata":
        a[:, 100:130, 200:260] = 0  # nodata in all three bands
        a[1, 300:310, 10:400] = 0  # and in the green band only
        f = _write(tmp_path / "n.tif", a, nodata=0)
        valid = a != 0
        lum_valid = valid.all(axis=0)
    else:
        mask = np.full(SHAPE, 255, np.uint8)
        mask[50:90, 20:300] = 0
        f = _write(tmp_path / "m.tif", a, mask=mask)
        valid = np.broadcast_to(mask != 0, a.shape)
        lum_valid = mask != 0

    stats = scan_raster(
        f, ScanSettings(chunk_bytes=CHUNK * np.dtype(dtype).itemsize, noise_max_pixels=0, threads=2)
    )
    assert stats.chunks >= 3 * 8  # many chunks, so buffers are recycled many times over

    for band, b in zip(stats.bands, range(3), strict=True):
        v = a[b][valid[b]].astype(np.int64)
        assert (band.valid, band.min, band.max) == (v.size, v.min(), v.max())
        assert band.mean == pytest.approx(v.mean(), rel=1e-12)
        assert band.std == pytest.approx(v.std(), rel=1e-9)  # population std, as GDAL
        counts = np.bincount(v - v.min())
        assert list(band.histogram.counts) == counts.tolist()

    ai = a.astype(np.int64)
    y = (299 * ai[0] + 587 * ai[1] + 114 * ai[2] + 500) // 1000  # Rec. 601, ties round up
    yv = y[lum_valid]
    lum = stats.luminosity
    assert (lum.valid, lum.min, lum.max) == (yv.size, yv.min(), yv.max())
    assert list(lum.histogram.counts) == np.bincount(yv - yv.min()).tolist()


def test_misregistration_windows_copied_from_recycled_chunks_equal_direct_reads(tmp_path):
    """The capture copies its windows out of the chunks as they pass: the shifts equal those
    of the same windows read straight from the file (one window per read)."""
    rng = np.random.default_rng(7)
    base = ndimage.gaussian_filter(rng.normal(size=SHAPE), 2.0)  # aperiodic texture
    base = (base - base.min()) / (base.max() - base.min()) * 200 + 20
    a = np.stack([np.roll(base, 2, axis=1), base, base]).astype(np.uint8)  # red: 2 px right
    f = _write(tmp_path / "r.tif", a)
    stats = scan_raster(f, ScanSettings(chunk_bytes=CHUNK, noise=False, luminosity=False))

    with rasterio.open(f) as ds:
        plan = _MisregistrationWindows.plan(ds, band_infos(ds, None))
        direct: dict[int, list[rad.Shift]] = {1: [], 3: []}
        for w in plan.windows:
            win = ds.read(window=Window(w.col_off, w.row_off, w.width, w.height)).astype(float)
            f_ref = rad.tapered_spectrum(win[1])
            for idx in (1, 3):
                direct[idx].append(
                    rad.phase_correlation_spectra(
                        f_ref, rad.tapered_spectrum(win[idx - 1]), upsample=20
                    )
                )
    assert len(plan.windows) == 5
    for idx, shifts in direct.items():
        got = stats.misregistration[idx]
        assert got.dx == float(np.median([s.dx for s in shifts]))
        assert got.dy == float(np.median([s.dy for s in shifts]))
    assert stats.misregistration[1].dx == pytest.approx(2.0, abs=0.1)


def test_scratch_arrays_are_per_thread_and_reused():
    first = rad.scratch("test", (4, 5), np.uint32)
    again = rad.scratch("test", (2, 3), np.uint32)  # smaller: a view of the same memory
    assert np.shares_memory(first, again) and again.shape == (2, 3)
    bigger = rad.scratch("test", (10, 10), np.uint32)
    assert bigger.shape == (10, 10) and bigger.dtype == np.uint32
    other: list[np.ndarray] = []
    t = threading.Thread(target=lambda: other.append(rad.scratch("test", (10, 10), np.uint32)))
    t.start()
    t.join()
    assert not np.shares_memory(bigger, other[0])  # counting threads never share one


@pytest.mark.parametrize("dtype", ["uint8", "uint16", "float32"])
def test_noise_of_sampled_chunks_added_in_a_side_thread_equals_each_chunk_added_in_turn(
    tmp_path, dtype
):
    """Integer bands' noise is added by a side thread, one accumulator per chunk merged at the
    end (float bands stay in the counting thread, in order): the sigmas equal those of every
    sampled chunk's pixels added one after the other, as read straight from the file."""
    from orthospec.raster.reading import chunk_windows

    rng = np.random.default_rng(21)
    a = _textured(rng, "uint16", SHAPE).astype(dtype)
    a[:, 100:104, 50:300] = 0  # a few nodata pixels: the validity path too
    f = _write(tmp_path / "z.tif", a, nodata=0)
    chunk = CHUNK * np.dtype(dtype).itemsize
    stride = 3  # every third chunk, as noise_max_pixels samples a big image
    settings = ScanSettings(
        chunk_bytes=chunk,
        noise_max_pixels=SHAPE[0] * SHAPE[1] // stride + 1,
        luminosity=False,
        misregistration=False,
    )
    got = scan_raster(f, settings)

    with rasterio.open(f) as ds:
        wins = list(chunk_windows(ds, chunk))
    assert len(wins) > 2 * stride
    want = {b: rad.NoiseAccumulator() for b in range(3)}
    for w in wins[::stride]:
        for b in range(3):
            band = a[b, w.row_off : w.row_off + w.height, w.col_off : w.col_off + w.width]
            want[b].add(band, band != 0)
    for b in range(3):
        assert got.bands[b].noise_sigma_immerkaer == want[b].immerkaer_sigma
        assert got.bands[b].noise_sigma_homogeneous == want[b].homogeneous_sigma


def test_luminosity_of_stacked_planes_equals_the_formula_for_every_byte_triple():
    """The one-pass (einsum) luminosity of consecutive R, G, B planes gives Rec. 601's
    Y = (299 R + 587 G + 114 B + 500) // 1000 for all 2^24 byte triples, and for 16-bit
    values up to 65535 (the uint32 sum cannot overflow)."""
    v = np.arange(256, dtype=np.uint8)
    for red in range(0, 256, 32):  # 32 red values at a time: 2 M triples, small arrays
        planes = np.stack(np.meshgrid(v[red : red + 32], v, v, indexing="ij")).reshape(
            3, 2048, 1024
        )
        wide = planes.astype(np.int32)
        want = (299 * wide[0] + 587 * wide[1] + 114 * wide[2] + 500) // 1000
        assert np.array_equal(rad.luminosity_block(*planes, np.uint8, planes=planes), want)

    rng = np.random.default_rng(4)
    planes16 = rng.integers(0, 65535, (3, 300, 500), endpoint=True, dtype=np.uint16)
    planes16[:, 0, :3] = 65535
    wide = planes16.astype(np.int64)
    want16 = (299 * wide[0] + 587 * wide[1] + 114 * wide[2] + 500) // 1000
    assert np.array_equal(rad.luminosity_block(*planes16, np.uint16, planes=planes16), want16)
    assert np.array_equal(rad.luminosity_block(*planes16, np.uint16), want16)  # separate bands
