"""One ROI reader (raster/roi.py) for `measure edge`, the edge provider, mosaic and sample (issue 15 item 2).

The reader is checked against what was written with rasterio (window, dtype, nodata and mask,
pixel size) and against GDAL's bounds; then `orthospec measure edge` and `check` must report the
same RER and FWHM for one real edge chip read through it (the same ROI, nodata and GSD).
"""

from __future__ import annotations

import json
import shutil
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml
from click.testing import CliRunner
from rasterio.errors import NotGeoreferencedWarning
from rasterio.transform import from_origin

from orthospec.api import check
from orthospec.cli.main import cli
from orthospec.errors import MeasureError
from orthospec.qcr import all_records
from orthospec.raster.roi import MapWindow, PixelWindow, raster_bounds, read_roi

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
BAOTOU = REAL / "baotou_CALVAL_L0R_000000_20200328T032332_202003T032334_MTF_12196_7333.tif"
RGB = REAL / "RGB.byte.tif"
BAOTOU_ROI = [
    40,
    12,
    85,
    42,
]  # the near-vertical dark/bright edge with some zero fill (test_edge_real.py)


def _real(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"real test image {path.name} not found in {REAL} (shared data absent)")
    return path


def _write(
    path: Path,
    arr: np.ndarray,
    *,
    crs: str | None = "EPSG:25832",
    size: float = 0.2,
    nodata: float | None = None,
    mask: np.ndarray | None = None,
    transform=None,
) -> Path:
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=arr.shape[1],
        height=arr.shape[0],
        count=1,
        dtype=arr.dtype,
        crs=crs,
        nodata=nodata,
        transform=transform or from_origin(500000.0, 5600000.0, size, size),
    ) as ds:
        ds.write(arr, 1)
        if mask is not None:
            ds.write_mask(mask.astype(np.uint8) * 255)
    return path


def test_pixel_window_keeps_dtype_and_declared_nodata(tmp_path):
    arr = np.arange(40 * 30, dtype=np.uint16).reshape(40, 30)
    arr[5, 7] = 9
    path = _write(tmp_path / "a.tif", arr, nodata=9)
    got = read_roi(path, window=PixelWindow(4, 2, 20, 12), name="images/a.tif")
    assert got.window == (4, 2, 20, 12) and got.data.dtype == np.uint16
    assert np.array_equal(got.values, arr[2:12, 4:20])
    assert got.nodata == 9.0 and got.masked
    assert np.array_equal(np.ma.getmaskarray(got.data), arr[2:12, 4:20] == 9)
    assert np.isnan(got.filled()[3, 3]) and got.gsd_m == pytest.approx(0.2)
    # an explicit nodata replaces the declared one
    other = read_roi(path, window=PixelWindow(4, 2, 20, 12), nodata=float(arr[2, 4]))
    assert np.ma.getmaskarray(other.data).sum() == 1 and bool(np.ma.getmaskarray(other.data)[0, 0])


def test_dataset_mask_marks_invalid_pixels(tmp_path):
    arr = np.full((20, 20), 100, dtype=np.uint8)
    valid = np.ones((20, 20), dtype=bool)
    valid[:, :3] = False
    path = _write(tmp_path / "m.tif", arr, mask=valid)
    got = read_roi(path)
    assert got.nodata is None and np.array_equal(np.ma.getmaskarray(got.data), ~valid)


@pytest.mark.parametrize(
    "crs,transform,want",
    [
        ("EPSG:25832", from_origin(500000.0, 5600000.0, 0.25, 0.25), 0.25),
        # NAD83 / New York Long Island (ftUS): 1 US survey foot = 1200/3937 m
        ("EPSG:2263", from_origin(1000000.0, 200000.0, 1.0, 1.0), 1200 / 3937),
        ("EPSG:4326", from_origin(10.0, 50.0, 1e-5, 1e-5), None),  # degrees are not a length
        ("EPSG:25832", from_origin(500000.0, 5600000.0, 0.25, 0.5), None),  # not square
        (None, None, None),
    ],
)
def test_gsd_from_the_transform(tmp_path, crs, transform, want):
    path = tmp_path / "g.tif"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        _write(path, np.zeros((10, 10), dtype=np.uint8), crs=crs, transform=transform)
        got = read_roi(path)
    if want is None:
        assert got.gsd_m is None and got.gsd_note
    else:
        assert got.gsd_m == pytest.approx(want, rel=1e-9)


def test_map_window_reads_the_pixels_it_touches(tmp_path):
    arr = np.arange(50 * 60, dtype=np.int16).reshape(50, 60)
    path = _write(tmp_path / "w.tif", arr, size=0.5)
    # x 500002.0..500005.2 -> columns 4..10.4 -> 4..11; y 5599995.1..5599998.0 -> rows 4..9.8 -> 4..10
    got = read_roi(path, window=MapWindow(500002.0, 5599995.1, 500005.2, 5599998.0))
    assert got.window == (4, 4, 11, 10)
    assert np.array_equal(got.values, arr[4:10, 4:11])
    with pytest.raises(MeasureError, match="does not overlap"):
        read_roi(path, window=MapWindow(0.0, 0.0, 1.0, 1.0))


@pytest.mark.parametrize(
    "kw,message",
    [
        ({"band": 2}, "band 2 does not exist"),
        ({"window": PixelWindow(0, 0, 11, 5)}, "exceeds the image"),
        ({"max_pixels": 50, "too_large": "give the target an roi"}, "give the target an roi"),
    ],
)
def test_bad_window_band_or_size_names_the_file(tmp_path, kw, message):
    path = _write(tmp_path / "s.tif", np.zeros((10, 10), dtype=np.uint8))
    with pytest.raises(MeasureError, match=message) as exc:
        read_roi(path, name="images/s.tif", **kw)
    assert str(exc.value).startswith("images/s.tif: ")


def test_truncated_real_geotiff_is_an_error_naming_the_file(tmp_path):
    data = _real(RGB).read_bytes()
    bad = tmp_path / "cut.tif"
    bad.write_bytes(data[: len(data) // 2])
    for fn in (
        lambda: read_roi(bad, name="images/cut.tif"),
        lambda: raster_bounds(bad, name="images/cut.tif"),
    ):
        with pytest.raises(MeasureError, match=r"^images/cut\.tif: not a readable raster"):
            fn()


def test_raster_bounds_are_gdals(tmp_path):
    with rasterio.open(_real(RGB)) as ds:
        want = tuple(ds.bounds)
    assert raster_bounds(RGB, name="RGB.byte.tif") == pytest.approx(want)


# --- `measure edge` and `check` read one ROI the same way ---------------------------------------

PROFILE = textwrap.dedent("""\
    orthospec_profile: 1
    id: edge-roi-test
    version: 1.0.0
    title: Edge ROI test
    source: {title: CEOS WGCV IVOS edge target}
    rules:
      - id: E-RER
        title: Relative edge response recorded
        clause: {document: CEOS WGCV IVOS, section: "9"}
        quote: "RER"
        scope: edge
        measure: edge.rer
        requirement: {op: ">=", value: 0, unit: "1"}
        consequence: warn
      - id: E-FWHM
        title: FWHM recorded
        clause: {document: CEOS WGCV IVOS, section: "11"}
        quote: "FWHM"
        scope: edge
        measure: edge.fwhm
        requirement: {op: ">=", value: 0, unit: "px"}
        consequence: warn
    """)


def test_measure_edge_and_check_agree_on_a_real_chip(tmp_path):
    """The Baotou chip (uint16, zero fill around the rotated target) written as a GeoTIFF with
    0 declared as nodata and 0.5 m pixels: the CLI and the edge provider read the same window
    through raster/roi.py, so both see the same nodata mask, dtype and GSD (0.5 m from the
    transform in both) and report identical RER and FWHM."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(_real(BAOTOU)) as src:
            chip = src.read(1)
    root = tmp_path / "delivery"
    (root / "images").mkdir(parents=True)
    (root / "tables").mkdir()
    tif = _write(root / "images" / "baotou.tif", chip, nodata=0, size=0.5)
    (root / "tables" / "images.csv").write_text(
        "image_id,file,block\nBT,images/baotou.tif,B1\n", encoding="utf-8"
    )
    manifest = {
        "orthospec_delivery": 1,
        "id": "D-ROI-1",
        "project": {"id": "P1", "name": "Edge ROI", "crs": "EPSG:25832"},
        "contractor": {"name": "ACME Mapping"},
        "sensor": {"type": "satellite", "digital": True},
        "product": {"gsd": {"value": 9.0, "unit": "m"}},  # not used: the transform gives 0.5 m
        "blocks": [{"id": "B1"}],
        "tables": {"images": "tables/images.csv"},
        "edge_targets": [{"id": "E1", "image": "BT", "roi": BAOTOU_ROI, "band": 1}],
    }
    (root / "delivery.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")
    (tmp_path / "profile.yaml").write_text(PROFILE, encoding="utf-8")

    res = CliRunner().invoke(
        cli(), ["measure", "edge", str(tif), "--roi", ",".join(map(str, BAOTOU_ROI)), "--json"]
    )
    assert res.exit_code == 0, res.output
    cli_doc = json.loads(res.output)
    assert cli_doc["valid"] and cli_doc["gsd_m"] == 0.5
    assert cli_doc["fwhm_m"] == pytest.approx(cli_doc["fwhm_px"] * 0.5)

    doc = check(root, str(tmp_path / "profile.yaml"), date="2026-06-30").document
    rec = {r["rule"]: r for r in all_records(doc) if r["item"] == "E1"}
    assert rec["E-RER"]["measured"]["value"] == pytest.approx(cli_doc["rer"], rel=1e-9)
    assert rec["E-FWHM"]["measured"]["value"] == pytest.approx(cli_doc["fwhm_px"], rel=1e-9)
    detail = doc["details"]["edges"]["E1"]
    assert detail["gsd_m"] == 0.5 and detail["primary_fit"] == cli_doc["primary_fit"]
    # the declared nodata matters: without it the zero fill in the window fails the health checks
    shutil.copy(tif, tmp_path / "plain.tif")
    with rasterio.open(tmp_path / "plain.tif", "r+") as ds:
        ds.nodata = None
    plain = json.loads(
        CliRunner()
        .invoke(
            cli(),
            [
                "measure",
                "edge",
                str(tmp_path / "plain.tif"),
                "--roi",
                ",".join(map(str, BAOTOU_ROI)),
                "--json",
            ],
        )
        .output
    )
    assert plain["valid"] is False and plain["rer"] is None
