"""The numpy kernels of the edge chain (measures/edge/numfit.py) against scipy, the library they
replace for start-up time (issue 31): scipy is the independent reference here, and the whole
chain run with either gives the same figures."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize, special
from scipy.interpolate import make_smoothing_spline as scipy_spline

from orthospec.measures.edge import EdgeLimits, measure_edge, numfit
from orthospec.measures.synthetic import PsfFamily, family_edge, family_truth


@pytest.mark.parametrize("n", [6, 40, 160])
def test_spline_is_scipys_gcv_smoothing_spline(n):
    rng = np.random.default_rng(n)
    x = np.sort(rng.uniform(-10, 10, n))
    y = 100 * np.tanh(x) + rng.normal(0, 3, n)
    w = rng.integers(1, 30, n).astype(float)
    ref, ours = scipy_spline(x, y, w=w), numfit.make_smoothing_spline(x, y, w=w)
    q = np.linspace(-11, 11, 400)  # extrapolation beyond the end knots included
    for nu in (0, 1, 2):
        a = ref(q) if nu == 0 else ref.derivative(nu)(q)
        b = ours(q) if nu == 0 else ours.derivative(nu)(q)
        assert (
            np.max(np.abs(a - b)) <= 1e-4 * np.max(np.abs(a)) + 1e-9
        )  # GCV argmin to 1e-5, eigen-basis rounding
    fixed = scipy_spline(x, y, w=w, lam=0.5)(q)
    assert numfit.make_smoothing_spline(x, y, w=w, lam=0.5)(q) == pytest.approx(fixed, abs=1e-6)


def test_spline_rejects_what_scipy_rejects():
    x = np.arange(6.0)
    with pytest.raises(ValueError):
        numfit.make_smoothing_spline(x[::-1], x)
    with pytest.raises(ValueError):
        numfit.make_smoothing_spline(x[:4], x[:4])
    with pytest.raises(ValueError):
        numfit.make_smoothing_spline(x, x, w=np.zeros(6))


@pytest.mark.parametrize(
    "d1,d2,f", [(1, 10, 2.0), (3, 50, 0.5), (2, 200, 7.0), (5, 5, 1e-3), (40, 900, 1.3)]
)
def test_f_survival_is_scipys(d1, d2, f):
    assert numfit.fdtrc(d1, d2, f) == pytest.approx(
        float(special.fdtrc(d1, d2, f)), rel=1e-10, abs=1e-14
    )


def test_brentq_is_scipys():
    def f(t):
        return math.tanh(t) - 0.3

    assert numfit.brentq(f, -2, 3) == pytest.approx(optimize.brentq(f, -2, 3), abs=1e-11)
    with pytest.raises(ValueError):
        numfit.brentq(f, 1, 3)


def test_least_squares_reaches_scipys_minimum_with_and_without_bounds():
    rng = np.random.default_rng(2)
    x = np.linspace(-4, 4, 120)
    y = 10 + 50 / (1 + np.exp(-(x - 0.3) / 0.7)) + rng.normal(0, 0.5, x.size)

    def resid(p):
        return p[0] + p[1] / (1 + np.exp(-(x - p[2]) / p[3])) - y

    p0 = np.array([0.0, 40.0, 0.0, 1.0])
    ref = optimize.least_squares(resid, p0, x_scale="jac")
    ours = numfit.least_squares(resid, p0)
    assert ours.status > 0 and ours.x == pytest.approx(ref.x, rel=1e-6)
    lo, hi = np.array([-100, 0, -1, 0.9]), np.array([100, 100, 1, 5])  # the width's bound is active
    ref = optimize.least_squares(resid, p0, bounds=(lo, hi), x_scale="jac")
    ours = numfit.least_squares(resid, p0, bounds=(lo, hi))
    assert ours.x[3] == pytest.approx(0.9) and ours.x == pytest.approx(ref.x, rel=1e-5)
    assert ours.cost == pytest.approx(ref.cost, rel=1e-8)


# one ROI of each family at SNR inf and 100 (issue 31's grid): the model selected is the same
# and the figures within a small fraction of the targets (FWHM 2 %, RER 0.02, MTF 0.01)
FAMILIES = [
    PsfFamily("gauss", sigma=0.7),
    PsfFamily("halo", sigma=0.55, sigma2=4.0, weight=0.1),
    PsfFamily("defocus", sigma=0.5, radius=1.5),
    PsfFamily("motion_x", sigma=0.5, length=2.0),
    PsfFamily("mtfc", sigma=0.8, amount=0.3),
]


@pytest.mark.parametrize("fam", FAMILIES, ids=lambda f: f.kind)
@pytest.mark.parametrize("snr", [None, 100.0])
def test_chain_gives_scipys_figures(fam, snr):
    truth = family_truth(fam, angle_deg=8.0)
    img = family_edge(
        fam,
        (100, 100),
        angle_deg=8.0,
        dark=40.0,
        bright=200.0,
        snr=snr,
        bit_depth=8,
        offset_px=0.3,
        rng=np.random.default_rng(5),
        truth=truth,
    )
    lim = EdgeLimits(min_snr=25)
    ours = measure_edge(img, limits=lim)
    with numfit.use_scipy():
        ref = measure_edge(img, limits=lim)
    assert ours.valid and ref.valid and ours.primary_fit == ref.primary_fit
    assert ours.angle_deg == pytest.approx(ref.angle_deg, abs=1e-6)
    assert ours.estimate("fwhm_px").value == pytest.approx(ref.estimate("fwhm_px").value, rel=0.002)
    assert ours.estimate("rer").value == pytest.approx(ref.estimate("rer").value, abs=0.002)
    assert ours.estimate("mtf_nyquist").value == pytest.approx(
        ref.estimate("mtf_nyquist").value, abs=0.001
    )
