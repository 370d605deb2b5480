"""raster.facts.read_facts: the one reading of an image's header facts (issue 25).

Every value is checked against what the test wrote with rasterio and against GDAL's own
``gdalinfo -json`` of the same file (an independent reader: the system's GDAL binary).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

from orthospec.raster.facts import RasterFacts, read_facts
from orthospec.raster.filechecks import check_file

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
GDALINFO = shutil.which("gdalinfo")


def _write(path: Path, data: np.ndarray, **profile: object) -> Path:
    prof: dict[str, object] = dict(
        driver="GTiff",
        width=data.shape[2],
        height=data.shape[1],
        count=data.shape[0],
        dtype=data.dtype,
        crs="EPSG:25832",
        transform=Affine(0.25, 0, 500_000.0, 0, -0.25, 5_400_000.0),
    )
    prof.update(profile)
    with rasterio.open(path, "w", **prof) as ds:
        ds.write(data)
    return path


def _gdalinfo(path: Path) -> dict:
    if GDALINFO is None:
        pytest.skip("gdalinfo (gdal-bin) is not installed")
    out = subprocess.run(
        [GDALINFO, "-json", "-nomd", "-norat", "-noct", str(path)],
        check=True,
        capture_output=True,
        text=True,
        env={**os.environ, "GDAL_PAM_ENABLED": "NO"},
    )
    return json.loads(out.stdout)


def _gdalinfo_md(path: Path) -> dict:
    if GDALINFO is None:
        pytest.skip("gdalinfo (gdal-bin) is not installed")
    out = subprocess.run(
        [GDALINFO, "-json", str(path)],
        check=True,
        capture_output=True,
        text=True,
        env={**os.environ, "GDAL_PAM_ENABLED": "NO"},
    )
    return json.loads(out.stdout)


@pytest.fixture
def tiled16(tmp_path: Path) -> Path:
    """4 bands of 12-bit data in uint16, tiled 256, deflate, nodata 0, NBITS=12, stored statistics and
    two overview levels."""
    data = np.random.default_rng(1).integers(1, 4096, (4, 600, 700), dtype=np.uint16)
    p = _write(
        tmp_path / "tiled.tif",
        data,
        tiled=True,
        blockxsize=256,
        blockysize=256,
        compress="deflate",
        nodata=0,
        nbits=12,
        photometric="RGB",
        alpha="unspecified",
    )
    with rasterio.open(p, "r+") as ds:
        ds.update_tags(
            1,
            STATISTICS_MINIMUM="1",
            STATISTICS_MAXIMUM="4095",
            STATISTICS_MEAN="2048.5",
            STATISTICS_STDDEV="1182.2",
        )
        ds.build_overviews([2, 4])
    return p


def test_header_facts_equal_what_was_written_and_gdalinfo(tiled16: Path) -> None:
    f = read_facts(tiled16)
    info = _gdalinfo(tiled16)
    assert f.error is None and f.georeference is None and f.georeferenced
    # as written
    assert (f.driver, f.width, f.height, f.count) == ("GTiff", 700, 600, 4)
    assert f.dtypes == ("uint16",) * 4
    assert (f.bit_depth, f.nbits, f.bit_depth_container) == (12, 12, 16)
    assert f.nodata == (0.0,) * 4
    assert f.transform == (0.25, 0.0, 500_000.0, 0.0, -0.25, 5_400_000.0)
    assert f.pixel_size == (0.25, 0.25) and f.pixel_size_m == (0.25, 0.25)
    assert f.bounds == (500_000.0, 5_400_000.0 - 150.0, 500_000.0 + 175.0, 5_400_000.0)
    assert (
        f.epsg == 25832
        and f.crs_name == "EPSG:25832"
        and f.pixel_unit == "metre"
        and f.unit_metres == 1.0
    )
    assert (f.compression, f.lossless, f.tiled, f.layout, f.block_shape) == (
        "DEFLATE",
        True,
        True,
        "tiled",
        (256, 256),
    )
    assert f.overviews == (2, 4)
    assert f.stats[0] == {"min": 1.0, "max": 4095.0, "mean": 2048.5, "std": 1182.2}
    assert f.stats[1:] == (None, None, None)
    assert f.rotated is False
    # as GDAL's own gdalinfo reads the same file
    assert [f.width, f.height] == info["size"]
    assert list(f.transform[i] for i in (2, 0, 1, 5, 3, 4)) == info["geoTransform"]
    assert [b["type"] for b in info["bands"]] == ["UInt16"] * 4
    assert [b["noDataValue"] for b in info["bands"]] == list(f.nodata)
    assert [b["colorInterpretation"].lower() for b in info["bands"]] == list(f.colorinterp)
    assert [b["block"] for b in info["bands"]] == [[256, 256]] * 4
    assert [len(b.get("overviews", [])) for b in info["bands"]] == [2] * 4
    corners = info["cornerCoordinates"]
    assert (
        corners["lowerLeft"][0],
        corners["lowerLeft"][1],
        corners["upperRight"][0],
        corners["upperRight"][1],
    ) == f.bounds
    assert f.sha256 == hashlib.sha256(tiled16.read_bytes()).hexdigest()
    md = _gdalinfo_md(tiled16)
    assert md["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"] == f.compression
    assert md["bands"][0]["metadata"][""]["STATISTICS_MEAN"] == "2048.5"
    assert md["bands"][0]["metadata"]["IMAGE_STRUCTURE"]["NBITS"] == "12"


def test_real_landsat_facts_against_gdalinfo() -> None:
    path = REAL / "RGB.byte.tif"
    if not path.is_file():
        pytest.skip("../shared/data/real is not beside the checkout")
    f = read_facts(path, sha256=False)
    info = _gdalinfo(path)
    assert f.sha256 is None
    assert [f.width, f.height, f.count] == [*info["size"], len(info["bands"])]
    assert list(f.transform[i] for i in (2, 0, 1, 5, 3, 4)) == pytest.approx(
        info["geoTransform"], abs=0
    )
    assert f.epsg == 32618 and f.layout == "striped" and not f.tiled and f.bit_depth == 8
    assert f.colorinterp == ("red", "green", "blue")
    corners = info["cornerCoordinates"]
    assert f.bounds == pytest.approx(
        (
            corners["lowerLeft"][0],
            corners["lowerLeft"][1],
            corners["upperRight"][0],
            corners["upperRight"][1],
        ),
        abs=1e-6,
    )


def test_rotated_transform_pixel_size_and_envelope(tmp_path: Path) -> None:
    """Pixel size from the rotated transform (hypot of its columns), bounds the envelope (as GDAL)."""
    t = Affine.translation(500_000, 5_400_000) * Affine.rotation(30) * Affine.scale(0.5, -0.5)
    p = _write(tmp_path / "rot.tif", np.ones((1, 40, 60), np.uint8), transform=t)
    f = read_facts(p, sha256=False)
    assert f.rotated is True
    assert f.pixel_size == pytest.approx((0.5, 0.5))
    with rasterio.open(p) as ds:
        assert f.bounds == tuple(ds.bounds)


def test_geographic_crs_has_no_metre_pixel(tmp_path: Path) -> None:
    p = _write(
        tmp_path / "geo.tif",
        np.ones((1, 10, 10), np.uint8),
        crs="EPSG:4326",
        transform=Affine(0.0001, 0, 9.0, 0, -0.0001, 48.0),
    )
    f = read_facts(p, sha256=False)
    assert f.epsg == 4326 and f.pixel_unit == "degree"
    assert f.pixel_size == pytest.approx((0.0001, 0.0001)) and f.pixel_size_m is None


def test_float_samples_have_no_bit_depth(tmp_path: Path) -> None:
    p = _write(tmp_path / "f.tif", np.zeros((1, 8, 8), np.float32))
    f = read_facts(p, sha256=False)
    assert f.dtypes == ("float32",) and f.bit_depth is None and f.bit_depth_container is None


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
@pytest.mark.parametrize("kind", ["no-crs", "identity"])
def test_not_georeferenced_keeps_the_other_facts(tmp_path: Path, kind: str) -> None:
    p = tmp_path / "plain.tif"
    with rasterio.open(
        p,
        "w",
        driver="GTiff",
        width=16,
        height=8,
        count=1,
        dtype="uint8",
        **({"crs": "EPSG:25832"} if kind == "identity" else {}),
    ) as ds:
        ds.write(np.ones((1, 8, 16), np.uint8))
    f = read_facts(p)
    assert f.error is None and not f.georeferenced
    assert f.georeference == (
        "no georeference (no CRS)"
        if kind == "no-crs"
        else "no georeference (identity geotransform)"
    )
    assert (f.width, f.height, f.bit_depth) == (16, 8, 8)
    assert f.transform is None and f.bounds is None and f.pixel_size is None
    assert f.sha256 == hashlib.sha256(p.read_bytes()).hexdigest()


@pytest.mark.parametrize(
    ("make", "says"),
    [
        (lambda p: None, "cannot stat file"),
        (lambda p: p.write_bytes(b""), "zero-size file"),
        (lambda p: p.write_bytes(b"<VRTDataset rasterXSize='1'/>"), "not a GeoTIFF or JPEG 2000"),
        (lambda p: p.write_bytes(b"II*\x00" + b"\x00" * 40), "not a readable raster"),
        (lambda p: os.mkfifo(p), "not a regular file"),
    ],
)
def test_bad_files_are_an_error_never_an_exception(tmp_path: Path, make, says: str) -> None:
    p = tmp_path / "bad.tif"
    make(p)
    f = read_facts(p)
    assert f.error is not None and says in f.error, f.error
    assert not f.readable and not f.georeferenced and f.transform is None
    # the bytes of a regular, non-empty file are still hashed (the evidence names what was delivered)
    regular = p.is_file() and p.stat().st_size > 0
    assert (f.sha256 == hashlib.sha256(p.read_bytes()).hexdigest()) if regular else f.sha256 is None


def test_to_dict_is_json_and_round_trips(tiled16: Path) -> None:
    f = read_facts(tiled16)
    d = f.to_dict()
    text = json.dumps(d)
    assert json.loads(text)["block_shape"] == [256, 256]
    assert RasterFacts.from_dict(json.loads(text)) == f


def test_file_checks_are_judged_on_the_same_facts(tiled16: Path) -> None:
    """One reader: FileChecks keeps the RasterFacts it was judged on, and agrees with them."""
    c = check_file(tiled16, expect_epsg=25832, expect_gsd=0.25)
    f = read_facts(tiled16, sha256=False)
    assert c.facts == f
    assert (c.width, c.height, c.band_count, c.dtypes, c.nbits) == (
        f.width,
        f.height,
        f.count,
        f.dtypes,
        f.nbits,
    )
    assert (c.block_height, c.block_width) == f.block_shape and c.layout == f.layout
    assert (c.pixel_size_x, c.pixel_size_y) == f.pixel_size and c.epsg == f.epsg
    assert c.crs_ok is True and c.gsd_ok is True and c.has_overviews and c.stored_statistics
    assert "facts" not in c.to_dict()
