"""One read of the pixels, one error boundary, and the [dask] extra (issues 14 item 4, 15 items 2 and 6)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

from orthospec.errors import MeasureError, OrthospecError
from orthospec.raster.reading import ScanSettings, gdal_errors, scan_raster


def _write(path: Path, data: np.ndarray, **profile) -> Path:
    prof = dict(
        driver="GTiff",
        width=data.shape[2],
        height=data.shape[1],
        count=data.shape[0],
        dtype=data.dtype,
        crs="EPSG:25832",
        transform=Affine(0.5, 0, 500000, 0, -0.5, 5600000),
    )
    prof.update(profile)
    with rasterio.open(path, "w", **prof) as ds:
        ds.write(data)
    return path


def _textured(rng: np.random.Generator, shape: tuple[int, int, int]) -> np.ndarray:
    from scipy import ndimage

    base = ndimage.gaussian_filter(rng.normal(size=shape[1:]), 3.0)
    base = (base - base.min()) / (base.max() - base.min())
    bands = [base * (150 + 20 * k) + 30 + rng.normal(0, 3, shape[1:]) for k in range(shape[0])]
    return np.clip(np.stack(bands), 1, 255).astype(np.uint8)


def test_the_full_scan_reads_every_pixel_exactly_once(tmp_path, monkeypatch):
    """Statistics, histograms, noise, luminosity and misregistration come from one read: the
    pixels GDAL hands over (counted at rasterio's read) equal the image's, once."""
    data = _textured(np.random.default_rng(3), (3, 700, 900))
    f = _write(
        tmp_path / "rgb.tif", data, photometric="RGB", tiled=True, blockxsize=128, blockysize=128
    )
    read_px = []
    original = rasterio.io.DatasetReader.read

    def counting(self, *args, **kwargs):
        out = original(self, *args, **kwargs)
        read_px.append(out.size)
        return out

    monkeypatch.setattr(rasterio.io.DatasetReader, "read", counting)
    stats = scan_raster(f, ScanSettings(chunk_bytes=200_000))
    assert stats.chunks > 5
    assert sum(read_px) == data.size
    assert stats.misregistration and stats.luminosity is not None
    assert all(b.noise_sigma_immerkaer is not None for b in stats.bands)


def test_misregistration_from_the_streamed_chunks_finds_a_known_shift(tmp_path):
    """The windows are assembled from many small chunks; the 1.5 px shift written is found."""
    from scipy import ndimage

    rng = np.random.default_rng(5)
    base = ndimage.gaussian_filter(rng.normal(size=(600, 600)), 2.0)
    shifted = np.fft.ifft2(ndimage.fourier_shift(np.fft.fft2(base), (1.5, 0.0))).real
    a = np.stack([shifted, base, base])
    a = ((a - a.min()) / (a.max() - a.min()) * 200 + 20).astype(np.uint8)
    f = _write(tmp_path / "mis.tif", a, photometric="RGB", tiled=True, blockxsize=64, blockysize=64)
    stats = scan_raster(f, ScanSettings(chunk_bytes=50_000))  # windows span several chunks
    assert stats.chunks > 20
    assert stats.misregistration[1].dy == pytest.approx(1.5, abs=0.1)
    assert stats.misregistration[1].dx == pytest.approx(0.0, abs=0.1)
    assert stats.misregistration[3].magnitude < 0.1


@pytest.mark.parametrize("nodata", [0, 255])  # the darkest value (fast path) and another one
def test_nodata_in_a_few_chunks_only_is_excluded_everywhere(tmp_path, nodata):
    """Validity masks are built only for chunks that hold the nodata value: statistics and the
    luminosity histogram still equal numpy's over the valid pixels (known truth)."""
    rng = np.random.default_rng(11)
    a = rng.integers(1, 255, (3, 512, 512), dtype=np.uint8)
    a[:, 300:340, 10:50] = nodata  # nodata in every band, one chunk
    a[1, 5, 5] = nodata  # nodata in band 2 only, another chunk
    a[2, 400, 500] = nodata  # and in band 3 only, a third
    f = _write(
        tmp_path / "nd.tif",
        a,
        photometric="RGB",
        nodata=nodata,
        tiled=True,
        blockxsize=64,
        blockysize=64,
    )
    stats = scan_raster(f, ScanSettings(chunk_bytes=40_000))
    assert stats.chunks > 10
    for k, b in enumerate(stats.bands):
        v = a[k][a[k] != nodata].astype(np.float64)
        assert (b.valid, b.min, b.max) == (v.size, v.min(), v.max())
        assert b.mean == pytest.approx(v.mean(), rel=1e-12) and b.std == pytest.approx(
            v.std(), rel=1e-12
        )
    ai = a.astype(np.int64)
    y = (299 * ai[0] + 587 * ai[1] + 114 * ai[2] + 500) // 1000  # Rec. 601, ties round up
    valid = (a != nodata).all(axis=0)
    lum = stats.luminosity
    assert lum is not None and lum.valid == int(valid.sum())
    expected = np.bincount(y[valid], minlength=256)
    assert list(lum.histogram.counts) == expected[lum.histogram.offset : int(lum.max) + 1].tolist()


def test_library_errors_become_measure_errors_naming_the_file(tmp_path):
    import pyproj

    missing = tmp_path / "images" / "a.tif"
    with pytest.raises(MeasureError) as info, gdal_errors(file="images/a.tif", path=missing):
        rasterio.open(missing)
    assert str(info.value).startswith("images/a.tif: not a readable raster")
    assert str(tmp_path) not in str(info.value)
    assert isinstance(info.value.__cause__, rasterio.errors.RasterioError)
    with (
        pytest.raises(MeasureError, match=r"^f\.tif: not a readable CRS") as crs,
        gdal_errors(file="f.tif", what="CRS"),
    ):
        pyproj.CRS.from_user_input("EPSG:999999")
    assert isinstance(crs.value.__cause__, pyproj.exceptions.CRSError)


def test_other_errors_pass_the_boundary_unchanged():
    """Only the libraries' errors are mapped: a bug stays a bug, our own errors stay ours."""
    with pytest.raises(KeyError), gdal_errors(file="x.tif"):
        raise KeyError("bug")
    own = MeasureError("x.tif: refused")
    with pytest.raises(MeasureError) as info, gdal_errors(file="x.tif"):
        raise own
    assert info.value is own


def test_a_corrupt_vector_file_is_a_measure_error(tmp_path):
    import pyogrio
    import shapely

    from orthospec.raster.reading import read_vector

    good = tmp_path / "good.gpkg"
    geoms = np.array([shapely.to_wkb(shapely.box(0, 0, 1, 1))], dtype=object)
    pyogrio.raw.write(
        str(good),
        geometry=geoms,
        field_data=[np.array([1])],
        fields=["seam"],
        geometry_type="Polygon",
        crs="EPSG:25832",
        driver="GPKG",
    )
    bad = tmp_path / "bad.gpkg"
    bad.write_bytes(good.read_bytes()[:1024])  # GeoPackage header, truncated database
    with pytest.raises(MeasureError, match=r"bad\.gpkg: not a readable vector file"):
        read_vector(bad, name="bad.gpkg")


def test_scheduler_without_dask_names_the_extra_to_install(tmp_path):
    """Dask is an optional extra: without it, a scheduler gives an OrthospecError saying what
    to install (run where ``import distributed`` fails, as in an install without the extra)."""
    img = _write(tmp_path / "a.tif", np.ones((1, 64, 64), np.uint8))
    code = (
        "import sys\n"
        "sys.modules['distributed'] = None\n"
        "from orthospec.errors import OrthospecError\n"
        "from orthospec.raster.parallel import scan_images\n"
        "try:\n"
        f"    scan_images([{str(img)!r}], scheduler='tcp://127.0.0.1:1')\n"
        "except OrthospecError as exc:\n"
        "    print('OrthospecError:', exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("OrthospecError:") and "orthospec[dask]" in out.stdout


def test_require_dask_passes_when_dask_is_installed():
    pytest.importorskip("distributed")
    from orthospec.raster.parallel import require_dask

    require_dask()  # no error
    assert issubclass(MeasureError, OrthospecError)


def test_on_report_streams_each_image_once_and_keeps_none(tmp_path):
    """National scale (issue 14 item 3): reports are handed over as they complete, not kept;
    each index arrives once with the same measurements as the kept-list mode."""
    from orthospec.raster.parallel import scan_images

    rng = np.random.default_rng(2)
    paths = [
        _write(tmp_path / f"i{k}.tif", rng.integers(1, 255, (3, 40, 50), dtype=np.uint8))
        for k in range(5)
    ]
    paths.append(tmp_path / "absent.tif")
    kept = scan_images(paths, workers=1)
    got: dict[int, object] = {}

    def take(i: int, rep) -> None:
        assert i not in got
        got[i] = rep

    assert scan_images(paths, workers=1, on_report=take) == []
    assert sorted(got) == list(range(len(paths)))
    for i, rep in got.items():
        assert rep.path == str(paths[i]) and rep.sha256 == kept[i].sha256
        assert rep.radiometry == kept[i].radiometry and rep.error == kept[i].error
    assert got[5].error is not None and "absent.tif" in got[5].error


def test_check_scheduler_without_dask_exits_2_naming_the_extra(tmp_path):
    """`orthospec check --scheduler` in an install without the [dask] extra: exit 2 before any
    work, the message says what to install (no error record per image, no traceback)."""
    delivery = Path(__file__).resolve().parents[1] / "examples" / "deliveries" / "aerial-pass"
    code = (
        "import sys\n"
        "sys.modules['distributed'] = None\n"
        "from orthospec.cli.main import main\n"
        f"main(['check', {str(delivery)!r}, '-p', 'jrc-v3', '--scheduler', 'tcp://127.0.0.1:1',"
        f" '--out', {str(tmp_path / 'out')!r}, '--format', 'json'])\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert out.returncode == 2, out.stderr
    assert "orthospec[dask]" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "out" / "qcr.json").exists()
