"""Seed steps 4-5: the working frame and the edge line.

Step 4 turns the ROI so that the edge runs near the columns (profile along x) and dark is on
the left; every later step runs in that frame, so results do not depend on edge polarity or
on transposing the image. Step 5 finds the edge on every line (largest difference, cubic,
inflection), fits a robust straight line through those locations and (added) refines it by
one Fermi-Dirac edge over all pixels near it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .fits import logistic
from .numfit import least_squares


@dataclass(frozen=True, eq=False)
class Frame:
    """Step 4: the ROI in the working frame (edge ~ vertical, dark left) and how it got there."""

    work: np.ndarray
    transposed: bool  # 4a: the edge ran along the rows (profile along y)
    mirrored: bool  # 4b: bright was on the left

    @property
    def direction(self) -> str:
        return "along" if self.transposed else "across"

    @property
    def polarity(self) -> str:
        return "bright_to_dark" if self.mirrored else "dark_to_bright"

    def to_roi(self, r: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Working (row, col) -> ROI (x, y)."""
        cc = (self.work.shape[1] - 1) - c if self.mirrored else c
        return (r, cc) if self.transposed else (cc, r)


def orient(img: np.ndarray) -> Frame:
    """Step 4a: along/across by the larger gradient energy; 4b: dark/bright side by the sign
    of the summed column differences."""
    ex = np.nansum(np.diff(img, axis=1) ** 2)
    ey = np.nansum(np.diff(img, axis=0) ** 2)
    transposed = bool(ey > ex)
    work = img.T if transposed else img
    mirrored = bool(np.nansum(np.diff(work, axis=1)) < 0)
    if mirrored:
        work = work[:, ::-1]
    return Frame(np.ascontiguousarray(work), transposed, mirrored)


@dataclass(frozen=True, eq=False)
class EdgeLine:
    """Step 5: per-line edge locations (working frame) and the line x = c0 + c1 * row."""

    rows: np.ndarray  # lines with a detected edge
    locs: np.ndarray  # sub-pixel column of the edge on each of them
    kept: np.ndarray  # not rejected as an outlier
    c0: float
    c1: float
    residual_rms_px: float  # of the kept lines about the (unrefined) robust line
    max_residual_px: float  # straightness: largest 5-line running median of the residuals
    ok: bool  # at least 3 kept lines and a finite slope

    @property
    def n_kept(self) -> int:
        return int(self.kept.sum())

    @property
    def theta(self) -> float:
        """Edge angle to the columns in radians (NaN without a line)."""
        return math.atan(self.c1) if self.ok else math.nan

    @property
    def angle_deg(self) -> float | None:
        """Step 5f: |angle| to the along/across direction, deg."""
        return abs(math.degrees(self.theta)) if self.ok else None

    def fitted_cols(self) -> np.ndarray:
        """The fitted line's column at every detected line (NaN without a line)."""
        return self.c0 + self.c1 * self.rows if self.ok else np.full(self.rows.size, np.nan)


def locate_line(work: np.ndarray, *, refine: bool) -> EdgeLine:
    """Step 5a-f: per-line locations, robust line, straightness; 5g (added): refinement."""
    rows, locs = _line_locations(work)
    kept = np.zeros(rows.size, dtype=bool)
    c0 = c1 = math.nan
    resid_rms = math.nan
    max_resid = math.nan
    if rows.size >= 3:
        c0, c1, kept = _robust_line(rows.astype(float), locs)
        res = locs[kept] - (c0 + c1 * rows[kept])
        resid_rms = float(np.sqrt(np.mean(res**2)))
        max_resid = _straightness(res)
    ok = int(kept.sum()) >= 3 and math.isfinite(c1)
    if ok and refine:
        c0, c1 = _refine_line(work, rows[kept], c0, c1)
    return EdgeLine(rows, locs, kept, c0, c1, resid_rms, max_resid, ok)


_CUBIC = np.linalg.inv(np.vander(np.array([-1.0, 0.0, 1.0, 2.0]), 4))


def _line_locations(work: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seed 5a-c per line: largest adjacent difference, cubic through the 4 pixels
    around it (t = -1, 0, 1, 2 from its left pixel), edge at the inflection -b / 3a."""
    nrow, ncol = work.shape
    diff = np.diff(work, axis=1)
    diff = np.where(np.isfinite(diff), diff, -np.inf)
    k = np.argmax(diff, axis=1)
    rows = np.arange(nrow)
    ok = (k >= 1) & (k + 2 <= ncol - 1) & (diff[rows, k] > 0)
    rows, k = rows[ok], k[ok]
    vals = work[rows[:, None], k[:, None] + np.arange(-1, 3)[None, :]]
    fin = np.isfinite(vals).all(axis=1)
    rows, k, vals = rows[fin], k[fin], vals[fin]
    coef = vals @ _CUBIC.T  # a t^3 + b t^2 + c t + d
    a, b = coef[:, 0], coef[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(np.abs(a) > 1e-12 * np.abs(vals).max(axis=1, initial=1.0),
                     -b / (3.0 * a), 0.5)
    good = (t >= -1.0) & (t <= 2.0)
    return rows[good], k[good] + t[good]


def _robust_line(r: np.ndarray, x: np.ndarray) -> tuple[float, float, np.ndarray]:
    """x = c0 + c1 r by least squares, rejecting |residual| > 3 * max(1.4826 MAD, 0.05 px)
    until the kept set no longer changes."""
    kept = np.ones(r.size, dtype=bool)
    c1, c0 = np.polyfit(r, x, 1)
    for _ in range(30):
        res = x - (c0 + c1 * r)
        sig = 1.4826 * np.median(np.abs(res[kept] - np.median(res[kept])))
        new = np.abs(res) <= 3.0 * max(float(sig), 0.05)
        if new.sum() < 3 or np.array_equal(new, kept):
            break
        kept = new
        c1, c0 = np.polyfit(r[kept], x[kept], 1)
    return float(c0), float(c1), kept


def _straightness(res: np.ndarray, window: int = 5) -> float:
    """Largest deviation of the edge from the fitted line, as a running median over
    ``window`` consecutive kept lines (so per-line noise does not count as bending)."""
    if res.size < window:
        return float(np.max(np.abs(res)))
    runs = np.median(np.lib.stride_tricks.sliding_window_view(res, window), axis=1)
    return float(np.max(np.abs(runs)))


def _refine_line(work: np.ndarray, rows: np.ndarray, c0: float, c1: float,
                 half: float = 5.0) -> tuple[float, float]:
    """Fit v = a + b / (1 + exp(-d / s)), d = (x - c0 - c1 y) cos(atan c1), to every finite
    pixel of the kept lines within ``half`` px of the line; return the refined (c0, c1).

    All pixels of the transition constrain the line, not only the four around each line's
    largest difference, which matters for blurred, noisy edges. The ESF shape is the same
    along the edge, so a symmetric model does not bias the slope. Falls back to the
    step-5 line if the fit fails or moves it by more than 1 px.
    """
    cols = np.arange(work.shape[1], dtype=float)
    r = rows.astype(float)[:, None]
    x = np.broadcast_to(cols[None, :], (rows.size, cols.size))
    v = work[rows, :]
    near = np.isfinite(v) & (np.abs(x - (c0 + c1 * r)) <= half)
    if near.sum() < 20:
        return c0, c1
    xs, ys, vs = x[near], np.broadcast_to(r, x.shape)[near], v[near]
    lo, hi = float(np.percentile(vs, 5)), float(np.percentile(vs, 95))
    if not hi > lo:
        return c0, c1
    ym = float(ys.mean())

    def resid(p: np.ndarray) -> np.ndarray:
        k0, k1, a, b, s = p
        d = (xs - k0 - k1 * (ys - ym)) / math.sqrt(1.0 + k1 * k1)
        return a + b * logistic(d / s) - vs

    def jac(p: np.ndarray) -> np.ndarray:
        k0, k1, _, b, s = p
        q = 1.0 + k1 * k1
        d = (xs - k0 - k1 * (ys - ym)) / math.sqrt(q)
        lg = logistic(d / s)
        dz = b * lg * (1.0 - lg) / s  # d resid / d d
        return np.column_stack([-dz / math.sqrt(q), dz * (-(ys - ym) / math.sqrt(q) - d * k1 / q),
                                np.ones_like(d), lg, -dz * d / s])

    p0 = np.array([c0 + c1 * ym, c1, lo, hi - lo, 0.5])
    try:
        res = least_squares(
            resid, p0, jac=jac, x_scale=np.array([1.0, 0.01, hi - lo, hi - lo, 0.5]), max_nfev=200
        )
    except (ValueError, np.linalg.LinAlgError):
        return c0, c1
    k0, k1 = float(res.x[0]), float(res.x[1])
    new0 = k0 - k1 * ym
    span = float(ys.max() - ys.min())
    moved = max(abs(new0 - c0 + (k1 - c1) * y) for y in (ys.min(), ys.max()))
    if not (
        res.status > 0 and np.all(np.isfinite(res.x)) and res.x[4] > 0 and moved <= 1.0 and span > 0
    ):
        return c0, c1
    return new0, k1
