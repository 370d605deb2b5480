"""Streaming scans equal GDAL's exact statistics, never write into the delivery."""

from __future__ import annotations

import math
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine
from scipy import ndimage

from orthospec.errors import MeasureError
from orthospec.raster.reading import (
    ScanSettings,
    chunk_windows,
    mask_share,
    open_read_only,
    read_only_env,
    scan_raster,
)

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
RGB = REAL / "RGB.byte.tif"


def write_tif(path: Path, data: np.ndarray, **profile) -> Path:
    """A GeoTIFF in EPSG:25832 with 0.5 m pixels; ``profile`` adds creation options."""
    if data.ndim == 2:
        data = data[None]
    mask = profile.pop("mask", None)
    prof = dict(driver="GTiff", width=data.shape[2], height=data.shape[1], count=data.shape[0],
                dtype=data.dtype, crs="EPSG:25832",
                transform=Affine(0.5, 0, 500000, 0, -0.5, 5600000))
    prof.update(profile)
    with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True), rasterio.open(path, "w", **prof) as ds:
        ds.write(data)
        if mask is not None:
            ds.write_mask(mask)
    return path


def gdal_exact(path: Path, tmp_path: Path) -> list[tuple[float, float, float, float]]:
    """GDAL's exact statistics, computed on a copy (the call may write .aux.xml)."""
    copy = tmp_path / "gdal_copy" / path.name
    copy.parent.mkdir(exist_ok=True)
    shutil.copy(path, copy)
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(copy) as ds:
            for b in range(1, ds.count + 1):
                s = ds.statistics(b, approx=False, clear_cache=True)
                out.append((s.min, s.max, s.mean, s.std))
    return out


def assert_equals_gdal(path: Path, tmp_path: Path, **settings) -> list:
    stats = scan_raster(path, ScanSettings(**settings))
    ref = gdal_exact(path, tmp_path)
    assert len(stats.bands) == len(ref)
    for b, (mn, mx, mean, std) in zip(stats.bands, ref, strict=True):
        assert (b.min, b.max) == (mn, mx)
        assert b.mean == pytest.approx(mean, rel=1e-10)
        assert b.std == pytest.approx(std, rel=1e-9)
    return stats.bands


def test_real_rgb_equals_gdal_exact_statistics(tmp_path):
    bands = assert_equals_gdal(RGB, tmp_path)
    with rasterio.open(RGB) as ds:
        a = ds.read()
    for i, b in enumerate(bands):
        valid = a[i][a[i] != 0]
        assert b.valid == valid.size
        assert b.histogram.offset == valid.min()
        assert sum(b.histogram.counts) == valid.size
        assert b.histogram.counts[-1] == np.count_nonzero(valid == 255)
        assert b.saturation_high_pct == pytest.approx(100 * np.mean(valid == 255))
        assert b.nodata_fraction == pytest.approx(np.mean(a[i] == 0))
        assert b.nodata == 0.0 and b.saturation_low_hidden  # DN 0 is nodata here


def test_stale_statistics_tags_in_the_file_are_not_trusted():
    # RGB.byte.tif carries STATISTICS_MINIMUM=0 computed without nodata; we recompute
    with rasterio.open(RGB) as ds:
        assert ds.tags(1)["STATISTICS_MINIMUM"] == "0"
    assert scan_raster(RGB).bands[0].min == 1.0


def test_scan_writes_nothing_next_to_the_input(tmp_path):
    src = tmp_path / "delivery"
    src.mkdir()
    f = shutil.copy(RGB, src / "img.tif")
    before = sorted(p.name for p in src.iterdir())
    scan_raster(f)
    with read_only_env(), open_read_only(f) as ds:
        assert ds.mode == "r"
    assert sorted(p.name for p in src.iterdir()) == before == ["img.tif"]


@pytest.fixture
def rng():
    return np.random.default_rng(123)


def test_8bit_tiled_deflate_with_nodata(tmp_path, rng):
    a = rng.integers(0, 256, (3, 300, 260), dtype=np.uint8)
    a[:, :40, :] = 7
    f = write_tif(tmp_path / "t.tif", a, tiled=True, blockxsize=64, blockysize=64,
                  compress="deflate", nodata=7)
    bands = assert_equals_gdal(f, tmp_path)
    assert all(b.valid == np.count_nonzero(a[i] != 7) for i, b in enumerate(bands))
    assert not bands[0].saturation_low_hidden


def test_16bit_eleven_bit_striped_nbits(tmp_path, rng):
    a = rng.integers(0, 2048, (1, 257, 199), dtype=np.uint16)
    a[0, 0, :5] = 2047
    f = write_tif(tmp_path / "s11.tif", a, nbits=11, blockysize=16, nodata=0)
    bands = assert_equals_gdal(f, tmp_path)
    b = bands[0]
    assert (b.bit_depth, b.bit_depth_source, b.range_high) == (11, "NBITS", 2047)
    assert b.used_bits == 11
    valid = a[a != 0]
    assert b.saturation_high_pct == pytest.approx(100 * np.mean(valid == 2047))
    assert b.cv_percent == pytest.approx(100 * valid.std() / 2048)
    # an explicit --bit-depth wins over the tag
    s12 = scan_raster(f, ScanSettings(bit_depth=12)).bands[0]
    assert (s12.bit_depth, s12.bit_depth_source) == (12, "argument")


def test_16bit_tiled_without_nbits_uses_full_container(tmp_path, rng):
    a = rng.integers(100, 60000, (2, 200, 300), dtype=np.uint16)
    f = write_tif(tmp_path / "u16.tif", a, tiled=True, blockxsize=128, blockysize=128,
                  compress="lzw")
    bands = assert_equals_gdal(f, tmp_path)
    assert bands[0].bit_depth == 16 and bands[0].range_high == 65535


def test_jpeg_compressed_matches_gdal_on_decoded_pixels(tmp_path, rng):
    a = ndimage.gaussian_filter(rng.integers(0, 256, (3, 256, 256)).astype(float), (0, 3, 3))
    a = (a - a.min()) / (a.max() - a.min()) * 255
    f = write_tif(tmp_path / "j.tif", a.astype(np.uint8), compress="jpeg", tiled=True,
                  blockxsize=128, blockysize=128)
    assert_equals_gdal(f, tmp_path)


def test_internal_mask_and_alpha_follow_gdal(tmp_path, rng):
    a = rng.integers(0, 256, (3, 120, 150), dtype=np.uint8)
    m = np.full((120, 150), 255, np.uint8)
    m[:50] = 0
    f = write_tif(tmp_path / "m.tif", a, mask=m)
    bands = assert_equals_gdal(f, tmp_path)
    assert bands[0].valid == 70 * 150
    alpha = np.full((1, 120, 150), 255, np.uint8)
    alpha[0, :30] = 0
    f2 = write_tif(tmp_path / "a.tif", np.concatenate([a, alpha]), photometric="RGB",
                   alpha="YES")
    bands2 = assert_equals_gdal(f2, tmp_path)
    assert [b.valid for b in bands2] == [90 * 150] * 3 + [120 * 150]


def test_float32_with_nodata_and_nan(tmp_path, rng):
    a = rng.normal(1000, 50, (1, 150, 170)).astype(np.float32)
    a[0, :10] = -9999
    a[0, 20, :30] = np.nan
    f = write_tif(tmp_path / "f.tif", a, nodata=-9999, tiled=True, blockxsize=64, blockysize=64)
    b = assert_equals_gdal(f, tmp_path)[0]
    assert b.valid == 140 * 170 - 30
    assert sum(b.histogram.counts) == b.valid
    assert b.histogram.edges[0] == b.min and b.histogram.edges[-1] == pytest.approx(b.max)
    assert b.saturation_low_pct is None  # no bit depth for float data unless declared


def test_signed_int16(tmp_path, rng):
    a = rng.integers(-500, 3000, (1, 90, 80), dtype=np.int16)
    f = write_tif(tmp_path / "i16.tif", a, nodata=-500)
    assert_equals_gdal(f, tmp_path)


def test_jpeg2000_is_read(tmp_path, rng):
    a = rng.integers(0, 256, (1, 64, 64), dtype=np.uint8)
    f = tmp_path / "x.jp2"
    with rasterio.open(f, "w", driver="JP2OpenJPEG", width=64, height=64, count=1,
                       dtype="uint8", crs="EPSG:25832", transform=Affine(1, 0, 0, 0, -1, 64),
                       reversible="YES", quality=100) as ds:
        ds.write(a)
    b = scan_raster(f).bands[0]
    assert (b.min, b.max, b.mean) == (a.min(), a.max(), pytest.approx(a.mean()))


def test_chunks_are_whole_blocks_and_bounded(tmp_path, rng):
    a = rng.integers(0, 256, (3, 700, 900), dtype=np.uint8)
    f = write_tif(tmp_path / "c.tif", a, tiled=True, blockxsize=128, blockysize=128)
    with rasterio.open(f) as ds:
        wins = list(chunk_windows(ds, chunk_bytes=128 * 128 * 3 * 2))
    covered = np.zeros((700, 900), int)
    for w in wins:
        assert w.row_off % 128 == 0 and w.col_off % 128 == 0
        assert w.height * w.width * 3 <= 128 * 128 * 3 * 2
        covered[w.row_off:w.row_off + w.height, w.col_off:w.col_off + w.width] += 1
    assert (covered == 1).all()
    # any chunking gives the same statistics (exact histogram merge)
    small = scan_raster(f, ScanSettings(chunk_bytes=128 * 128 * 3))
    big = scan_raster(f, ScanSettings(chunk_bytes=64 * 2**20))
    assert small.chunks > big.chunks == 1
    for s, b in zip(small.bands, big.bands, strict=True):
        assert (s.mean, s.std, s.histogram) == (b.mean, b.std, b.histogram)


@pytest.mark.parametrize("dtype", ["uint8", "float32"])
def test_scan_results_do_not_depend_on_the_counting_threads(tmp_path, rng, dtype):
    """Chunks queue up per counting thread (a slow chunk does not stall the others), yet each
    accumulator set still takes its chunks in order: one thread or two, the same bits, also
    for floating-point sums (float moments, noise)."""
    a = rng.normal(120, 30, (3, 600, 700)).clip(1, 255).astype(dtype)
    a[:, :40] = 0
    f = write_tif(tmp_path / "t.tif", a, tiled=True, blockxsize=64, blockysize=64, nodata=0,
                  photometric="RGB")
    runs = [scan_raster(f, ScanSettings(chunk_bytes=64 * 64 * 3 * 4 * 2, noise_max_pixels=0,
                                        threads=t)) for t in (1, 2, 2)]
    assert runs[0].chunks >= 20
    assert runs[0].to_dict() == runs[1].to_dict() == runs[2].to_dict()


@pytest.mark.parametrize("dtype", ["uint8", "uint16"])
def test_luminosity_histogram_of_rgb(tmp_path, rng, dtype):
    top = 255 if dtype == "uint8" else 4095
    a = rng.integers(1, top, (3, 64, 64), endpoint=True, dtype=dtype)
    a[:, 0, 0] = 0  # nodata in all bands at one pixel, in band 1 only at another
    a[0, 0, 1] = 0
    a[2, 5, 7] = 0  # and in band 3 only at a third
    f = write_tif(tmp_path / "rgb.tif", a, photometric="RGB", nodata=0)
    lum = scan_raster(f).luminosity
    ai = a.astype(np.int64)
    y = (299 * ai[0] + 587 * ai[1] + 114 * ai[2] + 500) // 1000  # exact, ties round up
    valid = (a != 0).all(axis=0)
    assert lum.valid == valid.sum() == 64 * 64 - 3
    assert lum.mean == pytest.approx(y[valid].mean(), rel=1e-12)
    expected = np.bincount(y[valid], minlength=top + 1)
    assert list(lum.histogram.counts) == expected[lum.histogram.offset:int(lum.max) + 1].tolist()


def test_band_misregistration_detects_known_shift(tmp_path, rng):
    base = ndimage.gaussian_filter(rng.normal(size=(300, 300)), 2.0)
    shifted = np.fft.ifft2(ndimage.fourier_shift(np.fft.fft2(base), (0.0, 1.5))).real
    a = np.stack([shifted, base, base])
    a = ((a - a.min()) / (a.max() - a.min()) * 200 + 20).astype(np.uint8)
    f = write_tif(tmp_path / "mis.tif", a, photometric="RGB")
    stats = scan_raster(f)
    assert stats.reference_band == 2
    assert stats.misregistration[1].dx == pytest.approx(1.5, abs=0.1)
    assert stats.misregistration[1].magnitude > 1.0  # over the JRC 1 px limit
    assert stats.misregistration[3].magnitude < 0.1


def test_cloud_mask_share(tmp_path):
    m = np.zeros((100, 100), np.uint8)
    m[:10, :50] = 1
    m[90:] = 255  # nodata rows
    f = write_tif(tmp_path / "cloud.tif", m, nodata=255)
    acc = mask_share(f)
    assert acc.valid == 9000 and acc.percent == pytest.approx(100 * 500 / 9000)


@pytest.mark.parametrize("layout", [
    dict(compress="deflate", tiled=True, blockxsize=128, blockysize=128),
    dict(tiled=True, blockxsize=128, blockysize=128),  # uncompressed: GDAL's direct I/O path
    dict(blockysize=16),                               # uncompressed strips
])
@pytest.mark.parametrize("user_env", [{}, {"GTIFF_DIRECT_IO": "YES"},
                                      {"GTIFF_VIRTUAL_MEM_IO": "YES"}])
def test_truncated_file_raises_measure_error(tmp_path, rng, layout, user_env, monkeypatch):
    """Never zeros for missing pixels: also not when the environment asks GDAL for direct I/O
    (which then fills the missing strips of an uncompressed file with zeros, silently)."""
    for k, v in user_env.items():
        monkeypatch.setenv(k, v)
    a = rng.integers(0, 256, (3, 512, 512), dtype=np.uint8)
    f = write_tif(tmp_path / "trunc.tif", a, **layout)
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])
    with pytest.raises(MeasureError, match=r"trunc\.tif"):
        scan_raster(f)


@pytest.mark.skipif(shutil.which("gdalinfo") is None, reason="gdalinfo (gdal-bin) not installed")
def test_equals_gdalinfo_stats(tmp_path, rng):
    a = rng.integers(0, 2048, (2, 120, 130), dtype=np.uint16)
    f = write_tif(tmp_path / "g.tif", a, nodata=3)
    copy = tmp_path / "copy.tif"
    shutil.copy(f, copy)
    out = subprocess.run(["gdalinfo", "-stats", "-json", str(copy)], capture_output=True,
                         text=True, check=True).stdout
    import json

    doc = json.loads(out)
    for b, gb in zip(scan_raster(f).bands, doc["bands"], strict=True):
        md = gb["metadata"][""]  # full precision (the top-level keys are rounded)
        assert (b.min, b.max) == (float(md["STATISTICS_MINIMUM"]), float(md["STATISTICS_MAXIMUM"]))
        assert b.mean == pytest.approx(float(md["STATISTICS_MEAN"]), rel=1e-9)
        assert b.std == pytest.approx(float(md["STATISTICS_STDDEV"]), rel=1e-9)


@pytest.mark.skipif(shutil.which("gdalinfo") is None, reason="gdalinfo (gdal-bin) not installed")
def test_8bit_histogram_equals_gdalinfo_hist(tmp_path):
    copy = Path(shutil.copy(RGB, tmp_path / "rgb.tif"))
    out = subprocess.run(["gdalinfo", "-hist", "-json", str(copy)], capture_output=True,
                         text=True, check=True).stdout
    import json

    doc = json.loads(out)
    for b, gb in zip(scan_raster(RGB).bands, doc["bands"], strict=True):
        h = gb["histogram"]
        assert (h["count"], h["min"], h["max"]) == (256, -0.5, 255.5)  # one bucket per DN
        ours = [0] * 256
        ours[b.histogram.offset:b.histogram.offset + len(b.histogram.counts)] = list(
            b.histogram.counts)
        assert ours == h["buckets"]


def _gdal_buckets_of(hist, gdal_hist: dict) -> list[int]:
    """Our per-DN histogram put into gdalinfo's buckets (GDAL's ComputeHistogram binning:
    floor((DN - min) * count / (max - min)) over the range gdalinfo reports)."""
    n, lo, hi = gdal_hist["count"], gdal_hist["min"], gdal_hist["max"]
    out = [0] * n
    for i, c in enumerate(hist.counts):
        if c:
            out[min(max(math.floor((hist.offset + i - lo) * (n / (hi - lo))), 0), n - 1)] += c
    return out


@pytest.mark.skipif(shutil.which("gdalinfo") is None, reason="gdalinfo (gdal-bin) not installed")
@pytest.mark.parametrize("case", ["uint8-nodata", "uint8-mask", "uint16-nodata"])
def test_histograms_with_invalid_pixels_equal_gdalinfo_hist_over_many_chunks(tmp_path, rng, case):
    """Issue 14: the counting paths (Pillow for bytes, under a GDAL mask too; numpy for 16
    bits) give gdalinfo's own histograms with the nodata pixels excluded, over many chunks.
    gdalinfo's histogram (GDAL 3.6) ignores a per-dataset mask, its statistics do not: the
    masked case is checked against the known valid pixels instead."""
    import json

    dtype, kind = case.split("-")
    top = 255 if dtype == "uint8" else 2047
    a = rng.integers(0, top, (3, 700, 900), endpoint=True, dtype=dtype)
    a[:, 100:180, 200:400] = 0  # a nodata block, and scattered zeros (random) besides
    profile = dict(tiled=True, blockxsize=128, blockysize=128, photometric="RGB")
    valid = np.ones((700, 900), bool)
    if kind == "nodata":
        profile["nodata"] = 0
    else:
        m = np.full((700, 900), 255, np.uint8)
        m[300:420, :500] = 0
        valid = m != 0
        profile["mask"] = m
    f = write_tif(tmp_path / f"{case}.tif", a, **profile)
    stats = scan_raster(f, ScanSettings(chunk_bytes=128 * 128 * 3 * 4))
    assert stats.chunks > 10
    if kind == "mask":
        for i, b in enumerate(stats.bands):
            want = np.bincount(a[i][valid], minlength=256)
            assert b.valid == valid.sum() < a[i].size
            assert list(b.histogram.counts) == want[b.histogram.offset:int(b.max) + 1].tolist()
        return
    copy = Path(shutil.copy(f, tmp_path / "gdal_copy.tif"))
    doc = json.loads(subprocess.run(["gdalinfo", "-hist", "-json", str(copy)], capture_output=True,
                                    text=True, check=True).stdout)
    for i, (b, gb) in enumerate(zip(stats.bands, doc["bands"], strict=True)):
        h = gb["histogram"]
        assert sum(h["buckets"]) == b.valid == np.count_nonzero(a[i]) < a[i].size
        if dtype == "uint8":
            assert (h["count"], h["min"], h["max"]) == (256, -0.5, 255.5)  # one bucket per DN
        assert _gdal_buckets_of(b.histogram, h) == h["buckets"]


def test_huge_single_block_is_read_in_bounded_row_windows(tmp_path, rng):
    a = rng.integers(0, 256, (1, 400, 300), dtype=np.uint8)
    f = write_tif(tmp_path / "strips.tif", a, blockysize=64)
    with rasterio.open(f) as ds:
        bh, bw = ds.block_shapes[0]
        assert bh * bw > 4 * 3000  # one block is bigger than four chunks
        wins = list(chunk_windows(ds, chunk_bytes=3000))
    assert len(wins) == 40 and all(w.height * w.width <= 3000 for w in wins)
    assert sum(w.height for w in wins) == 400
    small = scan_raster(f, ScanSettings(chunk_bytes=3000)).bands[0]
    assert (small.mean, small.std) == (pytest.approx(a.mean()), pytest.approx(a.std()))


def test_nodata_outside_the_dtype_range_excludes_nothing(tmp_path, rng):
    a = rng.integers(0, 2048, (1, 64, 64), dtype=np.uint16)
    a[0, 0, 0] = 55537  # what -9999 would wrap to
    f = write_tif(tmp_path / "nd.tif", a)
    with rasterio.open(f, "r+") as ds:
        ds.nodata = 70000  # not representable in uint16
    b = assert_equals_gdal(f, tmp_path)[0]
    assert b.valid == 64 * 64


# --------------------------------------------------------------------------- hostile files (issue 17)


def test_a_geotiff_named_vrt_is_refused_before_gdal_opens_it(tmp_path):
    outside = write_tif(tmp_path / "outside.tif", np.full((8, 8), 7, np.uint8))
    fake = tmp_path / "d" / "a.tif"
    fake.parent.mkdir()
    fake.write_text(
        f'<VRTDataset rasterXSize="8" rasterYSize="8"><VRTRasterBand dataType="Byte" band="1">'
        f"<SimpleSource><SourceFilename>{outside}</SourceFilename><SourceBand>1</SourceBand>"
        f"</SimpleSource></VRTRasterBand></VRTDataset>"
    )
    with pytest.raises(
        MeasureError,
        match=r"a.tif: not a readable raster: not a GeoTIFF or JPEG 2000 file "
        r"\(XML: a GDAL VRT\?\)",
    ):
        open_read_only(fake, name="a.tif")
    with pytest.raises(MeasureError, match="not a GeoTIFF"):
        scan_raster(fake)


def test_fifo_and_vsi_paths_are_refused_without_blocking(tmp_path):
    import os

    pipe = tmp_path / "p.tif"
    os.mkfifo(pipe)
    with pytest.raises(MeasureError, match="p.tif: not a regular file"):
        open_read_only(pipe, name="p.tif")
    with pytest.raises(MeasureError, match="file not found"):
        open_read_only("/vsicurl/http://127.0.0.1:9/x.tif")


def test_declared_size_is_refused_before_reading(tmp_path):
    import time

    from orthospec.raster.reading import RasterLimits

    big = tmp_path / "big.tif"
    with rasterio.open(
        big,
        "w",
        driver="GTiff",
        width=10**6,
        height=10**6,
        count=1,
        dtype="uint8",
        tiled=True,
        blockxsize=4096,
        blockysize=4096,
        BIGTIFF="YES",
        SPARSE_OK=True,
        crs="EPSG:25832",
        transform=Affine(0.5, 0, 500000, 0, -0.5, 5600000),
    ):
        pass
    t0 = time.perf_counter()
    with pytest.raises(
        MeasureError,
        match=r"declares 1,000,000 x 1,000,000 = 1,000,000,000,000 pixels, more "
        r"than the limit of 4,294,967,296",
    ):
        scan_raster(big)
    assert time.perf_counter() - t0 < 1.0
    bands = write_tif(tmp_path / "bands.tif", np.ones((70, 2, 2), np.uint8))
    with pytest.raises(MeasureError, match="declares 70 bands, more than the limit of 64"):
        scan_raster(bands)
    with read_only_env(), open_read_only(bands, limits=RasterLimits(bands=70)) as ds:
        assert ds.count == 70


def test_wal_geopackage_is_read_without_touching_the_delivery(tmp_path):
    import hashlib
    import sqlite3

    import pyogrio
    import shapely

    from orthospec.raster.reading import read_vector

    build = tmp_path / "build.gpkg"
    geoms = np.array([shapely.to_wkb(shapely.box(0, 0, 1, 1))], dtype=object)
    pyogrio.raw.write(
        str(build),
        geometry=geoms,
        field_data=[np.array([1])],
        fields=["seam"],
        geometry_type="Polygon",
        crs="EPSG:25832",
        driver="GPKG",
    )
    con = sqlite3.connect(build)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute("UPDATE gpkg_contents SET description = 'changed in the WAL'")
    con.commit()
    d = tmp_path / "d"
    d.mkdir()
    for suffix in ("", "-wal"):
        shutil.copyfile(f"{build}{suffix}", d / f"s.gpkg{suffix}")
    con.close()

    def state():
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.iterdir())}

    before = state()
    assert set(before) == {"s.gpkg", "s.gpkg-wal"}
    got, crs = read_vector(d / "s.gpkg")
    assert len(got) == 1 and got[0].equals(shapely.box(0, 0, 1, 1)) and "25832" in crs
    assert state() == before


def test_an_ogr_vrt_named_gpkg_is_refused(tmp_path):
    from orthospec.raster.reading import read_vector

    f = tmp_path / "seamlines.gpkg"
    f.write_text(
        "<OGRVRTDataSource><OGRVRTLayer name='x'><SrcDataSource>/etc/passwd</SrcDataSource>"
        "</OGRVRTLayer></OGRVRTDataSource>"
    )
    with pytest.raises(
        MeasureError,
        match=r"not a readable vector file: not a GeoPackage or shapefile "
        r"\(XML: an OGR VRT\?\)",
    ):
        read_vector(f, name="seamlines.gpkg")


def test_gdal_errors_carry_the_file_not_the_absolute_path(tmp_path):
    from orthospec.raster.reading import gdal_errors

    trunc = tmp_path / "t.tif"
    good = write_tif(tmp_path / "g.tif", np.ones((64, 64), np.uint8))
    trunc.write_bytes(good.read_bytes()[:100])
    with pytest.raises(MeasureError) as info, gdal_errors(file="images/t.tif", path=trunc):
        rasterio.open(trunc)
    assert str(info.value).startswith("images/t.tif: not a readable raster") and str(
        tmp_path
    ) not in str(info.value)


def test_a_plain_sqlite_file_named_gpkg_is_refused(tmp_path):
    """Only a GeoPackage (application_id GPKG) goes to GDAL; another SQLite file could hold OGR
    virtual tables pointing anywhere."""
    import sqlite3

    from orthospec.raster.reading import read_vector

    f = tmp_path / "seamlines.gpkg"
    con = sqlite3.connect(f)
    con.execute("CREATE TABLE t (a)")
    con.commit()
    con.close()
    with pytest.raises(MeasureError, match="not a GeoPackage or shapefile"):
        read_vector(f)
