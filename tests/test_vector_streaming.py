"""Seamline layers read in bounded batches and measured by the coverage path when the polygons form
a coverage (issue 28 item 7): the same geometries and the same gap / overlap as the general path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyogrio.raw
import pytest
import shapely

from orthospec.measures import mosaic
from orthospec.measures.mosaic import seamline_coverage
from orthospec.raster.reading import read_vector


def _write(path: Path, geoms: list) -> Path:
    pyogrio.raw.write(str(path), shapely.to_wkb(np.asarray(geoms, dtype=object)),
                      [np.arange(len(geoms), dtype=np.int64)], ["id"], crs="EPSG:25832",
                      geometry_type="Polygon", driver="GPKG")
    return path


def _grid(nx: int, ny: int) -> list:
    return [
        shapely.box(i * 10.0, j * 10.0, i * 10.0 + 10, j * 10.0 + 10)
        for j in range(ny)
        for i in range(nx)
    ]


@pytest.mark.parametrize("batch", [1, 7, 50, 20_000])
def test_batches_give_every_geometry_in_order(tmp_path, batch):
    geoms = _grid(10, 5)
    f = _write(tmp_path / "s.gpkg", geoms)
    got, crs = read_vector(f, batch=batch)
    assert crs == "EPSG:25832"
    assert [g.wkb for g in got] == [g.wkb for g in geoms]


def _general(geoms: list, aoi, monkeypatch) -> mosaic.SeamlineCoverage:
    with monkeypatch.context() as m:
        m.setattr(shapely, "coverage_is_valid", lambda _a: False)
        return seamline_coverage(geoms, aoi)


def test_a_coverage_measures_as_the_general_path(monkeypatch):
    geoms = _grid(20, 10)
    del geoms[37]  # a hole: a gap of 100 m²
    aoi = shapely.box(0, 0, 200, 100)
    fast = seamline_coverage(geoms, aoi)
    slow = _general(geoms, aoi, monkeypatch)
    assert fast.gap_area == pytest.approx(100.0) and slow.gap_area == pytest.approx(100.0)
    assert fast == slow


@pytest.mark.parametrize("shift", [0.5, 1e-3])
def test_overlaps_still_found(monkeypatch, shift):
    geoms = _grid(6, 4)
    geoms[8] = shapely.affinity.translate(geoms[8], shift, 0)  # overlaps its right neighbour
    aoi = shapely.box(0, 0, 60, 40)
    got = seamline_coverage(geoms, aoi)
    assert got.overlapping_pairs == ((8, 9),)
    assert got.overlap_area == pytest.approx(10.0 * shift)
    assert got == _general(geoms, aoi, monkeypatch)


def test_edges_not_vertex_for_vertex_take_the_general_path():
    geoms = _grid(2, 1)
    geoms[1] = shapely.Polygon(
        [(10, 0), (20, 0), (20, 10), (10, 10), (10, 5)]
    )  # extra vertex on the shared edge
    assert not shapely.coverage_is_valid(np.asarray(geoms, dtype=object))
    got = seamline_coverage(geoms, shapely.box(0, 0, 20, 10))
    assert (got.gap_area, got.overlap_area, got.overlapping_pairs) == (0.0, 0.0, ())
