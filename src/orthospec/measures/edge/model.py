"""Seed step 8 (added): the physical ESF model, the PSF integrated over the square pixel.

The PSF is one Gaussian, a Gaussian smeared by a box (defocus, motion: a flat-topped LSF),
two Gaussians (core and halo), a Gaussian sharpened by an unsharp mask, or a Gaussian x a
uniform disk, each convolved with the pixel's footprint at the measured edge angle (closed
forms in :mod:`orthospec.measures.psf`).

Why: the non-parametric spline spends its freedom on noise; a model with the pixel's known
footprint and 1-4 shape parameters is the efficient estimator when it holds. Which model,
and whether it holds, is tested, not assumed (:func:`psf_fit`); docs/edge-method.md, "The
physical PSF model".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..psf import footprint, gauss_boxes_esf, gauss_boxes_esf_dsigma, gauss_boxes_lsf
from . import pupil
from .bins import bin_index, bins
from .estimators import fwhm_of, make_fit
from .numfit import brentq, fdtrc, least_squares, make_smoothing_spline
from .result import GRID, NYQUIST, EdgeFit

_ADEQUATE_P = 1e-3  # lack-of-fit p-value below which the PSF model does not describe the ESF
_MODEL_TEXT = {
    "gauss": "Gaussian PSF x square pixel at the edge angle",
    "gauss-box": "Gaussian PSF x box (defocus/motion smear) x square pixel at the edge angle",
    "gauss2": "two Gaussian PSFs (core and halo, the halo may be shifted) x square pixel",
    "gauss-usm": "Gaussian PSF x square pixel, sharpened by an unsharp mask (1 + k) - k G(sigma_m)",
    "gauss-disk": "Gaussian PSF x uniform disk (defocus) x square pixel at the edge angle",
    "airy": "diffraction by a circular pupil x Gaussian jitter x box smear x square pixel",
    "gauss-mtfc": "Gaussian PSF x square pixel, sharpened by a 3-tap kernel [-k, 1 + 2k, -k] along "
    "rows and columns of the pixel grid (MTFC)",
}
# a uniform disk of radius R projects on a line to the semicircle density
# (2 / (pi R^2)) sqrt(R^2 - u^2); Gauss-Chebyshev (2nd kind) nodes u_i = R cos t_i,
# t_i = i pi / 13, weights 2/13 sin^2 t_i integrate it (ESF error < 1e-8 for sigma 0.5, R 2;
# < 1e-4 down to sigma 0.2)
_DISK_T = np.arange(1, 13) * np.pi / 13
_DISK_U = np.cos(_DISK_T)
_DISK_W = 2.0 / 13 * np.sin(_DISK_T) ** 2


_SHARPENING = frozenset({"gauss-usm", "gauss-mtfc"})  # models of a sharpened product
# a 3-tap kernel [-k, 1 + 2k, -k] on the rows and on the columns (separable, on the pixel
# grid, after sampling) is 9 copies of the blurred image shifted by whole pixels (i, j); along
# the edge normal a shift (i, j) is i cos t + j sin t px: taps (i, j) in {-1, 0, 1}^2
_TAPS = [(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)]


def _tap_weight(i: int, k: float) -> float:
    return 1.0 + 2.0 * k if i == 0 else -k


def _components(
    kind: str, q: np.ndarray, fp: tuple[float, float] = (1.0, 0.0)
) -> list[tuple[float, float, float, float]]:
    """(sigma px, weight, shift px, extra box width px) of each PSF component, shape params q
    (``fp``, the pixel footprint, places the taps of a kernel on the pixel grid)."""
    if kind == "gauss":
        return [(float(q[0]), 1.0, 0.0, 0.0)]
    if kind == "gauss-box":
        return [(float(q[0]), 1.0, 0.0, float(q[1]))]
    if kind == "gauss-disk":  # G(s) x disk of radius R (defocus), by quadrature
        s, r = float(q[0]), float(q[1])
        return [(s, float(w), r * float(u), 0.0) for w, u in zip(_DISK_W, _DISK_U, strict=True)]
    if kind == "gauss-usm":  # (1 + k) G(s) - k G(s) x G(s_m): unsharp masking (MTFC)
        s, sm, k = float(q[0]), float(q[1]), float(q[2])
        return [(s, 1.0 + k, 0.0, 0.0), (math.hypot(s, sm), -k, 0.0, 0.0)]
    if kind == "gauss-mtfc":  # G(s) x pixel, then the 3-tap kernel on rows and columns
        s, k = float(q[0]), float(q[1])
        return [
            (s, _tap_weight(i, k) * _tap_weight(j, k), i * fp[0] + j * fp[1], 0.0) for i, j in _TAPS
        ]
    return [
        (float(q[0]), float(q[2]), 0.0, 0.0),
        (float(q[1]), 1.0 - float(q[2]), float(q[3]), 0.0),
    ]


def _per_component(
    fn: Any,
    x: np.ndarray,
    c: float,
    comps: list[tuple[float, float, float, float]],
    fp: tuple[float, float],
) -> list[np.ndarray]:
    """``fn(x - c - shift_k, sigma_k, (*fp, box_k))`` for every component; components that
    share sigma and box (the disk's quadrature nodes) in one vectorised call."""
    out: list[np.ndarray | None] = [None] * len(comps)
    groups: dict[tuple[float, float], list[int]] = {}
    for i, (sig, _, _, box) in enumerate(comps):
        groups.setdefault((sig, box), []).append(i)
    n = x.size
    for (sig, box), idx in groups.items():
        xs = np.concatenate([x - c - comps[i][2] for i in idx])
        vals = fn(xs, sig, (*fp, box))
        for j, i in enumerate(idx):
            out[i] = vals[j * n : (j + 1) * n]
    return out  # type: ignore[return-value]


def _model_esf(kind: str, x: np.ndarray, p: np.ndarray, fp: tuple[float, float]) -> np.ndarray:
    """a + b * sum_k w_k ESF_k(x - c - shift_k): PSF components x the pixel footprint ``fp``."""
    a, b, c = p[0], p[1], p[2]
    if kind == "airy":
        return a + b * pupil.esf(x - c, float(p[3]), float(p[4]), float(p[5]), fp)
    comps = _components(kind, p[3:], fp)
    esf = _per_component(gauss_boxes_esf, x, c, comps, fp)
    out = np.zeros_like(x, dtype=float)
    for (_, w, _, _), e in zip(comps, esf, strict=True):
        out += w * e
    return a + b * out


def _model_jac(kind: str, x: np.ndarray, p: np.ndarray, fp: tuple[float, float]) -> np.ndarray:
    """Analytic Jacobian of :func:`_model_esf` (the numeric one cost 6-7 model evaluations
    per step, 85 % of the fit time): d/dc from the LSF, d/dsigma = sigma dLSF/dx (heat
    equation); the gauss-box width by a forward difference."""
    b, c = p[1], p[2]
    q = p[3:]
    cols = np.zeros((x.size, p.size))
    cols[:, 0] = 1.0
    if kind == "airy":  # q = f_c, s, L: jitter analytic, cut-off and smear by differences
        fc, s_, ln = (float(v) for v in q)
        e0 = pupil.esf(x - c, fc, s_, ln, fp)
        cols[:, 1] = e0
        cols[:, 2] = -b * pupil.lsf(x - c, fc, s_, ln, fp)
        cols[:, 3] = b * (pupil.esf(x - c, fc * (1 + 1e-5), s_, ln, fp) - e0) / (fc * 1e-5)
        cols[:, 4] = b * pupil.esf_dsigma(x - c, fc, s_, ln, fp)
        h = 1e-5 * max(ln, 1e-2)
        cols[:, 5] = b * (pupil.esf(x - c, fc, s_, ln + h, fp) - e0) / h
        return cols
    comps = _components(kind, q, fp)
    esf_k = _per_component(gauss_boxes_esf, x, c, comps, fp)
    lsf_k = _per_component(gauss_boxes_lsf, x, c, comps, fp)
    ds_k = _per_component(gauss_boxes_esf_dsigma, x, c, comps, fp)
    w = [cm[1] for cm in comps]
    cols[:, 1] = sum(wk * ek for wk, ek in zip(w, esf_k, strict=True))
    cols[:, 2] = -b * sum(wk * lk for wk, lk in zip(w, lsf_k, strict=True))
    if kind == "gauss":
        cols[:, 3] = b * ds_k[0]
    elif kind == "gauss-box":
        cols[:, 3] = b * ds_k[0]
        h = 1e-5 * max(float(q[1]), 1e-2)
        up = gauss_boxes_esf(x - c, float(q[0]), (*fp, float(q[1]) + h))
        cols[:, 4] = b * (up - esf_k[0]) / h
    elif kind == "gauss2":  # q = s1, s2, w, shift
        cols[:, 3] = b * w[0] * ds_k[0]
        cols[:, 4] = b * w[1] * ds_k[1]
        cols[:, 5] = b * (esf_k[0] - esf_k[1])
        cols[:, 6] = -b * w[1] * lsf_k[1]
    elif kind == "gauss-mtfc":  # q = s, k; weights w_i(k) w_j(k), dw_0/dk = 2, dw_1/dk = -1
        k = float(q[1])
        dw = [
            (2.0 if i == 0 else -1.0) * _tap_weight(j, k)
            + _tap_weight(i, k) * (2.0 if j == 0 else -1.0)
            for i, j in _TAPS
        ]
        cols[:, 3] = b * sum(wk * dk for wk, dk in zip(w, ds_k, strict=True))
        cols[:, 4] = b * sum(d * ek for d, ek in zip(dw, esf_k, strict=True))
    elif kind == "gauss-disk":  # q = s, R; component i shifted by R u_i
        cols[:, 3] = b * sum(wk * dk for wk, dk in zip(w, ds_k, strict=True))
        cols[:, 4] = -b * sum(wk * lk * u for wk, lk, u in zip(w, lsf_k, _DISK_U, strict=True))
    else:  # gauss-usm: q = s, s_m, k; components (s, 1 + k), (hypot(s, s_m), -k)
        s_, sm, k = float(q[0]), float(q[1]), float(q[2])
        big = math.hypot(s_, sm)
        cols[:, 3] = b * ((1.0 + k) * ds_k[0] - k * ds_k[1] * s_ / big)
        cols[:, 4] = b * (-k * ds_k[1] * sm / big)
        cols[:, 5] = b * (esf_k[0] - esf_k[1])
    return cols


@dataclass(frozen=True, eq=False)
class _Problem:
    """The binned ESF the models are fitted to: weighted least squares of the bin means."""

    d: np.ndarray  # pixel samples (px, DN) and their bin
    v: np.ndarray
    idx: np.ndarray
    xb: np.ndarray  # bin means and counts
    yb: np.ndarray
    nb: np.ndarray
    sw: np.ndarray  # sqrt(counts): the weights of the residuals
    fp: tuple[float, float]  # pixel footprint at the edge angle
    base_lo: list[float]  # bounds of (a, b, c) shared by every model
    base_hi: list[float]
    # per bin: the rounding variance of a bin mean (0 for float data): q^2 / 12, or q^2 / 4 in a
    # bin whose pixels all hold one DN (:func:`_rounding_variance`)
    qv: np.ndarray
    vd: float = 0.0  # px^2: mean spread of the samples' d within their (finely binned) bins

    def fit(
        self, kind: str, p0: list[float], lower: list[float], upper: list[float]
    ) -> tuple[np.ndarray, float] | None:
        """Parameters and chi2 (2 x cost) of ``kind`` started at ``p0``; None if it fails."""
        lo_b, hi_b = np.array(self.base_lo + lower), np.array(self.base_hi + upper)
        try:
            res = least_squares(
                lambda p: (_model_esf(kind, self.xb, p, self.fp) - self.yb) * self.sw,
                np.clip(np.array(p0, dtype=float), lo_b, hi_b),
                jac=lambda p: _model_jac(kind, self.xb, p, self.fp) * self.sw[:, None],
                bounds=(lo_b, hi_b),
                x_scale="jac",
                max_nfev=400,
            )
        except (ValueError, np.linalg.LinAlgError):
            return None
        if res.status < 0 or not np.all(np.isfinite(res.x)):
            return None
        return res.x, float(2.0 * res.cost)

    def pure_error(self, kind: str, p: np.ndarray) -> float:
        """Variance of the pixels' residuals about their bin's mean residual (the pure error)."""
        e = self.v - _model_esf(kind, self.d, p, self.fp)
        eb = np.bincount(self.idx, weights=e) / np.maximum(np.bincount(self.idx), 1)
        return float(np.sum((e - eb[self.idx]) ** 2) / (self.d.size - self.xb.size))

    def loo(self, kind: str, p: np.ndarray, var: float) -> np.ndarray:
        """Leave-one-out squared error of every bin mean, in units of its variance
        var / n_b + q^2 / 12: r_i / (1 - h_ii) with h the leverage of the linearised weighted fit."""
        r = _model_esf(kind, self.xb, p, self.fp) - self.yb
        jac = _model_jac(kind, self.xb, p, self.fp) * self.sw[:, None]
        try:
            q, _ = np.linalg.qr(jac)
            lev = np.minimum(np.sum(q * q, axis=1), 0.99)
        except np.linalg.LinAlgError:
            lev = np.full(r.size, p.size / r.size)
        return (r / (1.0 - lev)) ** 2 / (var / self.nb + self.qv)

    def chi(self, kind: str, p: np.ndarray, var: float) -> float:
        """chi2 of the bin means with the quantisation-aware variance var / n_b + q^2 / 12.

        The noise averages down with the bin's count, the rounding of a noise-free (or
        low-noise) plateau does not (same DN on every pixel).
        """
        r = _model_esf(kind, self.xb, p, self.fp) - self.yb
        return float(np.sum(r**2 / (var / self.nb + self.qv)))


@dataclass(frozen=True)
class _Test:
    """The chosen model's lack-of-fit F test and (when it fails) the cross-validation."""

    f_stat: float
    dof: tuple[int, int]
    p_value: float
    cv_model: float | None
    cv_spline: float | None


def psf_fit(
    d: np.ndarray,
    v: np.ndarray,
    bw: float,
    lo: float,
    hi: float,
    levels: tuple[float, float],
    angle_deg: float,
    sigma0: float,
    quant: float = 0.0,
    core: tuple[float, float] | None = None,
) -> EdgeFit | None:
    """Physical ESF model on the trimmed ESF samples, tested against the data.

    * every candidate PSF is fitted and the one chosen by its leave-one-out error, the
      simplest within one standard error of the best (:func:`_select_model`; issue 31: the
      likelihood ratio at p < 0.001 kept a Gaussian for motion-smeared edges);
    * the chosen model must pass the classical lack-of-fit F test: scatter of the bin
      means about the model against the pure error (scatter of the pixels' residuals
      within their bins), so no separate noise estimate is needed.
      ``params["adequate"]`` is p >= 0.001; only then may the model be the primary fit.
    """
    xb, yb, nb = bins(d, v, bw, core)
    idx = bin_index(d, bw, core)
    if xb.size < 12 or d.size - xb.size < 10:
        return None
    dark, bright = levels
    span = bright - dark
    big = 10 * abs(span) + 1
    prob = _Problem(
        d,
        v,
        idx,
        xb,
        yb,
        nb,
        np.sqrt(nb),
        footprint(angle_deg),
        [dark - big, 0.0, lo],
        [bright + big, 3 * big, hi],
        _rounding_variance(v, idx, xb.size, quant),
        _within_bin_spread(d, idx, core),
    )
    s0 = min(max(sigma0, 0.05), 8.0)
    one = prob.fit(
        "gauss", [dark, span, 0.0 if lo < 0 < hi else 0.5 * (lo + hi), s0], [0.02], [10.0]
    )
    if one is None:
        return None
    p = one[0]
    var_pe = prob.pure_error("gauss", p)
    if not var_pe > 0:
        return None
    kind, p, plausible = _select_model(prob, p, var_pe, lo, hi)
    if kind != "gauss":
        var_pe = prob.pure_error(kind, p)
    test = _lack_of_fit(prob, kind, p, var_pe)
    if float(p[1]) <= 0:
        return None
    unc = _uncertainty(prob, kind, p, var_pe, lo, hi, plausible)
    return _model_fit(prob, kind, p, (lo, hi), bw, quant, var_pe, test, unc)


def _rounding_variance(v: np.ndarray, idx: np.ndarray, nbins: int, quant: float) -> np.ndarray:
    """The rounding part of each bin mean's variance, q^2 / 12 for integer DNs (q = 1 DN).

    Where the noise is below the DN step, a bin whose pixels all hold the same DN (a tread of
    the rounding staircase: the far tails of a noise-free edge, where the ESF moves less than
    1 DN over pixels) says only that the ESF lies within +-q/2 of that DN, and its neighbours
    repeat the same rounding error: there it does not average to the q^2 / 12 of a uniform
    spread. Its bound, q^2 / 4, is what a model may be off there (issue 31: the right
    diffraction model failed the lack-of-fit test on noise-free 8-bit edges, p ~ 1e-4 to 1e-8,
    and the smoothing spline, which follows the staircase, was kept: MTF@Ny 0.012 low).
    """
    if quant <= 0:
        return np.zeros(nbins)
    n = np.bincount(idx)  # bins as ``bins`` numbers them: the non-empty ones, in order
    lo = np.full(n.size, np.inf)
    hi = np.full(n.size, -np.inf)
    np.minimum.at(lo, idx, v)
    np.maximum.at(hi, idx, v)
    out = np.where((hi == lo) & (n > 1), quant**2 / 4.0, quant**2 / 12.0)[n > 0]
    if out.size != nbins:
        raise ValueError("bins and bin_index disagree")
    return out


def _within_bin_spread(d: np.ndarray, idx: np.ndarray, core: tuple[float, float] | None) -> float:
    """Mean variance of the samples' distances about their bin's mean distance, over the finely
    binned transition (px^2)."""
    n = np.bincount(idx)
    mean = np.bincount(idx, weights=d) / np.maximum(n, 1)
    sel = (d >= core[0]) & (d <= core[1]) if core is not None else np.ones(d.size, dtype=bool)
    if not sel.any():
        return 0.0
    return float(np.mean((d[sel] - mean[idx[sel]]) ** 2))


def _select_model(
    prob: _Problem, p: np.ndarray, var_pe: float, lo: float, hi: float
) -> tuple[str, np.ndarray, dict[str, np.ndarray]]:
    """The candidate PSF models fitted, and the one their out-of-sample error prefers.

    Candidates: the Gaussian ``p``, Gaussian x box (motion, defocus), core + halo, unsharp-masked
    Gaussian, Gaussian x disk (defocus), the diffraction-limited pupil and a Gaussian sharpened
    by a 3-tap kernel on the pixel grid (MTFC as ground segments apply it: a continuous unsharp
    mask misses its discretisation, 0.003 MTF@Ny at 27 deg, issue 31). Each one's
    out-of-sample error is its leave-one-out error over the ESF bins, exact for a linearised
    least-squares fit (residual / (1 - leverage), the leverage from the Jacobian at the solution;
    no refits). The choice is the simplest model whose error is within one standard error of the
    best one's (the one-SE rule of cross-validation): a richer PSF fitted to a Gaussian edge is
    poorly determined (5 % FWHM scatter at SNR 50 instead of 1 %), so it must predict clearly
    better to be chosen. At equal size a blur-only PSF comes before a sharpened one: sharpening
    is a processing step of the product, which the data must show (a 3-tap kernel was chosen for
    one of three motion-smeared edges at SNR 100 in a near-tie, FWHM within 2 % either way).
    Returns (kind, parameters, every candidate that fitted).

    A component must be seen inside the window: +-2 sigma, the shift and the box in it (a halo
    wider than the window trades off against the levels and spoils the RER).
    """
    a0, b0, c0, g = (float(q) for q in p)
    half = 0.5 * (hi - lo)
    wide = max(half / 2.0, 1.5 * g)
    tried = {
        "gauss-box": prob.fit(
            "gauss-box", [a0, b0, c0, 0.7 * g, 2.0 * g], [0.02, 0.0], [wide, max(half, 3.0 * g)]
        ),
        "gauss2": prob.fit(
            "gauss2",
            [a0, b0, c0, 0.8 * g, min(2.5 * g, wide), 0.8, 0.0],
            [0.02, 0.02, 0.0, -half / 2.0],
            [wide, wide, 1.0, half / 2.0],
        ),
        "gauss-usm": prob.fit(
            "gauss-usm", [a0, b0, c0, g, min(1.5, wide), 0.5], [0.02, 0.3, 0.0], [wide, wide, 5.0]
        ),
        "gauss-disk": prob.fit(
            "gauss-disk", [a0, b0, c0, 0.6 * g, 1.2 * g], [0.2, 0.0], [wide, max(half, 3.0 * g)]
        ),
        "gauss-mtfc": prob.fit("gauss-mtfc", [a0, b0, c0, g, 0.1], [0.02, 0.0], [wide, 2.0]),
        "airy": prob.fit(
            "airy",
            [a0, b0, c0, min(max(0.5 / g, 0.2), 2.5), 0.3 * g, 0.5],
            [0.15, 0.0, 0.0],
            [3.0, wide, max(half, 3.0 * g)],
        ),
    }
    cands = {
        "gauss": p,
        **{k: v[0] for k, v in tried.items() if v is not None and float(v[0][1]) > 0},
    }
    loo = {k: prob.loo(k, q, var_pe) for k, q in cands.items()}
    best = min(loo, key=lambda k: float(loo[k].sum()))
    n = loo[best].size

    def within(k: str) -> bool:
        diff = loo[k] - loo[best]
        return float(diff.sum()) <= float(np.std(diff, ddof=1)) * math.sqrt(n)

    kind = min(
        (k for k in cands if within(k)),
        key=lambda k: (cands[k].size, k in _SHARPENING, float(loo[k].sum())),
    )
    return kind, cands[kind], {k: cands[k] for k in cands if within(k)}


def _lack_of_fit(prob: _Problem, kind: str, p: np.ndarray, var_pe: float) -> _Test:
    """Lack-of-fit F test of the chosen model; the out-of-sample comparison with the spline is
    needed (and paid for) only when the model fails it."""
    dof = (prob.xb.size - p.size, prob.d.size - prob.xb.size)
    f_stat = prob.chi(kind, p, var_pe) / dof[0]
    p_value = float(fdtrc(dof[0], dof[1], f_stat))  # F survival
    cv_model = cv_spline = None
    if p_value < _ADEQUATE_P:
        cv_model, cv_spline = _cv_errors(
            prob.xb, prob.yb, prob.nb, var_pe, prob.qv, kind, p, prob.fp, prob.base_lo, prob.base_hi
        )
    return _Test(f_stat, dof, p_value, cv_model, cv_spline)


@dataclass(frozen=True, eq=False)
class _Curves:
    """A fitted model's normalised ESF (callable), LSF on the grid ``x``, MTF (callable), RER centre."""

    x: np.ndarray
    esf_at: Any
    lsf: np.ndarray
    mtf_at: Any
    centre: float
    comps: list[tuple[float, float, float, float]]


def _deblur(kind: str, p: np.ndarray, vd: float) -> np.ndarray:
    """The parameters without the blur of the binning: a bin mean is the ESF averaged over its
    samples' spread in d (variance ``vd``: bw^2 / 12 for dense sampling, ~0 on a rational
    slope's lattice), i.e. the ESF convolved with it, which adds vd to every Gaussian variance
    (+0.2 % FWHM at sigma 0.45 px with 0.1-px bins, seen on noise-free 12-bit edges)."""
    if vd <= 0:
        return p
    q = p.copy()
    idx = {
        "gauss": [3],
        "gauss-box": [3],
        "gauss2": [3, 4],
        "gauss-usm": [3],
        "gauss-disk": [3],
        "airy": [4],
        "gauss-mtfc": [3],
    }[kind]
    for i in idx:
        q[i] = math.sqrt(max(float(q[i]) ** 2 - vd, 0.25 * float(q[i]) ** 2))
    return q


def _curves(
    kind: str,
    p: np.ndarray,
    fp: tuple[float, float],
    lo: float,
    hi: float,
    step: float = GRID,
    vd: float = 0.0,
) -> _Curves:
    p = _deblur(kind, p, vd)
    a, b_tot, c = float(p[0]), float(p[1]), float(p[2])
    x = np.arange(lo, hi + step / 2, step)

    def esf_at(q: np.ndarray) -> np.ndarray:
        return (_model_esf(kind, np.asarray(q, dtype=float), p, fp) - a) / b_tot

    if kind == "airy":
        comps = [(float(p[4]), 1.0, 0.0, float(p[5]))]
        lsf = pupil.lsf(x - c, float(p[3]), float(p[4]), float(p[5]), fp)

        def mtf_at(f: np.ndarray) -> np.ndarray:
            return np.abs(pupil.transfer(f, float(p[3]), float(p[4]), float(p[5]), fp))
    else:
        comps = sorted(_components(kind, p[3:], fp))
        lsf = np.zeros_like(x)
        for sig, w, shift, box in comps:
            lsf += w * gauss_boxes_lsf(x - c - shift, sig, (*fp, box))

        def mtf_at(f: np.ndarray) -> np.ndarray:
            f = np.asarray(f, dtype=float)
            otf = sum(
                w
                * np.exp(-2.0 * np.pi**2 * sig**2 * f**2 - 2j * np.pi * f * shift)
                * np.sinc(f * box)
                for sig, w, shift, box in comps
            )
            return np.abs(otf) * np.abs(np.sinc(f * fp[0])) * np.abs(np.sinc(f * fp[1]))

    # seed 9d: for a parametric ESF the RER centre is 0.5 on the normalised DN
    centre = c
    if kind == "gauss2":
        try:
            centre = float(brentq(lambda q: float(esf_at(np.array([q]))[0]) - 0.5, lo, hi))
        except ValueError:
            centre = c
    return _Curves(x, esf_at, lsf, mtf_at, centre, comps)


def _figures(
    kind: str, p: np.ndarray, fp: tuple[float, float], lo: float, hi: float, vd: float = 0.0
) -> np.ndarray:
    """(RER, FWHM px, MTF@Nyquist) of a model, on a 0.02-px grid within +-8 px of its centre
    (for the uncertainty's derivatives and the candidates' spread)."""
    c = float(p[2])
    cv = _curves(kind, p, fp, max(lo, c - 8.0), min(hi, c + 8.0), step=0.02, vd=vd)
    e = cv.esf_at(np.array([cv.centre - 0.5, cv.centre + 0.5]))
    return np.array(
        [float(e[1] - e[0]), fwhm_of(cv.x, cv.lsf), float(cv.mtf_at(np.array([NYQUIST]))[0])]
    )


def _uncertainty(
    prob: _Problem,
    kind: str,
    p: np.ndarray,
    var_pe: float,
    lo: float,
    hi: float,
    plausible: dict[str, np.ndarray],
) -> dict[str, Any]:
    """Standard uncertainties of RER, FWHM and MTF@Ny of the chosen model (issue 31).

    * noise: the delta method, u^2 = g C g', C the parameters' covariance of the weighted fit
      (bin variance var / n + q^2 / 12, scaled up by chi2 / dof when the model does not fit to
      the noise), g the figures' derivatives by central differences;
    * model: the largest difference between the chosen model's figures and those of every other
      candidate whose out-of-sample error was within one standard error of the best (models
      the data cannot tell apart).
    Both are combined in quadrature; the parts are kept for the report.
    """
    fp = prob.fp
    vd = prob.vd
    base = _figures(kind, p, fp, lo, hi, vd)
    var_b = var_pe / prob.nb + prob.qv
    jac = _model_jac(kind, prob.xb, p, fp) / np.sqrt(var_b)[:, None]
    r = (_model_esf(kind, prob.xb, p, fp) - prob.yb) / np.sqrt(var_b)
    dof = max(prob.xb.size - p.size, 1)
    scale = max(1.0, float(r @ r) / dof)
    try:
        cov = np.linalg.pinv(jac.T @ jac) * scale
    except np.linalg.LinAlgError:
        cov = np.full((p.size, p.size), np.nan)
    grad = np.zeros((3, p.size))
    for k in range(p.size):
        h = 1e-4 * max(abs(float(p[k])), 1e-2) if k != 2 else 1e-4
        up, dn = p.copy(), p.copy()
        up[k] += h
        dn[k] -= h
        grad[:, k] = (_figures(kind, up, fp, lo, hi, vd) - _figures(kind, dn, fp, lo, hi, vd)) / (
            2 * h
        )
    u_noise = np.sqrt(np.maximum(np.einsum("ik,kl,il->i", grad, cov, grad), 0.0))
    others = {k: _figures(k, q, fp, lo, hi, vd) for k, q in plausible.items() if k != kind}
    u_model = np.zeros(3)
    for fig in others.values():
        u_model = np.maximum(u_model, np.abs(np.nan_to_num(fig - base, nan=0.0)))
    total = np.hypot(u_noise, u_model)
    names = ("rer", "fwhm_px", "mtf_nyquist")
    return {
        "u": dict(zip(names, map(float, total), strict=True)),
        "u_noise": dict(zip(names, map(float, u_noise), strict=True)),
        "u_model": dict(zip(names, map(float, u_model), strict=True)),
        "candidates": {
            k: dict(zip(names, map(float, v), strict=True))
            for k, v in {kind: base, **others}.items()
        },
    }


def _model_fit(
    prob: _Problem,
    kind: str,
    p: np.ndarray,
    window: tuple[float, float],
    bw: float,
    quant: float,
    var_pe: float,
    test: _Test,
    unc: dict[str, Any],
) -> EdgeFit:
    """The chosen model as an :class:`EdgeFit`: its exact ESF, LSF and MTF (no FFT of a window)."""
    lo, hi = window
    fp = prob.fp
    a, b_tot = float(p[0]), float(p[1])
    cv = _curves(kind, p, fp, lo, hi, vd=prob.vd)
    comps = cv.comps
    return make_fit(
        kind,
        cv.x,
        cv.esf_at(cv.x),
        cv.lsf,
        cv.centre,
        cv.esf_at,
        (a, a + b_tot),
        {
            "model": _MODEL_TEXT[kind],
            "sigma_px": [q[0] for q in comps],
            "weights": [q[1] for q in comps],
            "shift_px": [q[2] for q in comps],
            "box_px": [q[3] for q in comps],
            **({"disk_radius_px": float(p[4])} if kind == "gauss-disk" else {}),
            **(
                {"usm_amount": float(p[5]), "usm_sigma_px": float(p[4])}
                if kind == "gauss-usm"
                else {}
            ),
            **({"mtfc_amount": float(p[4])} if kind == "gauss-mtfc" else {}),
            **(
                {"cutoff_cy_px": float(p[3]), "jitter_px": float(p[4]), "smear_px": float(p[5])}
                if kind == "airy"
                else {}
            ),
            "footprint_px": list(fp),
            "bin_px": bw,
            "noise_dn": math.sqrt(var_pe),
            "lack_of_fit_f": test.f_stat,
            "dof": list(test.dof),
            "p_value": test.p_value,
            "adequate": test.p_value >= _ADEQUATE_P,
            "quantisation_dn": quant,
            "cv_error_model": test.cv_model,
            "cv_error_spline": test.cv_spline,
            "selection": "leave-one-out error over the ESF bins, simplest model within one SE",
            **unc,
        },
        mtf_at=cv.mtf_at,
    )


_CV_FOLDS = 5


def _cv_errors(
    xb: np.ndarray,
    yb: np.ndarray,
    nb: np.ndarray,
    var_pe: float,
    qv: np.ndarray,
    kind: str,
    p: np.ndarray,
    fp: tuple[float, float],
    base_lo: list[float],
    base_hi: list[float],
) -> tuple[float, float]:
    """Out-of-sample error of the PSF model and of the GCV spline: 5-fold cross-validation
    over the ESF bins (bin k in fold k mod 5), each held-out bin's squared error divided by
    its quantisation-aware variance var_pe / n + q^2 / 12, mean over bins.

    Why: the lack-of-fit test only says whether the model is *exactly* right; what the
    choice needs is which fit predicts the ESF better where it was not fitted. A model
    slightly outside its family (a sharpened or defocused edge at low SNR) can still beat
    the noisier spline, and a spline that follows quantisation steps loses to the model.
    """
    var_b = var_pe / nb + qv
    sw = np.sqrt(nb)
    lo_b = np.concatenate([base_lo, np.full(p.size - 3, -np.inf)])
    hi_b = np.concatenate([base_hi, np.full(p.size - 3, np.inf)])
    lo_b[3:] = np.minimum(p[3:], 0.0) - np.abs(p[3:]) - 1.0
    hi_b[3:] = np.abs(p[3:]) * 3.0 + 1.0
    lo_b[3:] = np.where(kind == "gauss2", lo_b[3:], np.maximum(lo_b[3:], 0.0))
    lo_b[3] = max(lo_b[3], 0.02)  # the first width (sigma, or the pupil's cut-off): 0 divides by 0
    err_m = np.zeros(xb.size)
    err_s = np.zeros(xb.size)
    fold = np.arange(xb.size) % _CV_FOLDS
    for k in range(_CV_FOLDS):
        tr, te = fold != k, fold == k
        xt, yt, wt = xb[tr], yb[tr], sw[tr]

        def resid(
            q: np.ndarray, xt: np.ndarray = xt, yt: np.ndarray = yt, wt: np.ndarray = wt
        ) -> np.ndarray:
            return (_model_esf(kind, xt, q, fp) - yt) * wt

        try:
            res = least_squares(
                resid, np.clip(p, lo_b, hi_b), bounds=(lo_b, hi_b), x_scale="jac", max_nfev=100
            )
            err_m[te] = (_model_esf(kind, xb[te], res.x, fp) - yb[te]) ** 2
        except (ValueError, np.linalg.LinAlgError):
            err_m[te] = np.inf
        try:
            spl = make_smoothing_spline(xb[tr], yb[tr], w=nb[tr])
            err_s[te] = (spl(xb[te]) - yb[te]) ** 2
        except (ValueError, np.linalg.LinAlgError):
            err_s[te] = np.inf
    # the end bins cannot be predicted by a spline (extrapolation): score the inner bins
    inner = slice(_CV_FOLDS, xb.size - _CV_FOLDS)
    return (
        float(np.mean(err_m[inner] / var_b[inner])),
        float(np.mean(err_s[inner] / var_b[inner])),
    )
