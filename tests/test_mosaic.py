"""Mosaics (JRC Table 11) and pan-sharpening sharpness (§10.3): pure measures and file reading."""

from __future__ import annotations

import numpy as np
import pyogrio
import pytest
import shapely
from scipy import ndimage
from shapely.geometry import box

from orthospec.errors import MeasureError
from orthospec.measures.mosaic import (
    gradient_energy,
    pan_sharpness,
    radiometric_difference,
    seamline_coverage,
)
from orthospec.raster.vector import read_vector


def test_seamlines_that_partition_the_aoi_are_ok():
    aoi = box(0, 0, 100, 50)
    cells = [box(0, 0, 40, 50), box(40, 0, 100, 25), box(40, 25, 100, 50)]
    r = seamline_coverage(cells, aoi)
    assert r.ok and r.gap_area == 0 and r.overlap_area == 0 and r.covered_area == 5000


def test_seamline_gap_and_overlap_areas():
    aoi = box(0, 0, 100, 100)
    polys = [box(0, 0, 60, 100), box(50, 0, 100, 90)]  # overlap 10x90, gap 40x10
    r = seamline_coverage(polys, aoi)
    assert r.gap_area == pytest.approx(400) and r.gap_pct == pytest.approx(4.0)
    assert r.overlap_area == pytest.approx(900) and r.overlap_pct == pytest.approx(9.0)
    assert r.overlapping_pairs == ((0, 1),)
    assert not r.ok


def test_radiometric_difference_percent_of_mean_level():
    r = radiometric_difference([100.0, 50.0], [110.0, 50.0], bit_depth=8)
    assert r.difference_pct[0] == pytest.approx(100 * 10 / 105)
    assert r.difference_pct[1] == 0.0
    assert r.difference_range_pct[0] == pytest.approx(100 * 10 / 256)
    assert r.max_pct == pytest.approx(9.5238, rel=1e-4)  # within Table 11's 10 %
    with pytest.raises(MeasureError):
        radiometric_difference([1.0], [1.0, 2.0])


def test_gradient_energy_proxy_separates_sharp_and_blurred():
    rng = np.random.default_rng(5)
    pan = ndimage.gaussian_filter(rng.normal(size=(256, 256)), 0.7) * 50 + 500
    same = np.stack([pan * 0.5 + 10, pan * 0.4 + 20, pan * 0.3])  # contrast changes only
    blurred = np.stack([ndimage.gaussian_filter(b, 2.0) for b in same])
    sharp = pan_sharpness(pan, same)
    soft = pan_sharpness(pan, blurred)
    assert sharp.ratio == pytest.approx(1.0, rel=1e-9)
    assert sharp.highpass_correlation == pytest.approx(1.0, abs=1e-9)
    assert soft.ratio < 0.5 and soft.highpass_correlation < sharp.highpass_correlation
    with pytest.raises(MeasureError, match="flat"):
        gradient_energy(np.zeros((10, 10)))


def test_seamline_and_aoi_files(tmp_path):
    seams = tmp_path / "seamlines.gpkg"
    aoi = tmp_path / "aoi.gpkg"
    geoms = np.array(shapely.to_wkb([box(0, 0, 50, 100), box(50, 0, 100, 95)]), dtype=object)
    pyogrio.raw.write(str(seams), geometry=geoms, field_data=[np.array([1, 2])],
                      fields=["id"], geometry_type="Polygon", crs="EPSG:25832", driver="GPKG")
    pyogrio.raw.write(str(aoi), geometry=np.array([shapely.to_wkb(box(0, 0, 100, 100))],
                                                  dtype=object),
                      field_data=[np.array([1])], fields=["id"], geometry_type="Polygon",
                      crs="EPSG:25832", driver="GPKG")
    (cells, _), (area, _) = read_vector(seams), read_vector(aoi)
    r = seamline_coverage(cells, shapely.union_all(area))  # what the mosaic provider measures
    assert r.gap_area == pytest.approx(250) and r.overlap_area == 0
    with pytest.raises(MeasureError, match="missing.gpkg: file not found"):
        read_vector(tmp_path / "missing.gpkg")
