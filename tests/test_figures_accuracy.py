"""Accuracy figures: valid SVG, deterministic bytes, expected artists present."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from orthospec.errors import MeasureError
from orthospec.figures.accuracy import (
    checkpoint_map_svg,
    quadrant_distribution_svg,
    residual_histograms_svg,
)
from orthospec.measures.distribution import checkpoint_distribution

SVG = "{http://www.w3.org/2000/svg}"


def _data(n=20, seed=0):
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(0, 1000, n), rng.uniform(0, 1000, n)
    dx, dy = rng.normal(0, 0.3, n), rng.normal(0, 0.3, n)
    return x, y, dx, dy


def _gids(svg: str) -> set[str]:
    root = ET.fromstring(svg)
    return {el.get("id") for el in root.iter() if el.get("id")}


def test_checkpoint_map_is_deterministic_and_has_vectors_scale_and_gcps():
    x, y, dx, dy = _data()
    kw = {"ids": [f"C{i}" for i in range(20)], "gcp_x": [10.0, 990.0], "gcp_y": [10.0, 990.0],
          "flagged": ["C3"]}
    a = checkpoint_map_svg(x, y, dx, dy, **kw)
    b = checkpoint_map_svg(x, y, dx, dy, **kw)
    assert a == b
    ids = _gids(a)
    assert {"checkpoints", "discrepancy-vectors", "scale-arrow", "gcps", "scale-label"} <= ids
    assert "C3" in a and "discrepancy" in a
    assert "<dc:date>" not in a
    without = checkpoint_map_svg(x, y, dx, dy)
    assert "gcps" not in _gids(without)


def test_map_changes_with_data():
    x, y, dx, dy = _data()
    assert checkpoint_map_svg(x, y, dx, dy) != checkpoint_map_svg(x, y, dx * 2, dy)


def test_quadrant_figure_marks_low_shares():
    x, y, *_ = _data()
    x = x * 0.4  # crowd into the west
    r = checkpoint_distribution(x, y, area=None)
    svg = quadrant_distribution_svg(x, y, centre=(500.0, 500.0),
                                    shares={"NE": 0.0, "NW": 0.5, "SW": 0.5, "SE": 0.0},
                                    area=[(0, 0), (1000, 0), (1000, 1000), (0, 1000)])
    ids = _gids(svg)
    assert {"split-x", "split-y", "share-NE", "share-SW", "area", "checkpoints"} <= ids
    assert "NE 0%" in svg
    assert quadrant_distribution_svg(x, y, centre=r.centre) == \
        quadrant_distribution_svg(x, y, centre=r.centre)


def test_histograms_have_one_panel_per_axis():
    _, _, dx, dy = _data()
    two = residual_histograms_svg(dx, dy)
    three = residual_histograms_svg(dx, dy, dy * 2)
    assert "mean-dz" not in _gids(two)
    assert {"mean-dx", "mean-dy", "mean-dz", "rmse-dz"} <= _gids(three)
    assert two == residual_histograms_svg(dx, dy)


def test_bad_figure_input():
    with pytest.raises(MeasureError, match="non-finite"):
        checkpoint_map_svg([0.0, 1.0], [0.0, 1.0], [np.nan, 0.0], [0.0, 0.0])
    with pytest.raises(MeasureError, match="expected 2"):
        residual_histograms_svg([0.0, 1.0], [0.0])


def test_map_draws_block_outline_and_a_ground_scale_bar():
    x, y, dx, dy = _data()
    poly = [(-50.0, -50.0), (1950.0, -50.0), (1950.0, 1050.0), (-50.0, 1050.0)]  # 2 km wide block
    svg = checkpoint_map_svg(x, y, dx, dy, polygon=poly, scale=100.0)
    ids = _gids(svg)
    assert {"block-outline", "map-scale-bar", "map-scale-label", "scale-arrow"} <= ids
    # the ground bar: a fifth of the 2000 m wide extent (400 m) rounded up to 1-2-5, i.e. 500 m
    root = ET.fromstring(svg)
    label = "".join(next(el for el in root.iter() if el.get("id") == "map-scale-label").itertext())
    assert label.strip() == "500 m"
    assert "1 m discrepancy (vectors × 100)" in svg  # vectors to scale: the stated factor is the one used
