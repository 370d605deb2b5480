"""Block outlines and the area of interest in force: the checker's file's when it states them, else
the manifest's (red team R13/R17; delivery/outlines.py, Delivery.block_outlines, derived.py).

Real example deliveries and checker files read by the real loaders; the tolerance cases use shapely
squares whose symmetric difference and Hausdorff distance follow from the arithmetic in each comment.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest
import yaml
from shapely.geometry import box
from tests.checking import DATE, check_with, records, resigned

from orthospec.delivery.checker import load_checker, stated_outlines
from orthospec.delivery.reader import open_delivery
from orthospec.engine.providers.derived import OUTLINE_TOLERANCE, _disagreement

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deliveries" / "aerial-pass"
CHECKER = ROOT / "examples" / "checker" / "aerial-pass"


def test_the_tolerance_is_one_percent_of_area_and_of_size() -> None:
    assert OUTLINE_TOLERANCE == 0.01
    square = box(0, 0, 1000, 1000)  # 1e6 m2; 1 % of the area 1e4 m2, 1 % of sqrt(area) = 10 m
    # shifted 5 m east: symmetric difference 2 x 5 x 1000 = 1e4 m2 (exactly 1 %), Hausdorff 5 m
    assert _disagreement(box(5, 0, 1005, 1000), square) is None
    # shifted 6 m: 1.2e4 m2 = 1.2 % > 1 %
    why = _disagreement(box(6, 0, 1006, 1000), square)
    assert why is not None and "differs by 1.2 %" in why
    # a 2 m wide, 100 m long spike (a snaked corridor): 200 m2 = 0.02 %, but Hausdorff 100 m > 10 m
    spike = square.union(box(1000, 499, 1100, 501))
    why = _disagreement(spike, square)
    assert why is not None and "up to 100 map units" in why and "at most 10)" in why


def test_without_a_checker_the_manifest_outlines_are_in_force() -> None:
    d = open_delivery(EXAMPLE)
    manifest = yaml.safe_load((EXAMPLE / "delivery.yaml").read_text(encoding="utf-8"))
    got = d.block_outlines()
    assert list(got) == ["B01", "B02", "B03"]
    ring, ev = got["B02"]
    assert [list(v) for v in ring] == manifest["blocks"][1]["polygon"]
    assert (ev.file, ev.path, ev.sha256) == (
        "delivery.yaml",
        "blocks[1].polygon",
        d.manifest_sha256,
    )
    load_checker(CHECKER)  # loaded without a delivery: nothing is attached to any delivery
    assert d.block_outlines() == got


def test_a_bound_checker_file_puts_its_outlines_in_force(tmp_path: Path) -> None:
    doc = yaml.safe_load((CHECKER / "checker.yaml").read_text(encoding="utf-8"))
    doc["blocks"][1]["polygon"] = [
        [507500, 5403000],
        [514000, 5403000],
        [514000, 5410200],
        [507500, 5410200],
    ]
    doc["area_of_interest"] = doc["blocks"][1]["polygon"]
    path = tmp_path / "checker.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    d = open_delivery(EXAMPLE)
    chk = load_checker(path, delivery=d)
    stated = stated_outlines(chk)
    assert stated is not None
    ring, ev = d.block_outlines(stated)["B02"]
    assert ring[1] == (514000.0, 5403000.0)  # the checker's, not the manifest's 514500
    assert ev.file == "checker:checker.yaml" and ev.sha256 == chk.sha256
    assert ev.path == f"blocks[1] (line {chk.lines[('blocks', 1)]})"
    aoi, aoi_ev = stated.area_of_interest or ((), None)
    assert (
        len(aoi) == 4 and aoi_ev is not None and aoi_ev.path.startswith("area_of_interest (line ")
    )


def _run(tmp_path: Path, change: Any) -> Any:
    """Check a copy of aerial-pass with the example checker's file (re-signed) changed by ``change``."""
    d = tmp_path / "aerial-pass"
    shutil.copytree(EXAMPLE, d)
    path = resigned(CHECKER, d, tmp_path / "checker.yaml")
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    change(doc)
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return check_with(d, "jrc-v3", checker=path, date=DATE)


def test_a_block_only_one_side_lists_is_a_finding(tmp_path: Path) -> None:
    def swap_b03_for_b04(doc: dict[str, Any]) -> None:
        # the checker knows B01, B02 and a B04 (east of everything); the manifest has B03 instead
        doc["blocks"][2] = {
            "id": "B04",
            "polygon": [[530000, 5400000], [531000, 5400000], [531000, 5401000]],
        }

    result = _run(tmp_path, swap_b03_for_b04)
    assert not result.accepted
    doc = result.document
    rec = {r["rule"] + "/" + r["item"]: r for r in records(doc)}
    agree = rec["JRC-12.4-BLOCK-OUTLINES-AGREE/D-2026-014"]
    assert agree["verdict"] == "fail"
    assert (
        "block B03 (delivery.yaml blocks[2]): the checker file checker.yaml gives no outline"
        in agree["message"]
    )
    assert (
        "block B04: the checker file checker.yaml gives its outline, delivery.yaml lists no such block"
        in agree["message"]
    )
    # B03 has no outline in force: its points are in no block the checker drew - never a pass
    assert rec["JRC-12.4-CHECKPOINTS-IN-BLOCK/B03"]["verdict"] == "missing"


@pytest.mark.parametrize("shift, verdict", [(0.4, "pass"), (300.0, "fail")])
def test_a_declaration_within_the_tolerance_agrees(
    tmp_path: Path, shift: float, verdict: str
) -> None:
    """The checker's B03 moved 0.4 m north (about 0.4 x 7000 x 2 = 5600 m2 of 5.0e7 m2: 0.011 %, Hausdorff
    0.4 m) agrees; 300 m north (about 4.2e6 m2: 8.4 %, 300 m > 71 m) does not."""

    def move_b03(doc: dict[str, Any]) -> None:
        doc["blocks"][2]["polygon"] = [[x, y + shift] for x, y in doc["blocks"][2]["polygon"]]

    result = _run(tmp_path, move_b03)
    assert result.accepted == (verdict == "pass")
    got = {
        r["item"]: r["verdict"]
        for r in records(result.document)
        if r["rule"] == "JRC-12.4-BLOCK-OUTLINES-AGREE"
    }
    assert got == {"D-2026-014": verdict}


def test_a_dem_serves_the_blocks_in_force(tmp_path: Path) -> None:
    """derived.dem_blocks from the DEM file's footprint: B02 declared cut at x = 511,500 m (R13) misses a
    DEM over x 512-514 km; the checker's true B02 (to x = 514,500 m) contains it."""
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin

    from orthospec.engine.providers.derived import dem_blocks
    from orthospec.engine.registry import ProviderContext

    d = tmp_path / "aerial-pass"
    shutil.copytree(EXAMPLE, d)
    with rasterio.open(
        d / "images" / "dem.tif",
        "w",
        driver="GTiff",
        width=20,
        height=20,
        count=1,
        dtype="float32",
        crs="EPSG:25832",
        transform=from_origin(512000, 5406000, 100, 100),
    ) as ds:  # x 512-514 km, y 5404-5406 km
        ds.write(np.zeros((1, 20, 20), dtype="float32"))
    (d / "tables" / "dem.csv").write_text("dem_id,file\nDEM-1,images/dem.tif\n", encoding="utf-8")
    m = yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))
    m["tables"]["dem"] = "tables/dem.csv"
    m["blocks"][1]["polygon"] = [
        [507500.0, 5403000.0],
        [511500.0, 5403000.0],
        [511500.0, 5410200.0],
        [507500.0, 5410200.0],
        [507500.0, 5403000.0],
    ]
    (d / "delivery.yaml").write_text(yaml.safe_dump(m, sort_keys=False), encoding="utf-8")

    def served(checker: Path | None) -> Any:
        delivery = open_delivery(d)
        stated = (
            stated_outlines(load_checker(checker, delivery=delivery))
            if checker is not None
            else None
        )
        (got,) = dem_blocks(ProviderContext(delivery=delivery, parameters={}, outlines=stated))
        return got.values["DEM-1"]

    assert served(None) is None  # the manifest's outlines: the footprint overlaps no block
    assert served(resigned(CHECKER, d, tmp_path / "checker.yaml")) == "B02"


def test_the_mosaic_measures_the_area_in_force(tmp_path: Path) -> None:
    """mosaic.aoi_coverage (JRC §5.2.2) measures the checker's area of interest, as photo coverage does;
    without the checker's file, the union of the manifest's block polygons. Expected shares: the
    images' bounds read with rasterio, unioned and intersected with each area by shapely."""
    import rasterio
    import shapely
    from shapely.geometry import Polygon

    from orthospec.engine.providers.mosaic import mosaic_measures
    from orthospec.engine.registry import ProviderContext

    d = tmp_path / "aerial-pass"
    shutil.copytree(EXAMPLE, d)
    path = resigned(CHECKER, d, tmp_path / "checker.yaml")
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    ring = [[500000, 5400000], [520500, 5400000], [520500, 5418000], [500000, 5418000]]
    doc["area_of_interest"] = ring
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    feet = []
    for tif in sorted((d / "images").glob("*.tif")):
        with rasterio.open(tif) as ds:
            feet.append(box(*ds.bounds))
    covered = shapely.union_all(feet)
    manifest = yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))
    blocks = shapely.union_all([Polygon(b["polygon"]) for b in manifest["blocks"]])

    def coverage(checker: Path | None) -> tuple[float, Any]:
        delivery = open_delivery(d)
        stated = (
            stated_outlines(load_checker(checker, delivery=delivery))
            if checker is not None
            else None
        )
        got = {
            m.name: m
            for m in mosaic_measures(
                ProviderContext(delivery=delivery, parameters={}, outlines=stated)
            )
        }
        m = got["mosaic.aoi_coverage"]
        return m.values[delivery.id], m.evidence[delivery.id]

    share, ev = coverage(path)
    aoi = Polygon(ring)
    assert share == pytest.approx(covered.intersection(aoi).area / aoi.area * 100.0, rel=1e-9)
    assert ev[0].file == "checker:checker.yaml"
    share, ev = coverage(None)
    assert share == pytest.approx(covered.intersection(blocks).area / blocks.area * 100.0, rel=1e-9)
    assert ev[0].file == "delivery.yaml" and ev[0].path == "blocks"
