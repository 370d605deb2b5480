"""The ``derived.*`` facts split by subject (issue 28 item 2): the same measures registered from their new
modules, their arithmetic in measures/ checked against hand-computed values, and the photo lay-down
handing its left-out images to ``derived.photo_coverage`` as a typed result, not through ctx.memo."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import box
from tests.conftest import EXAMPLES

from orthospec.engine.catalog import known_measures
from orthospec.measures.laydown import (
    GSD_TOLERANCE,
    ground_scale,
    inflated,
    placeable,
    published_format,
    same_station_distance,
)
from orthospec.measures.outlines import OUTLINE_TOLERANCE, disagreement
from orthospec.measures.pansharpening import PAN_MARGIN, image_pansharpened

#: measure -> (scope, unit, module) as registered before the split (specs/schema/measures.json of
#: main 2f0c4e6), with the module of engine/providers/ that registers it now
REGISTERED = {
    "derived.area_of_interest_agrees": ("delivery", "bool", "outlines"),
    "derived.block_outlines_agree": ("delivery", "bool", "outlines"),
    "derived.camera_agrees": ("camera", "bool", "camera"),
    "derived.dem_blocks": ("dem", "text", "dem"),
    "derived.dem_delivered": ("delivery", "bool", "dem"),
    "derived.dem_delivered_agrees": ("delivery", "bool", "dem"),
    "derived.dem_used": ("delivery", "bool", "dem"),
    "derived.is_master": ("image", "bool", "masters"),
    "derived.master_images": ("delivery", "1", "masters"),
    "derived.master_images_agree": ("delivery", "bool", "masters"),
    "derived.orthorectification": ("delivery", "text", "orthorectification"),
    "derived.pansharpened": ("delivery", "bool", "pansharpening"),
    "derived.pansharpened_agrees": ("delivery", "bool", "pansharpening"),
    "derived.photo_coverage": ("delivery", "%", "coverage"),
    "derived.project_crs_agrees": ("delivery", "bool", "project_crs"),
    "derived.resolution_class": ("image", "text", "pixel"),
    "derived.resolution_class_agrees": ("image", "bool", "pixel"),
}


def test_the_same_derived_measures_are_registered_by_subject() -> None:
    got = {
        n: (s.scope, s.measures[n], s.fn.__module__.rsplit(".", 1)[1])
        for n, s in known_measures().items()
        if n.startswith("derived.")
    }
    assert got == REGISTERED


def test_the_former_module_still_exports_the_former_names() -> None:
    from orthospec.engine.providers import coverage, dem, derived, outlines, pixel

    assert derived.photo_coverage is coverage.photo_coverage
    assert derived.dem_blocks is dem.dem_blocks
    assert derived.block_outlines_agree is outlines.block_outlines_agree
    assert derived.measured_pixel_m is pixel.measured_pixel_m
    assert derived.OUTLINE_TOLERANCE == 0.01
    assert (derived.GSD_TOLERANCE, derived.PAN_MARGIN) == (1.2, 1.5)


# ---------------------------------------------------------------- measures/laydown.py (JRC §5.2.1-5.2.2)


def test_ground_scale_is_height_over_focal_length_times_pixel() -> None:
    # 2,000 m above ground, f = 100 mm, 5 µm pixels: 2000 x 5e-6 / 0.1 = 0.1 m; 1,000 m with an
    # UltraCam Eagle (f 100.5 mm, 5.2 µm): 1000 x 5.2e-6 / 0.1005 = 0.0517413 m
    got = ground_scale(np.array([2000.0, 1000.0]), np.array([5.0, 5.2]), np.array([100.0, 100.5]))
    assert got == pytest.approx([0.1, 0.0517413], rel=1e-6)


@pytest.mark.parametrize(
    ("across", "along", "expected"),
    [
        (17310.0, 11310.0, (17310, 11310)),  # declared wide: the long side across track
        (100.0, 50.0, (17310, 11310)),  # a wrong declared format takes the published one
        (11310.0, 17310.0, (11310, 17310)),  # declared with the long side along track: kept so
        (math.nan, math.nan, (17310, 11310)),  # nothing declared: wide
    ],
)
def test_published_format_keeps_the_declared_orientation(
    across: float, along: float, expected: tuple[int, int]
) -> None:
    assert published_format(across, along, (11310, 17310)) == expected


def test_placeable_needs_a_finite_station_and_a_positive_footprint() -> None:
    x = np.array([0.0, math.nan, 0.0, 0.0])
    y = np.zeros(4)
    across = np.array([1.0, 1.0, 0.0, 1.0])
    along = np.array([1.0, 1.0, 1.0, math.inf])
    assert placeable(x, y, across, along).tolist() == [True, False, False, False]


def test_inflated_is_strictly_coarser_than_the_tolerance_times_the_reference() -> None:
    assert GSD_TOLERANCE == 1.2
    scale = np.array([0.30, 0.31, 0.31, 0.31, 0.20])
    ref = np.array([0.25, 0.25, math.nan, 0.25, 0.25])
    placed = np.array([True, True, True, False, True])
    # 1.2 x 0.25 = 0.30: equal is not coarser; unknown reference or unplaced photo: not judged
    assert inflated(scale, ref, placed).tolist() == [False, True, False, False, False]


def test_same_station_distance_is_five_percent_of_the_median_shorter_side() -> None:
    # shorter sides 80, 200, 150 -> median 150 -> 7.5
    got = same_station_distance(np.array([100.0, 200.0, 150.0]), np.array([80.0, 300.0, 400.0]))
    assert got == pytest.approx(7.5)


# ---------------------------------------------------------------- measures/outlines.py (red team R13/R17)


def test_an_outline_shifted_within_one_percent_agrees() -> None:
    assert OUTLINE_TOLERANCE == 0.01
    in_force = box(0, 0, 1000, 1000)  # 1 km²: at most 10,000 m² apart and 10 m away
    assert disagreement(box(0, 0, 1000, 1000), in_force) is None
    # shifted 5 m: symmetric difference 2 x 5 x 1000 = 10,000 m² (1 %), Hausdorff 5 m
    assert disagreement(box(5, 0, 1005, 1000), in_force) is None


def test_an_outline_shifted_by_twenty_metres_disagrees() -> None:
    # symmetric difference 2 x 20 x 1000 = 40,000 m² = 4 % of the area, Hausdorff 20 m > 10 m
    why = disagreement(box(20, 0, 1020, 1000), box(0, 0, 1000, 1000))
    assert why is not None
    assert "differs by 4 % of the area in force" in why
    assert "up to 20 map units" in why


# ---------------------------------------------------------------- measures/pansharpening.py (JRC §10.5)


@pytest.mark.parametrize(
    ("bands", "gsd", "ms", "declared", "expected"),
    [
        (4, 0.5, 2.0, None, True),  # 0.5 m <= 2.0 / 1.5 = 1.33 m: fused with PAN
        (4, 0.31, 1.24, False, True),  # WorldView-3 fused: the data beat a declared false
        (4, 1.0, 1.24, None, None),  # between 0.83 m and 1.24 m, nothing declared: undecided
        (4, 1.0, 1.24, True, True),  # ... the declaration decides
        (4, 1.24, 1.24, True, False),  # not finer than the MS pixel
        (1, 0.5, 2.0, True, False),  # a single band is not multispectral
        (None, 0.5, 2.0, None, None),  # band count unknown
        (4, 0.5, math.nan, None, None),  # native MS pixel unknown
    ],
)
def test_image_pansharpened(
    bands: int | None, gsd: float, ms: float, declared: bool | None, expected: bool | None
) -> None:
    assert PAN_MARGIN == 1.5
    assert image_pansharpened(bands, gsd, ms, declared)[0] is expected


# ---------------------------------------------------------------- the lay-down's typed result


def test_the_lay_down_names_the_photos_it_left_out_without_ctx_memo() -> None:
    """aerial-fail F04 (examples/deliveries/aerial-fail/README.md): flying height empty for F01_0103,
    F01_0104 and F01_0105; the lay-down says so itself and writes nothing into the run's memo."""
    from orthospec.delivery.reader import open_delivery
    from orthospec.engine.providers.coverage import LayDown, _lay_down, photo_coverage
    from orthospec.engine.registry import ProviderContext

    ctx = ProviderContext(delivery=open_delivery(EXAMPLES / "aerial-fail"), parameters={})
    lay = _lay_down(ctx)
    assert isinstance(lay, LayDown)
    assert lay.why is None
    assert lay.incomplete == ["F01_0103", "F01_0104", "F01_0105"]
    assert lay.inflated == []
    (got,) = photo_coverage(ctx)
    note = str(got.notes.iloc[0])
    assert got.values.iloc[0] is None  # a lower bound below 100 % decides nothing
    assert "F01_0103, F01_0104, F01_0105 lack an exposure station or flying height" in note
    assert not [k for k in ctx.memo if k.startswith("derived.")]


# ---------------------------------------------------------------- derived.dem_blocks reads through raster/facts.py


def _dem_delivery(tmp_path: Path, crs: str | None) -> Path:
    """aerial-pass with a 2 x 2 km DEM (x 508-510 km, y 5404-5406 km: inside block B02) and no
    `block` column, so derived.dem_blocks places it by its file's footprint."""
    import rasterio
    import yaml
    from rasterio.transform import from_origin

    d = tmp_path / "aerial-pass"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    with rasterio.open(
        d / "images" / "dem.tif",
        "w",
        driver="GTiff",
        width=20,
        height=20,
        count=1,
        dtype="float32",
        crs=crs,
        transform=from_origin(508000, 5406000, 100, 100),
    ) as ds:
        ds.write(np.zeros((1, 20, 20), dtype="float32"))
    (d / "tables" / "dem.csv").write_text("dem_id,file\nDEM-1,images/dem.tif\n", encoding="utf-8")
    m = yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))
    m["tables"]["dem"] = "tables/dem.csv"
    (d / "delivery.yaml").write_text(yaml.safe_dump(m, sort_keys=False), encoding="utf-8")
    return d


@pytest.mark.parametrize(
    ("crs", "blocks", "note"),
    [
        ("EPSG:25832", "B02", "footprint of images/dem.tif overlaps block(s) B02"),
        # no CRS: its geotransform alone is no place on the ground, so it serves no block (a failing
        # DEM then returns the delivery, rollup.py) instead of the blocks its numbers happen to hit
        (None, None, "cannot read the footprint of images/dem.tif: no georeference (no CRS)"),
    ],
)
def test_a_dem_is_placed_by_its_georeferenced_footprint(
    tmp_path: Path, crs: str | None, blocks: str | None, note: str
) -> None:
    from orthospec.delivery.reader import open_delivery
    from orthospec.engine.providers.dem import dem_blocks
    from orthospec.engine.registry import ProviderContext

    delivery = open_delivery(_dem_delivery(tmp_path, crs))
    (got,) = dem_blocks(ProviderContext(delivery=delivery, parameters={}))
    assert got.values.to_dict() == {"DEM-1": blocks}
    assert got.notes.to_dict() == {"DEM-1": note}


# ---------------------------------------------------------------- shared work under a typed key


def test_shared_work_is_computed_once_per_run() -> None:
    from orthospec.engine.providers.shared import Shared
    from orthospec.engine.registry import ProviderContext

    calls: list[int] = []

    def compute(ctx: ProviderContext) -> list[int]:
        calls.append(1)
        return [len(calls)]

    work = Shared("test.work", compute)
    run, other = (ProviderContext(delivery=None, parameters={}) for _ in range(2))  # type: ignore[arg-type]
    first = work.get(run)
    assert work.get(run) is first and first == [1]  # the same object, computed once
    assert work.get(other) == [2]  # another run computes its own
    assert len(calls) == 2


def test_satellite_and_seamlines_read_one_footprint_computation() -> None:
    """area_selection.py reads the image footprints through satellite.footprints, not its own key."""
    import inspect

    from orthospec.engine.providers import area_selection, satellite

    assert area_selection.footprints is satellite.footprints
    assert "ctx.memo" not in inspect.getsource(area_selection)
