"""File checks: format, compression, layout, bit depth, CRS, GSD, names, listing, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

from orthospec.raster.filechecks import check_file, check_name, listing_consistency

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
RGB = REAL / "RGB.byte.tif"


def write(path: Path, data: np.ndarray, **profile) -> Path:
    if data.ndim == 2:
        data = data[None]
    prof = dict(driver="GTiff", width=data.shape[2], height=data.shape[1], count=data.shape[0],
                dtype=data.dtype, crs="EPSG:25832", transform=Affine(0.25, 0, 5e5, 0, -0.25, 6e6))
    prof.update(profile)
    with rasterio.open(path, "w", **prof) as ds:
        ds.write(data)
    return path


@pytest.fixture
def img8():
    return np.random.default_rng(0).integers(0, 256, (3, 64, 80), dtype=np.uint8)


def test_real_image_facts():
    c = check_file(RGB, expect_epsg=32618, expect_gsd=300.0, gsd_tolerance=0.001)
    assert c.error is None
    assert (c.driver, c.compression, c.lossless, c.layout) == ("GTiff", "NONE", True, "striped")
    assert (c.block_width, c.block_height, c.band_count) == (791, 3, 3)
    assert c.colour_interpretation == ("red", "green", "blue")
    assert c.crs_ok is True and c.epsg == 32618 and c.gsd_ok is True
    assert c.pixel_size_unit == "metre"
    assert c.nodata == (0.0, 0.0, 0.0) and c.nodata_declared
    assert c.bit_depth_ok is True and c.bit_depth_recommended is False
    assert c.stored_statistics is True


@pytest.mark.parametrize(("opts", "name", "lossless"), [
    ({"compress": "deflate"}, "DEFLATE", True),
    ({"compress": "lzw"}, "LZW", True),
    ({"compress": "zstd"}, "ZSTD", True),
    ({}, "NONE", True),
    ({"compress": "jpeg"}, "JPEG", False),
    ({"compress": "webp"}, "WEBP", False),
    ({"compress": "webp", "webp_lossless": True}, "WEBP", True),
])
def test_compression_lossless_or_lossy_from_tags(tmp_path, img8, opts, name, lossless):
    c = check_file(write(tmp_path / "x.tif", img8, **opts))
    assert (c.compression, c.lossless) == (name, lossless)


@pytest.mark.parametrize(("quality", "lossless"), [(100, True), (20, False)])
def test_jpeg2000_reversibility(tmp_path, img8, quality, lossless):
    f = write(tmp_path / "x.jp2", img8, driver="JP2OpenJPEG", quality=quality,
              reversible="YES" if lossless else "NO")
    c = check_file(f)
    assert (c.driver, c.compression, c.lossless) == ("JP2OpenJPEG", "JPEG2000", lossless)


def test_tiled_and_nbits(tmp_path):
    a = np.zeros((1, 100, 100), np.uint16)
    c = check_file(write(tmp_path / "t.tif", a, tiled=True, blockxsize=32, blockysize=32,
                         nbits=12))
    assert (c.layout, c.block_width, c.block_height) == ("tiled", 32, 32)
    assert (c.bit_depth_container, c.nbits, c.bit_depth_recommended) == (16, 12, True)


def test_crs_and_gsd_mismatch(tmp_path, img8):
    c = check_file(write(tmp_path / "x.tif", img8), expect_epsg=25833, expect_gsd=0.2)
    assert c.crs_ok is False and c.gsd_ok is False
    c2 = check_file(tmp_path / "x.tif", expect_epsg=25832, expect_gsd=0.25)
    assert c2.crs_ok is True and c2.gsd_ok is True and c2.rotated is False


@pytest.mark.parametrize(("name", "ok", "problem"), [
    ("photo_nr.tif", True, None),
    ("photo nr.tif", False, "spaces"),
    ("photo", False, "extension"),
    ("ph:oto.tif", False, "Windows"),
    ("CON.tif", False, "reserved"),
    ("a.tif.", False, "dot"),
])
def test_windows_naming(name, ok, problem):
    r = check_name(name)
    assert r.ok is ok
    if problem:
        assert any(problem in p for p in r.problems)


def test_listing_consistency_both_directions():
    r = listing_consistency(["a.tif", "b.tif", "b.tif", "C.tif", "d.tif"],
                            ["a.tif", "b.tif", "c.tif", "e.tif"])
    assert r.listed_missing == ("d.tif",)
    assert r.unlisted == ("e.tif",)
    assert r.duplicates == ("b.tif",)
    assert r.case_mismatch == (("C.tif", "c.tif"),)
    assert not r.ok
    assert listing_consistency(["x/a.tif"], ["x\\a.tif"]).ok


def test_bad_files_give_an_error_not_an_exception(tmp_path, img8):
    empty = tmp_path / "empty.tif"
    empty.write_bytes(b"")
    text = tmp_path / "notes.tif"
    text.write_text("not an image")
    good = write(tmp_path / "good.tif", img8)
    trunc = tmp_path / "trunc.tif"
    trunc.write_bytes(good.read_bytes()[:100])
    nogeo = tmp_path / "nogeo.tif"
    with pytest.warns(rasterio.errors.NotGeoreferencedWarning), rasterio.open(
            nogeo, "w", driver="GTiff", width=8, height=8, count=1, dtype="uint8") as ds:
        ds.write(np.zeros((1, 8, 8), np.uint8))
    cases = {empty: "zero-size", text: "not a readable raster", trunc: "not a readable raster",
             nogeo: "no georeference", tmp_path / "missing.tif": "cannot stat"}
    for path, msg in cases.items():
        c = check_file(path)
        assert c.error is not None and msg in c.error and str(path) in c.error


def test_unsupported_format_is_reported(tmp_path):
    f = tmp_path / "x.bmp"
    f.write_bytes(b"BM" + b"\x00" * 10)
    assert "not a readable raster" in check_file(f).error


def test_vector_files_present_and_readable(tmp_path):
    import pyogrio
    import shapely
    from shapely.geometry import box

    from orthospec.raster.filechecks import check_vector

    f = tmp_path / "tiles.gpkg"
    geoms = np.array(shapely.to_wkb([box(0, 0, 1, 1), box(1, 0, 2, 1)]), dtype=object)
    pyogrio.raw.write(str(f), geometry=geoms, field_data=[np.array(["T1", "T2"])],
                      fields=["tile"], geometry_type="Polygon", crs="EPSG:25832", driver="GPKG")
    v = check_vector(f, expect_epsg=25832)
    assert v.error is None and v.features == 2 and v.geometry_type == "Polygon"
    assert v.crs_ok is True and v.fields == ("tile",)
    assert check_vector(f, expect_epsg=4326).crs_ok is False
    assert "file not found" in check_vector(tmp_path / "seams.shp").error
    junk = tmp_path / "junk.gpkg"
    junk.write_text("nope")
    assert "not a readable vector file" in check_vector(junk).error


def test_hostile_headers_are_errors_without_facts(tmp_path):
    """Issue 17: a VRT named .tif and a 70-band image are refused before GDAL reads them further;
    no driver is reported, so the scan (parallel.scan_image) measures nothing."""
    import os

    from orthospec.provenance import sha256_file

    vrt = tmp_path / "v.tif"
    vrt.write_text('<VRTDataset rasterXSize="2" rasterYSize="2"></VRTDataset>')
    c = check_file(vrt)
    assert "not a GeoTIFF or JPEG 2000 file (XML: a GDAL VRT?)" in c.error and c.driver is None
    bands = write(tmp_path / "b.tif", np.ones((70, 2, 2), np.uint8))
    c = check_file(bands)
    assert "declares 70 bands, more than the limit of 64" in c.error and c.driver is None
    pipe = tmp_path / "p.tif"
    os.mkfifo(pipe)
    assert "not a regular file" in check_file(pipe).error
    with pytest.raises(OSError, match="not a regular file"):
        sha256_file(pipe)
