"""Tile index, seamline and block-outline layers of a source folder (ingest/vectors.py), written
here with pyogrio from known geometries and attributes: each layer matched to the images by its
name attribute or by geometry, and what matched nothing on either side listed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyogrio.raw
import pytest
import shapely

from orthospec.ingest.vectors import read_layer, role_of

CRS = "EPSG:32632"
#: four 100 m tiles in a row, as init --from names them (image id -> footprint)
IMAGES = {f"T{i}": (500000.0 + 100 * i, 5000000.0, 500100.0 + 100 * i, 5000100.0) for i in range(4)}


def _write(path: Path, geoms: list[object], crs: str = CRS, **attrs: list[object]) -> Path:
    fields = {k: np.array(v, dtype=object) for k, v in attrs.items()}
    driver = {".shp": "ESRI Shapefile", ".gpkg": "GPKG", ".geojson": "GeoJSON"}[path.suffix]
    pyogrio.raw.write(
        str(path),
        shapely.to_wkb(np.array(geoms, dtype=object)),
        list(fields.values()),
        list(fields),
        geometry_type="Polygon",
        crs=crs,
        driver=driver,
    )
    return path


@pytest.mark.parametrize("suffix", [".shp", ".gpkg", ".geojson"])
def test_a_tile_index_matched_by_its_name_attribute(tmp_path: Path, suffix: str) -> None:
    geoms = [shapely.box(*IMAGES[f"T{i}"]) for i in range(3)] + [shapely.box(0, 0, 1, 1)]
    p = _write(
        tmp_path / f"index{suffix}",
        geoms,
        location=["tiles/T0.tif", "D:\\lot3\\T1.TIF", "t2", "T9.tif"],
        note=["a", "b", "c", "d"],
    )
    lay = read_layer(p, f"source/index{suffix}", images=IMAGES, image_crs=CRS)
    assert lay.error is None and lay.features == 4
    assert lay.role == "tiles" and lay.matched_by == "attribute location"
    assert lay.matched == {"T0": 0, "T1": 1, "T2": 2}
    assert lay.unmatched_features == ["#4 location='T9.tif'"]
    assert lay.images_without_feature == ["T3"]
    assert lay.declarable is (suffix != ".geojson")  # the check reads GeoPackage and shapefile only


def test_without_a_name_attribute_the_geometry_decides(tmp_path: Path) -> None:
    shifted = shapely.box(
        500300.0 + 40, 5000000.0, 500400.0 + 40, 5000100.0
    )  # IoU 60/140: not the same tile
    geoms = [
        shapely.box(*IMAGES["T1"]),
        shapely.box(*IMAGES["T0"]).buffer(-2, join_style="mitre"),
        shifted,
    ]
    p = _write(tmp_path / "kacheln.shp", geoms, nr=[7, 8, 9])
    lay = read_layer(p, "source/kacheln.shp", images=IMAGES, image_crs=CRS)
    assert lay.matched_by == "geometry" and lay.role == "tiles"
    assert lay.matched == {"T1": 0, "T0": 1}  # 96 x 96 inside 100 x 100: IoU 0.92 >= 0.9
    assert lay.unmatched_features == ["#3 (no tile with the same footprint)"]
    assert lay.images_without_feature == ["T2", "T3"]


def test_a_layer_in_another_crs_is_reprojected_before_matching(tmp_path: Path) -> None:
    from pyproj import Transformer

    t = Transformer.from_crs(CRS, "EPSG:4326", always_xy=True)
    geoms = [
        shapely.transform(
            shapely.box(*IMAGES[k]).segmentize(5),
            lambda xy: np.column_stack(t.transform(xy[:, 0], xy[:, 1])),
        )
        for k in ("T2", "T3")
    ]
    p = _write(tmp_path / "wgs.gpkg", geoms, crs="EPSG:4326")
    lay = read_layer(p, "source/wgs.gpkg", images=IMAGES, image_crs=CRS)
    assert any("reprojected from WGS 84" in n for n in lay.notes)
    assert lay.matched == {"T2": 0, "T3": 1} and lay.images_without_feature == ["T0", "T1"]


def test_seamlines_are_matched_by_coverage_and_gaps_listed(tmp_path: Path) -> None:
    # two seamline polygons cut along other lines than the tiles: together they cover T0..T2, T3 half
    geoms = [
        shapely.box(500000.0, 5000000.0, 500150.0, 5000100.0),
        shapely.box(500150.0, 5000000.0, 500350.0, 5000100.0),
    ]
    p = _write(tmp_path / "Seamlines.shp", geoms)
    assert (
        role_of("source/Seamlines.shp") == "seamlines"
        and role_of("source/mosaic_cutlines.gpkg") == "seamlines"
    )
    lay = read_layer(p, "source/Seamlines.shp", images=IMAGES, image_crs=CRS)
    assert lay.role == "seamlines" and lay.matched_by == "coverage of the footprints"
    assert sorted(lay.matched) == ["T0", "T1", "T2"] and lay.images_without_feature == ["T3"]


def test_block_outlines_by_their_id_attribute(tmp_path: Path) -> None:
    geoms = [
        shapely.box(500000.0, 5000000.0, 500200.0, 5000100.0),
        shapely.box(500200.0, 5000000.0, 500400.0, 5000100.0),
        shapely.Polygon([(0, 0), (1, 1), (1, 0), (0, 1)]),
    ]  # a bow-tie: invalid
    p = _write(tmp_path / "Lose.gpkg", geoms, Los=["L1", "L2", "L3"])
    assert role_of("source/Lose.gpkg") is None  # "Lose" is not one of the words: the role is given
    lay = read_layer(p, "source/Lose.gpkg", images=IMAGES, image_crs=CRS, role="blocks")
    assert sorted(lay.outlines) == ["L1", "L2"]
    assert lay.outlines["L2"].bounds == (500200.0, 5000000.0, 500400.0, 5000100.0)
    assert any("block 'L3': invalid polygon" in n for n in lay.notes)


def test_block_outlines_without_an_id_are_not_used(tmp_path: Path) -> None:
    geoms = [shapely.box(*IMAGES["T0"]), shapely.box(*IMAGES["T1"])]
    p = _write(tmp_path / "blocks.shp", geoms, name=["same", "same"])
    lay = read_layer(p, "source/blocks.shp", images=IMAGES, image_crs=CRS)
    assert (
        lay.role == "blocks"
        and not lay.outlines
        and "no attribute names the blocks" in (lay.error or "")
    )


@pytest.mark.parametrize(
    "content", [b"", b"not a shapefile at all", b'{"type": "FeatureCollection", "feat']
)
def test_a_broken_vector_file_is_a_line_not_a_crash(tmp_path: Path, content: bytes) -> None:
    p = tmp_path / ("broken.geojson" if content.startswith(b"{") else "broken.gpkg")
    p.write_bytes(content)
    lay = read_layer(p, f"source/{p.name}", images=IMAGES, image_crs=CRS)
    assert lay.error and f"source/{p.name}" in lay.error and not lay.matched
