"""The binned, super-sampled ESF and its smoothing spline (used by steps 7 and 8).

Bins are ``bw`` px wide and centred on multiples of ``bw`` (symmetric about the edge); the
spline is the GCV cubic smoothing spline (scipy's criterion, :mod:`.numfit`) of the bin means weighted by their counts.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .numfit import make_smoothing_spline


def within_bin_std(d: np.ndarray, v: np.ndarray, bw: float) -> float:
    """Pooled scatter of the pixels about their ESF-bin means: the noise the ESF fit sees
    (local to the edge, unlike the whole-side std of the SNR check)."""
    if d.size < 3:
        return math.nan
    idx = bin_index(d, bw)
    n = np.bincount(idx)
    mean = np.bincount(idx, weights=v) / np.maximum(n, 1)
    dof = int(d.size - np.count_nonzero(n))
    if dof < 2:
        return math.nan
    return float(np.sqrt(np.sum((v - mean[idx]) ** 2) / dof))


Core = tuple[float, float] | None
COARSE = 5  # outside the core, bins are COARSE x bw wide


def bin_index(d: np.ndarray, bw: float, core: Core = None) -> np.ndarray:
    """Bins of ``bw`` px centred on multiples of bw (symmetric about 0), counted from 0.

    With ``core`` (lo, hi) px, only the transition is binned finely: beyond it (the uniform
    areas, where the ESF is flat) every COARSE fine bins form one (issue 31: the window reaches
    20 px and more, and the GCV spline's cost grows with the number of bins)."""
    idx = np.floor(d / bw + 0.5).astype(np.int64)
    if core is not None:
        k_lo, k_hi = (int(np.floor(c / bw + 0.5)) for c in core)
        lab = idx.copy()
        left, right = idx < k_lo, idx > k_hi
        lab[left] = k_lo - COARSE * ((k_lo - idx[left] + COARSE - 1) // COARSE)
        lab[right] = k_hi + COARSE * ((idx[right] - k_hi + COARSE - 1) // COARSE)
        return np.unique(lab, return_inverse=True)[1].astype(np.int64)
    return idx - idx.min()


def bins(
    d: np.ndarray, v: np.ndarray, bw: float, core: Core = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bin the ESF at ``bw`` px: mean distance, mean value and count of each non-empty bin."""
    idx = bin_index(d, bw, core)
    n = np.bincount(idx)
    sd = np.bincount(idx, weights=d)
    sv = np.bincount(idx, weights=v)
    nz = n > 0
    return sd[nz] / n[nz], sv[nz] / n[nz], n[nz].astype(float)


def coverage(d: np.ndarray, bw: float, half: float) -> float:
    """Share of bins within +-half px of the edge that hold at least one sample."""
    sel = np.abs(d) <= half
    nb = round(2 * half / bw) + 1
    if not sel.any():
        return 0.0
    idx = np.floor(d[sel] / bw + 0.5).astype(np.int64)
    return float(np.unique(idx).size / nb)


def sampling_gap(d: np.ndarray, half: float) -> float:
    """Largest distance (px) between neighbouring ESF sample positions within +-half px of the
    edge: the coarsest step at which the slanted edge samples its ESF there (issue 31).

    An edge at 0 deg samples every line at the same phases (gap 1 px); a slope p/q (q lines
    repeat the pattern) gives the lattice cos(theta) / q, and a slope near it fills the gaps
    in proportion to the lines and the mismatch. The positions are those of the fitted line, so
    the gap is measured, not inferred from the angle."""
    sel = d[(d >= -half) & (d <= half)]
    if sel.size < 2:
        return math.inf
    ends = np.concatenate([[-half], np.sort(sel), [half]])
    return float(np.max(np.diff(ends)))


_CHI2_TRIGGER = 0.1  # GCV fits below this interpolate noise (seen: 0.07; normal: 0.2-1)
_CHI2_TARGET = 0.4  # where such a fit is moved to (typical chi2 / bins of good fits)


def smoothing_spline(
    d: np.ndarray,
    v: np.ndarray,
    bw: float,
    lo: float,
    hi: float,
    noise: float = math.nan,
    core: Core = None,
) -> Any:
    """GCV cubic smoothing spline of the binned ESF (weights = samples per bin).

    Guard against GCV's known occasional gross under-smoothing: with the pixel ``noise``
    known (scatter within plateau bins), a GCV fit that leaves less than 0.1 of the
    expected noise variance in the residuals (chi2 / bins < 0.1) is interpolating noise;
    lambda is then raised (bisection in log lambda) to chi2 / bins = 0.4, the level of
    good fits. The trigger is low on purpose: on real targets the plateau scatter also
    holds panel texture, which overstates the noise near the edge.
    """
    sel = (d >= lo) & (d <= hi)
    if sel.sum() < 10:
        return None
    xb, yb, nb = bins(d[sel], v[sel], bw, core)
    if xb.size < 6:
        return None
    try:
        spl = make_smoothing_spline(xb, yb, w=nb)
        if not (math.isfinite(noise) and noise > 0):
            return spl

        def chi2(s: Any) -> float:
            return float(np.sum(nb * (yb - s(xb)) ** 2) / noise**2 / xb.size)

        if chi2(spl) >= _CHI2_TRIGGER:
            return spl
        lo_l, hi_l = -12.0, 4.0  # log10 lambda
        best = spl
        for _ in range(30):
            mid = 0.5 * (lo_l + hi_l)
            cand = make_smoothing_spline(xb, yb, w=nb, lam=10.0**mid)
            if chi2(cand) < _CHI2_TARGET:
                lo_l = mid
            else:
                hi_l, best = mid, cand
            if hi_l - lo_l < 0.02:
                break
        return best
    except (ValueError, np.linalg.LinAlgError):
        return None
