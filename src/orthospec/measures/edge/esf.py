"""Seed steps 6-7: the ESF samples, their bins, and the uniform dark and bright areas.

Step 6 places every pixel of the kept lines at its *perpendicular* distance
``d = (x - x_edge(y)) cos(theta)`` from the fitted line. Step 7 finds the plateau starts as
the LSF's inflection points on a first smoothing-spline fit, the uniform areas beyond them,
the trimmed window the fits use, and the dark/bright levels and noise of the uniform areas.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .bins import coverage, sampling_gap, smoothing_spline
from .locate import EdgeLine
from .result import GRID

_NAN2 = (math.nan, math.nan)


@dataclass(frozen=True, eq=False)
class EsfSamples:
    """Step 6: pixel samples sorted by perpendicular distance (px, dark < 0 < bright)."""

    d: np.ndarray
    v: np.ndarray  # DN
    row_dmin: np.ndarray  # per kept line: nearest and farthest finite pixel (plateau widths)
    row_dmax: np.ndarray


def esf_samples(work: np.ndarray, line: EdgeLine) -> EsfSamples:
    """Step 6a-c: every finite pixel of the kept lines at its perpendicular distance."""
    if not line.ok:
        return EsfSamples(np.empty(0), np.empty(0), np.empty(0), np.empty(0))
    kr = line.rows[line.kept]
    cols = np.arange(work.shape[1], dtype=float)
    dd = (cols[None, :] - (line.c0 + line.c1 * kr[:, None])) * math.cos(line.theta)
    vv = work[kr, :]
    fin = np.isfinite(vv)
    d, v = dd[fin], vv[fin]
    row_dmin = np.where(fin, dd, np.inf).min(axis=1)
    row_dmax = np.where(fin, dd, -np.inf).max(axis=1)
    order = np.argsort(d, kind="stable")
    return EsfSamples(d[order], v[order], row_dmin, row_dmax)


@dataclass(frozen=True, eq=False)
class Areas:
    """Step 7: plateau starts, the trimmed window, and the uniform areas' statistics (NaN when
    not found)."""

    coverage: float = math.nan  # share of ESF bins within +-2 px holding samples
    gap: float = math.nan  # largest step between ESF sample positions within +-2 px, px
    dark_start: float = math.nan
    bright_start: float = math.nan
    window: tuple[float, float] | None = None  # trimmed ESF (lo, hi) px
    levels: tuple[float, float] = _NAN2  # dark, bright DN
    stds: tuple[float, float] = _NAN2
    saturated: float = math.nan  # largest share of a side's pixels at a saturation level
    widths: tuple[float, float] = _NAN2  # median dark / bright width beyond the starts, px
    uniform: np.ndarray | None = None  # samples in the uniform areas inside the window
    core: tuple[float, float] | None = None  # the transition (finely binned): uniform areas' starts

    @property
    def fittable(self) -> bool:
        """The step-8 fits need a window and ordered, finite levels."""
        lv = self.levels
        return self.window is not None and all(math.isfinite(x) for x in lv) and lv[1] > lv[0]


def uniform_areas(s: EsfSamples, bw: float, plateau_px: float,
                  sat: tuple[float | None, float | None]) -> Areas:
    """Step 7a-c on the ESF samples ``s`` binned at ``bw`` px; ``sat`` the saturation levels."""
    d, v = s.d, s.v
    if d.size < 20:
        return Areas()
    cover = coverage(d, bw, 2.0)
    gap = sampling_gap(d, 2.0)
    first = smoothing_spline(d, v, bw, -12.0, 12.0, core=(-4.0, 4.0))
    if first is None:
        return Areas(cover, gap)
    dark_start, bright_start = _plateau_starts(first, d)
    if not (math.isfinite(dark_start) and math.isfinite(bright_start)):
        return Areas(cover, gap, dark_start, bright_start)
    dark_edge, bright_edge, lo, hi = _trim(first, d, v, dark_start, bright_start, plateau_px)
    dark_side = d <= dark_edge
    bright_side = d >= bright_edge
    dsel = dark_side & (d >= lo)
    bsel = bright_side & (d <= hi)
    levels = stds = _NAN2
    sat_frac = math.nan
    if dsel.any() and bsel.any():
        levels = (float(v[dsel].mean()), float(v[bsel].mean()))
    if dark_side.sum() > 1 and bright_side.sum() > 1:
        stds = (float(v[dark_side].std(ddof=1)), float(v[bright_side].std(ddof=1)))
        sat_frac = max(saturated(v[dark_side], *sat), saturated(v[bright_side], *sat))
    widths = (
        float(np.median(dark_start - s.row_dmin)),
        float(np.median(s.row_dmax - bright_start)),
    )
    return Areas(
        cover,
        gap,
        dark_start,
        bright_start,
        (lo, hi),
        levels,
        stds,
        sat_frac,
        widths,
        dsel | bsel,
        (dark_edge - 1.0, bright_edge + 1.0),
    )


def _trim(
    first: Any,
    d: np.ndarray,
    v: np.ndarray,
    dark_start: float,
    bright_start: float,
    plateau_px: float,
) -> tuple[float, float, float, float]:
    """Step 7b-c: where the uniform areas begin (dark_edge, bright_edge) and the trimmed window.

    The uniform areas begin at 3x the start's distance from the centre (>= 1 px beyond it; at
    the LSF inflection a Gaussian's ESF tail still holds ~16 % of the step, at 3 sigma 0.1 %),
    or further out where the LSF has a long tail (below 2 % of its peak only there). The trim
    keeps at least ``plateau_px`` beyond each start, at least 4x the start's distance from the
    centre, and 1 px of uniform area (tails not cut).
    """
    centre = 0.5 * (dark_start + bright_start)
    tail_d, tail_b = _tail_ends(first, d, dark_start, bright_start)
    dark_edge = centre + min(3.0 * (dark_start - centre), dark_start - centre - 1.0)
    bright_edge = centre + max(3.0 * (bright_start - centre), bright_start - centre + 1.0)
    if math.isfinite(tail_d):
        dark_edge = min(dark_edge, tail_d)
    if math.isfinite(tail_b):
        bright_edge = max(bright_edge, tail_b)
    lo = max(
        min(dark_start - plateau_px, centre + 4.0 * (dark_start - centre), dark_edge - 1.0),
        float(d[0]),
    )
    hi = min(
        max(bright_start + plateau_px, centre + 4.0 * (bright_start - centre), bright_edge + 1.0),
        float(d[-1]),
    )
    # issue 31: the window grows with the PSF's measured extent: twice the distance out to which
    # the ESF still differs from the far plateau by more than the noise allows (a halo or a
    # diffraction tail below 2 % of the LSF's peak still holds 1-2 % of the step beyond 4 px,
    # and the levels must come from beyond it: RER +0.02 else)
    ext_d, ext_b = _tail_extent(d, v, centre)
    lo = min(lo, max(centre - 2.0 * ext_d - 1.0, float(d[0])))
    hi = max(hi, min(centre + 2.0 * ext_b + 1.0, float(d[-1])))
    dark_edge = min(dark_edge, centre - ext_d)
    bright_edge = max(bright_edge, centre + ext_b)
    return dark_edge, bright_edge, lo, hi


_TAIL_TOL = 0.005  # of the step: an ESF this close to its far plateau is in the uniform area


def _tail_extent(
    d: np.ndarray, v: np.ndarray, centre: float, bw: float = 0.5
) -> tuple[float, float]:
    """Distances (px) from the centre beyond which the ESF, binned at ``bw`` and smoothed over
    three bins, stays within max(0.5 % of the step, 3 standard errors) of its far plateau (the
    median of the outer quarter of each side); 0 when it settles at once."""
    idx = np.floor((d - centre) / bw).astype(np.int64)
    idx -= idx.min()
    n = np.bincount(idx)
    ok = n > 0
    x = (np.flatnonzero(ok) + 0.5) * bw + (float(d[0]) - centre) // bw * bw
    y = np.bincount(idx, weights=v)[ok] / n[ok]
    cnt = n[ok]
    if x.size < 12:
        return 0.0, 0.0
    ys = np.convolve(np.pad(y, 1, mode="edge"), np.ones(3) / 3.0, mode="valid")
    out: list[Any] = []
    for side in (x < 0, x > 0):
        xs, vals, cs = x[side], ys[side], cnt[side]
        if xs.size < 8:
            out.append(0.0)
            continue
        far = np.argsort(np.abs(xs))[-max(xs.size // 4, 2) :]
        level = float(np.median(vals[far]))
        spread = 1.4826 * float(np.median(np.abs(y[side][far] - np.median(y[side][far]))))
        out.append((xs, vals, cs, level, spread))
    if any(isinstance(o, float) for o in out):
        return 0.0, 0.0
    step = abs(out[1][3] - out[0][3])
    ext = []
    for xs, vals, cs, level, spread in out:
        tol = np.maximum(
            _TAIL_TOL * step, 3.0 * spread / np.sqrt(3.0) * np.sqrt(np.median(cs) / cs)
        )
        order = np.argsort(np.abs(xs))  # outward from the edge
        off = (np.abs(vals - level) > tol)[order]
        # settled: the first place from where 2 px (4 bins) in a row are within tolerance, so
        # that a noise excursion far out does not count as tail
        run = np.convolve(~off, np.ones(_SETTLE), mode="valid") == _SETTLE
        first = int(np.argmax(run)) if run.any() else off.size - 1
        ext.append(float(np.abs(xs[order][first])) if off[: first + 1].any() else 0.0)
    return ext[0], ext[1]


_SETTLE = 4  # bins of 0.5 px


_TAIL = 0.02  # the uniform areas begin where the LSF is below 2 % of its peak


def _plateau_starts(spl: Any, d: np.ndarray) -> tuple[float, float]:
    """Seed 7a: LSF inflection points (extrema of ESF'') either side of the LSF peak."""
    lo, hi = max(float(d[0]), -12.0), min(float(d[-1]), 12.0)
    x = np.arange(lo, hi + GRID / 2, GRID)
    lsf = spl.derivative(1)(x)
    near = np.abs(x) <= 3.0
    if not near.any():
        return math.nan, math.nan
    ip = int(np.flatnonzero(near)[np.argmax(lsf[near])])
    peak = x[ip]
    d2 = spl.derivative(2)(x)
    left = (x >= peak - 6.0) & (x < peak)
    right = (x > peak) & (x <= peak + 6.0)
    if not left.any() or not right.any():
        return math.nan, math.nan
    return float(x[left][np.argmax(d2[left])]), float(x[right][np.argmin(d2[right])])


def _tail_ends(
    spl: Any, d: np.ndarray, dark_start: float, bright_start: float, frac: float = _TAIL
) -> tuple[float, float]:
    """First points beyond the plateau starts where the first-pass LSF falls below ``frac``
    of its peak (NaN if it never does within the data / 12 px)."""
    lo, hi = max(float(d[0]), -12.0), min(float(d[-1]), 12.0)
    x = np.arange(lo, hi + GRID / 2, GRID)
    lsf = spl.derivative(1)(x)
    between = (x >= dark_start) & (x <= bright_start)
    if not between.any():
        return math.nan, math.nan
    thr = frac * float(lsf[between].max())
    left = np.flatnonzero((x < dark_start) & (lsf < thr))
    right = np.flatnonzero((x > bright_start) & (lsf < thr))
    # a sharpened edge rings: a negative LSF lobe (over/undershoot) right after the
    # transition is part of the edge response, not of the uniform area
    reach = round(3.0 / GRID)
    tail_b = math.nan
    if right.size:
        i = int(right[0])
        neg = np.flatnonzero(lsf[i : i + reach] < -thr)
        if neg.size:
            j = i + int(neg[0])
            while j + 1 < x.size and lsf[j + 1] < -thr:
                j += 1
            i = j + 1 if j + 1 < x.size else j
        tail_b = float(x[i])
    tail_d = math.nan
    if left.size:
        i = int(left[-1])
        neg = np.flatnonzero(lsf[max(i - reach, 0) : i + 1][::-1] < -thr)
        if neg.size:
            j = i - int(neg[0])
            while j - 1 >= 0 and lsf[j - 1] < -thr:
                j -= 1
            i = j - 1 if j > 0 else j
        tail_d = float(x[i])
    return tail_d, tail_b


def saturation_levels(
    dtype: np.dtype, bit_depth: int | None, given: tuple[float | None, float | None] | None
) -> tuple[float | None, float | None]:
    """Saturation levels (low, high) in DN: ``given``, else 0 and 2**bit_depth - 1, or the
    integer dtype's range (0 low for unsigned data: zero fill counts as saturated)."""
    if given is not None:
        return given
    hi: float | None = None
    if bit_depth is not None:
        hi = float(2**bit_depth - 1)
    elif np.issubdtype(dtype, np.integer):
        hi = float(np.iinfo(dtype).max)
    lo = 0.0 if (bit_depth is not None or np.issubdtype(dtype, np.unsignedinteger)) else None
    return lo, hi


def saturated(vals: np.ndarray, lo: float | None, hi: float | None) -> float:
    """Share of one side's pixels at (or beyond) a saturation level."""
    sat = np.zeros(vals.size, dtype=bool)
    if lo is not None:
        sat |= vals <= lo
    if hi is not None:
        sat |= vals >= hi
    return float(sat.mean()) if vals.size else math.nan
