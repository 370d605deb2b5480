"""Fits: affine / polynomial residuals, closed-form PRESS against explicit refits, limits."""

from __future__ import annotations

import numpy as np
import pytest

from orthospec.errors import MeasureError
from orthospec.measures.fits import (
    fit_affine,
    fit_polynomial,
    interior_orientation,
    interior_orientation_limits,
    scanner_grid_fit,
)


def _gcps(n: int, seed: int = 0, noise: float = 0.5):
    rng = np.random.default_rng(seed)
    src = rng.uniform(0, 10000, (n, 2))  # image col,row
    x, y = src[:, 0], src[:, 1]
    dst = np.column_stack([
        500000 + 0.5 * x + 0.01 * y + 2e-6 * x * x,
        4000000 - 0.02 * x - 0.5 * y + 1e-6 * x * y,
    ]) + rng.normal(0, noise, (n, 2))
    return src, dst


def _explicit_press(src, dst, order):
    """PRESS by n explicit refits (numpy lstsq on raw monomials)."""
    def design(xy):
        x, y = xy[:, 0] / 1e4, xy[:, 1] / 1e4
        cols = [np.ones_like(x), x, y] + ([x * x, x * y, y * y] if order == 2 else [])
        return np.column_stack(cols)

    diffs = []
    for i in range(len(src)):
        keep = np.arange(len(src)) != i
        coef, *_ = np.linalg.lstsq(design(src[keep]), dst[keep], rcond=None)
        diffs.append(dst[i] - design(src[i:i + 1])[0] @ coef)
    d = np.array(diffs)
    return d


@pytest.mark.parametrize("order", [1, 2])
def test_closed_form_press_equals_explicit_refits(order):
    src, dst = _gcps(12, seed=order)
    res = fit_polynomial(src, dst, order=order, ids=[f"G{i}" for i in range(12)])
    d = _explicit_press(src, dst, order)
    np.testing.assert_allclose(res.loo_x, d[:, 0], rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(res.loo_y, d[:, 1], rtol=1e-7, atol=1e-7)
    assert res.press_x == pytest.approx(np.mean(d[:, 0] ** 2), rel=1e-8)
    assert res.press_r == pytest.approx(np.mean((d**2).sum(axis=1)), rel=1e-8)
    assert res.press_sum_r == pytest.approx(np.sum(d**2), rel=1e-8)  # the "sum" reading
    assert res.sqrt_press_r == pytest.approx(np.sqrt(res.press_r))
    # leave-one-out errors are never smaller than fitted residuals
    assert res.sqrt_press_r >= res.rmse_r


def test_second_order_absorbs_quadratic_terms_first_order_does_not():
    src, dst = _gcps(30, noise=0.0)
    assert fit_polynomial(src, dst, order=2).rmse_r < 1e-6
    assert fit_polynomial(src, dst, order=1).rmse_r > 1.0


def test_residual_statistics_hand_checked():
    # Exact affine plus a known residual pattern orthogonal to the affine space.
    src = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    base = src @ np.array([[2.0, 0.5], [-0.3, 1.5]]) + [10, 20]
    eps = np.array([1, -1, -1, 1], float) * 0.2  # x·y pattern: not representable by affine
    res = fit_affine(src, base + np.column_stack([eps, -eps]), ids=list("abcd"), unit="px")
    np.testing.assert_allclose(res.residual_x, eps, atol=1e-12)
    assert res.rmse_x == pytest.approx(0.2) and res.rmse_y == pytest.approx(0.2)
    assert res.max_residual == pytest.approx(0.2 * np.sqrt(2))
    assert res.max_abs_x == pytest.approx(0.2)
    np.testing.assert_allclose(res.predict(src), base + np.column_stack([eps, -eps]) -
                               np.column_stack([res.residual_x, res.residual_y]), atol=1e-9)


def test_order_three_refused_citing_table_9():
    src, dst = _gcps(20)
    with pytest.raises(MeasureError, match="Table 9"):
        fit_polynomial(src, dst, order=3)
    with pytest.raises(MeasureError, match="1 or 2"):
        fit_polynomial(src, dst, order=0)


@pytest.mark.parametrize(
    ("src", "dst", "kwargs", "match"),
    [
        (np.zeros((3, 2)), np.zeros((3, 2)), {"order": 1}, "at least 4"),
        (np.c_[np.arange(6.0), np.arange(6.0)], np.zeros((6, 2)), {"order": 1}, "degenerate"),
        (np.array([[0, 0], [1, 0], [0, 1], [1, np.nan], [2, 2]]), np.zeros((5, 2)),
         {"order": 1, "ids": list("abcde")}, "non-finite.*d"),
        (np.zeros((5, 3)), np.zeros((5, 2)), {"order": 1}, "shape"),
        (np.random.default_rng(0).random((5, 2)), np.zeros((5, 2)),
         {"order": 1, "ids": list("aabcd")}, "duplicate.*a"),
    ],
)
def test_fit_bad_input(src, dst, kwargs, match):
    with pytest.raises(MeasureError, match=match):
        fit_polynomial(src, dst, **kwargs)


def _fiducials(n):
    corners = [[-106, -106], [106, -106], [106, 106], [-106, 106]]
    mids = [[0, -110], [110, 0], [0, 110], [-110, 0]]
    return np.array(corners + (mids if n == 8 else []), float)


@pytest.mark.parametrize("n", [4, 8])
def test_interior_orientation_in_pixels(n):
    mm = _fiducials(n)
    px = mm / 0.021 + [11000, 11000]  # 21 µm scan
    rng = np.random.default_rng(n)
    noisy = px + rng.normal(0, 0.3, px.shape)
    res = interior_orientation(noisy, mm, ids=[f"F{i}" for i in range(n)])
    assert res.unit == "px" and res.kind == "interior-orientation" and res.n == n
    assert 0 < res.rmse_max_axis < 0.5
    assert res.max_residual >= max(res.max_abs_x, res.max_abs_y)
    assert interior_orientation_limits(n) == ((0.5, 0.7) if n == 4 else (1.0, 0.7))


def test_interior_orientation_other_counts_refused():
    with pytest.raises(MeasureError, match=r"4 .*or 8"):
        interior_orientation(np.zeros((6, 2)), np.zeros((6, 2)))


def test_scanner_grid_fit_and_grid_size():
    g = np.arange(5) * 50000.0  # 5 x 5 grid, 50 mm spacing, in µm
    ref = np.array([[x, y] for y in g for x in g])
    rng = np.random.default_rng(3)
    meas = ref * 1.00001 + [3.0, -2.0] + rng.normal(0, 2.0, ref.shape)
    res = scanner_grid_fit(meas, ref)
    assert res.grid_shape == (5, 5) and res.unit == "µm" and res.n == 25
    assert 0.5 < res.rmse_x < 4.0
    small = ref.reshape(5, 5, 2)[:4, :, :].reshape(-1, 2)
    with pytest.raises(MeasureError, match="4 x 5"):
        scanner_grid_fit(small, small)
