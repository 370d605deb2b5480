"""Checkpoint distribution: quadrants, spacing vs Δ/10, GCP independence, footprint."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from orthospec.errors import MeasureError
from orthospec.measures.distribution import checkpoint_distribution


def _grid(nx=5, ny=4, size=1000.0):
    xs = (np.arange(nx) + 0.5) * size / nx
    ys = (np.arange(ny) + 0.5) * size / ny
    gx, gy = np.meshgrid(xs, ys)
    return gx.ravel(), gy.ravel()


def test_even_grid_is_well_distributed():
    x, y = _grid()
    ids = [f"C{i}" for i in range(20)]
    r = checkpoint_distribution(x, y, ids=ids, area=box(0, 0, 1000, 1000))
    assert r.n == 20 and r.count_ok and r.split_source == "area"
    assert r.centre == (500.0, 500.0)
    assert r.diagonal == pytest.approx(1000 * np.sqrt(2))
    # 5 columns: x = 100,300,500,700,900 -> x=500 goes east: 3 east, 2 west per row; 2 rows north
    assert r.quadrant_counts == {"NE": 6, "NW": 4, "SW": 4, "SE": 6}
    assert r.quadrants_ok and r.well_distributed
    assert r.min_quadrant_share == pytest.approx(0.2) and r.required_quadrant_share == 0.2
    assert r.nn_reference == pytest.approx(100 * np.sqrt(2))
    assert r.nn_min == pytest.approx(200.0)  # x spacing 200, y spacing 250
    assert r.nn_min_ratio == pytest.approx(200 / (100 * np.sqrt(2)))
    assert r.closer_than_reference == ()


def test_clustered_points_fail_quadrants_and_spacing():
    x, y = _grid()
    x = x * 0.3  # all in the west part of the block
    pts_x = np.r_[x, 990.0]
    pts_y = np.r_[y, 990.0]
    r = checkpoint_distribution(pts_x, pts_y, area=box(0, 0, 1000, 1000))
    assert r.quadrant_counts["SE"] == 0 and not r.quadrants_ok
    assert r.min_quadrant_share == 0.0
    assert r.quadrant_shares["NE"] == pytest.approx(1 / 21)
    assert len(r.closer_than_reference) == 20  # 60 m x-spacing < Δ/10 = 141 m


def test_hull_split_when_no_area_and_count_below_twenty():
    r = checkpoint_distribution([0, 10, 0, 10, 4], [0, 0, 20, 20, 3])
    assert r.split_source == "convex_hull" and r.centre == (5.0, 10.0)
    assert not r.count_ok
    assert r.quadrant_counts["SW"] == 2


def test_gcp_proximity_and_identical_points():
    x, y = _grid()
    ids = [f"C{i}" for i in range(20)]
    gx = np.array([x[0] + 5.0, x[5], 2000.0])
    gy = np.array([y[0], y[5], 2000.0])
    r = checkpoint_distribution(x, y, ids=ids, gcp_x=gx, gcp_y=gy, gcp_ids=["G1", "G2", "C19"],
                                min_gcp_distance=10.0)
    assert set(r.too_close_to_gcp) == {"C0", "C5"}
    assert set(r.identical_to_gcp) == {"C5", "C19"}  # same position / same id
    assert r.gcp_min_distance == 0.0
    assert r.gcp_distance is not None and r.gcp_distance[0] == pytest.approx(5.0)


def test_footprint():
    x, y = _grid()
    fp = Polygon([(0, 0), (1000, 0), (0, 1000)])  # lower-left triangle
    r = checkpoint_distribution(x, y, footprint=fp)
    inside = x + y <= 1000
    assert len(r.outside_footprint) == int((~inside).sum())
    assert r.inside_footprint_share == pytest.approx(inside.mean())


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"x": [], "y": []}, "no checkpoints"),
        ({"x": [1.0, np.nan], "y": [1.0, 2.0], "ids": ["a", "b"]}, "non-finite.*b"),
        ({"x": [1.0, 2.0], "y": [1.0]}, "same length"),
        ({"x": [1.0], "y": [1.0], "area": Polygon()}, "empty"),
        ({"x": [1.0], "y": [1.0], "gcp_x": [1.0]}, "together"),
    ],
)
def test_bad_input(kwargs, match):
    with pytest.raises(MeasureError, match=match):
        checkpoint_distribution(**kwargs)


@pytest.mark.parametrize("workers", [1, 2, -1])
def test_nearest_neighbour_distances_are_exact_whatever_the_threads(workers):
    """The KD-tree's threaded queries (a national block) give every point's nearest-neighbour
    distance, as the brute-force minimum over all pairs does; so does the GCP distance."""
    rng = np.random.default_rng(7)
    x, y = rng.random(1500) * 1000, rng.random(1500) * 1000
    gx, gy = rng.random(40) * 1000, rng.random(40) * 1000
    r = checkpoint_distribution(
        x, y, area=box(0, 0, 1000, 1000), gcp_x=gx, gcp_y=gy, workers=workers
    )
    pair = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    np.fill_diagonal(pair, np.inf)
    np.testing.assert_allclose(r.nn_distance, pair.min(axis=1), rtol=1e-12, atol=0)
    one = checkpoint_distribution(x, y, area=box(0, 0, 1000, 1000), gcp_x=gx, gcp_y=gy, workers=1)
    np.testing.assert_array_equal(
        r.nn_distance, one.nn_distance
    )  # bit for bit: same bytes in qcr.json
    to_gcp = np.hypot(x[:, None] - gx[None, :], y[:, None] - gy[None, :]).min(axis=1)
    np.testing.assert_allclose(r.gcp_distance, to_gcp, rtol=0, atol=1e-9)


def _brute(x, y, gx, gy, ids, gids, min_gcp, tol=1e-6):
    """Every figure from all pairs (numpy, no tree): the independent truth."""
    pair = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    np.fill_diagonal(pair, np.inf)
    g = np.hypot(x[:, None] - gx[None, :], y[:, None] - gy[None, :]).min(axis=1)
    ident = (g <= tol) | np.isin(ids, gids)
    return pair.min(), g.min(), set(ids[g < min_gcp]), set(ids[ident])


@pytest.mark.parametrize("layout", ["uniform", "cluster", "duplicates", "line", "grid", "two"])
@pytest.mark.parametrize("min_gcp", [0.0, 3.0, 5000.0])
def test_smallest_spacing_and_gcp_figures_match_brute_force(layout, min_gcp):
    """The smallest spacing (bounded queries) and the GCP figures (asked from the GCPs' side) are
    the all-pairs values, on layouts that defeat an estimate: a tight cluster off the probed
    points, exact duplicates, a line, a regular grid (every spacing equal), two points; the
    smallest spacing is bit for bit the minimum of every point's nearest-neighbour distance."""
    rng = np.random.default_rng(hash(layout) % 1000)
    n = 3000
    x, y = rng.random(n) * 1000, rng.random(n) * 1000
    if layout == "cluster":  # 400 points within 1 cm, at rows the evenly spread probes skip
        x[1:401], y[1:401] = 500 + rng.random(400) * 0.01, 500 + rng.random(400) * 0.01
    elif layout == "duplicates":
        x[2500:], y[2500:] = x[:500], y[:500]
    elif layout == "line":
        x, y = np.arange(n) * 0.7, np.full(n, 3.0)
    elif layout == "grid":
        gx_, gy_ = np.meshgrid(np.arange(60) * 10.0, np.arange(50) * 10.0)
        x, y = gx_.ravel(), gy_.ravel()
    elif layout == "two":
        x, y = np.array([1.0, 4.0]), np.array([2.0, 6.0])
    ids = np.array([f"C{i}" for i in range(x.size)], dtype=object)
    gx = np.r_[rng.random(30) * 1000, x[x.size // 2], x[-1] + 2.0]
    gy = np.r_[rng.random(30) * 1000, y[y.size // 2], y[-1]]
    gids = np.array([f"G{i}" for i in range(31)] + [str(ids[1])], dtype=object)
    r = checkpoint_distribution(
        x, y, ids=ids, gcp_x=gx, gcp_y=gy, gcp_ids=gids, min_gcp_distance=min_gcp
    )
    nn_min, g_min, near, ident = _brute(x, y, gx, gy, ids, gids, min_gcp)
    assert r.nn_min == pytest.approx(nn_min, rel=1e-12, abs=0)
    assert r.nn_min == r.nn_distance.min()  # bit for bit the per-point minimum
    assert r.gcp_min_distance == pytest.approx(g_min, rel=1e-12, abs=1e-12)
    assert r.gcp_min_distance == r.gcp_distance.min()
    assert set(r.too_close_to_gcp) == near and set(r.identical_to_gcp) == ident
    assert list(r.too_close_to_gcp) == [i for i in ids.tolist() if i in near]  # point order
    assert list(r.identical_to_gcp) == [i for i in ids.tolist() if i in ident]


def test_one_close_pair_among_many_is_found_wherever_it_is():
    """22,500 points on a jittered 10 m grid (every spacing at least 6 m) and one pair 1 mm apart:
    the smallest spacing is that pair's distance, known by construction, wherever the pair lies
    (30 places: most points are never probed for the upper bound, so most of these pairs are not)."""
    rng = np.random.default_rng(11)
    gx_, gy_ = np.meshgrid(np.arange(150) * 10.0, np.arange(150) * 10.0)
    x0 = gx_.ravel() + rng.uniform(-2, 2, 22500)
    y0 = gy_.ravel() + rng.uniform(-2, 2, 22500)
    for row in rng.choice(22499, 30, replace=False):
        x, y = x0.copy(), y0.copy()
        x[row + 1], y[row + 1] = x[row] + 0.0006, y[row] + 0.0008
        r = checkpoint_distribution(x, y)
        assert r.nn_min == pytest.approx(0.001, rel=1e-6), row
        assert r.nn_min == r.nn_distance.min()
