"""Seed step 8: the ESF fits named by the seed, normalised 0..1.

Non-parametric: the GCV cubic smoothing spline of the binned trimmed ESF (8a-II); its LSF
peak is the RER centre (9b). Parametric: a sum of Fermi-Dirac functions (8a-I); its RER
centre is ESF = 0.5 (9d). The physical PSF model (added) lives in :mod:`.model`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .bins import bins
from .estimators import fwhm_of, make_fit
from .numfit import brentq, least_squares, make_smoothing_spline
from .result import GRID, NYQUIST, SPLINE, EdgeFit


def logistic(z: np.ndarray) -> np.ndarray:
    """1 / (1 + exp(-z)), written with tanh (no overflow for large |z|)."""
    return 0.5 * (1.0 + np.tanh(0.5 * z))


def spline_fit(spl: Any, lo: float, hi: float, levels: tuple[float, float], bw: float) -> EdgeFit:
    """The smoothing spline ``spl`` on the window [lo, hi], normalised by the step-7 levels."""
    dark, bright = levels
    x = np.arange(lo, hi + GRID / 2, GRID)
    esf = (spl(x) - dark) / (bright - dark)
    lsf = spl.derivative(1)(x) / (bright - dark)
    centre = float(x[np.argmax(lsf)])  # seed 9b: the LSF top is the RER centre

    def esf_at(p: np.ndarray) -> np.ndarray:
        return (spl(p) - dark) / (bright - dark)

    return make_fit(SPLINE, x, esf, lsf, centre, esf_at, levels,
                    {"bin_px": bw, "smoothing": "GCV, weights = samples per bin"})


def _fermi(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """a + sum_i b_i logistic((x - c_i) / s_i), p = (a, b_1, c_1, s_1, b_2, ...)."""
    a = p[0]
    out = np.full_like(x, a, dtype=float)
    for b, c, s in p[1:].reshape(-1, 3):
        out += b * logistic((x - c) / s)
    return out


def fermi_fit(d: np.ndarray, v: np.ndarray, bw: float, lo: float, hi: float,
              levels: tuple[float, float], terms: int,
              core: tuple[float, float] | None = None) -> EdgeFit | None:
    """Parametric ESF: a + sum_i b_i / (1 + exp(-(x - c_i) / s_i)) (Fermi-Dirac terms)."""
    got = _fermi_params(*bins(d, v, bw, core), levels, lo, hi, terms)
    if got is None:
        return None
    p, name = got
    a = float(p[0])
    b_tot = float(p[1::3].sum()) if name != "fermi" else float(p[1])
    if b_tot <= 0:
        return None
    x = np.arange(lo, hi + GRID / 2, GRID)

    def esf_at(q: np.ndarray) -> np.ndarray:
        return (_fermi(np.asarray(q, dtype=float), p) - a) / b_tot

    esf = esf_at(x)
    lsf = np.zeros_like(x)
    for b, c, s in p[1:].reshape(-1, 3):
        z = (x - c) / s
        lsf += b / (4.0 * s) / np.cosh(0.5 * z) ** 2
    lsf /= b_tot
    # seed 9d: for a parametric ESF the RER centre is 0.5 on the normalised DN
    try:
        centre = float(brentq(lambda q: float(esf_at(np.array([q]))[0]) - 0.5, lo, hi))
    except ValueError:
        centre = float(x[np.argmax(lsf)])
    return make_fit(name, x, esf, lsf, centre, esf_at, (a, a + b_tot),
                    {"terms": (p.size - 1) // 3, "params": [float(q) for q in p]})


def _fermi_params(xb: np.ndarray, yb: np.ndarray, nb: np.ndarray, levels: tuple[float, float],
                  lo: float, hi: float, terms: int) -> tuple[np.ndarray, str] | None:
    """Weighted least squares of the bin means: one term first, then ``terms`` started from it
    (kept unless a term degenerates into a spike narrower than 0.05 px)."""
    dark, bright = levels
    span = bright - dark
    sw = np.sqrt(nb)

    def jac(p: np.ndarray) -> np.ndarray:
        cols = [sw]
        for b, c, s in p[1:].reshape(-1, 3):
            z = (xb - c) / s
            lg = logistic(z)
            dl = lg * (1.0 - lg)
            cols += [lg * sw, -b * dl / s * sw, -b * dl * z / s * sw]
        return np.column_stack(cols)

    def fit(p0: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
        try:
            res = least_squares(
                lambda p: (_fermi(xb, p) - yb) * sw, np.clip(p0, lower, upper),
                jac=jac, bounds=(lower, upper), x_scale="jac", max_nfev=1000)
        except (ValueError, np.linalg.LinAlgError):
            return None
        return res.x if res.status >= 0 and np.all(np.isfinite(res.x)) else None

    big = 10 * abs(span) + 1
    p1 = fit(np.array([dark, span, 0.0, 0.5]),
             np.array([dark - big, 0.0, lo, 0.02]), np.array([bright + big, 3 * big, hi, 10.0]))
    if p1 is None:
        return None
    if terms <= 1:
        return p1, "fermi"
    cs = np.linspace(-0.3, 0.3, terms) * p1[3] + p1[2]
    ss = p1[3] * np.geomspace(0.6, 1.6, terms)
    p0 = np.concatenate([[p1[0]], np.column_stack([np.full(terms, p1[1] / terms), cs, ss]).ravel()])
    lower = np.concatenate([[dark - big], np.tile([0.0, lo, 0.1], terms)])
    upper = np.concatenate([[bright + big], np.tile([1.2 * span, hi, 10.0], terms)])
    pn = fit(p0, lower, upper)
    # a term narrower than 0.05 px with a visible step is a spike fitted to noise
    if pn is not None and not np.any((pn[3::3] < 0.05) & (np.abs(pn[1::3]) > 0.05 * span)):
        return pn, f"fermi{terms}"
    return p1, "fermi"


_BOOT = 12  # parametric bootstrap replicates of the spline (issue 31): u within ~20 %


def spline_uncertainty(d: np.ndarray, v: np.ndarray, bw: float, lo: float, hi: float,
                       levels: tuple[float, float], noise: float, quant: float, fit: EdgeFit,
                       models: dict[str, dict[str, float]],
                       core: tuple[float, float] | None = None) -> dict[str, Any]:
    """Standard uncertainties of the spline's RER, FWHM and MTF@Ny (when it is the primary fit).

    Noise: a parametric bootstrap, the bin means redrawn about the fit with their variance
    noise^2 / n + q^2 / 12 and refitted (GCV again), seeded (deterministic); model: the largest
    difference to the figures of the plausible PSF models (``models``), since the spline is
    chosen when no model describes the edge and the two bracket the truth. In quadrature.
    """
    sel = (d >= lo) & (d <= hi)
    xb, yb, nb = bins(d[sel], v[sel], bw, core)
    dark, bright = levels
    span = bright - dark
    sd = np.sqrt((noise if np.isfinite(noise) else 0.0) ** 2 / nb + quant**2 / 12.0)
    x = np.arange(max(lo, fit.centre_px - 8.0), min(hi, fit.centre_px + 8.0), 0.02)
    base = np.array([fit.rer, fit.fwhm_px, fit.mtf_nyquist])
    rng = np.random.default_rng(0)
    reps = []
    spl0 = make_smoothing_spline(xb, yb, w=nb)
    for _ in range(_BOOT):
        try:
            s = make_smoothing_spline(xb, spl0(xb) + rng.normal(0.0, sd), w=nb)
        except (ValueError, np.linalg.LinAlgError):
            continue
        lsf = s.derivative(1)(x) / span
        c = float(x[np.argmax(lsf)])
        e = (s(np.array([c - 0.5, c + 0.5])) - dark) / span
        area = float(np.sum(lsf))
        mtf = abs(complex(np.sum(lsf * np.exp(-2j * np.pi * NYQUIST * x)))) / area if area > 0 else math.nan
        reps.append([float(e[1] - e[0]), fwhm_of(x, lsf), mtf])
    arr = np.array(reps) if reps else np.full((2, 3), np.nan)
    u_noise = np.nanstd(arr, axis=0, ddof=1)
    u_model = np.zeros(3)
    for fig in models.values():
        other = np.array([fig["rer"], fig["fwhm_px"], fig["mtf_nyquist"]])
        u_model = np.maximum(u_model, np.abs(np.nan_to_num(other - base, nan=0.0)))
    names = ("rer", "fwhm_px", "mtf_nyquist")
    total = np.hypot(u_noise, u_model)
    return {
        "u": dict(zip(names, map(float, total), strict=True)),
        "u_noise": dict(zip(names, map(float, u_noise), strict=True)),
        "u_model": dict(zip(names, map(float, u_model), strict=True)),
    }
