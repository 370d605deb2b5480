"""Check points as independent measurements (JRC §12.5-§12.6): repeats, GCPs, zero residuals.

JRC §12.5 assesses conformance "using independent measurements of image accuracy (i.e. not the
GCPs used for correction)" and asks that "CPs should not be close to the GCPs"; §12.6 has the
operator identify "the location of each checkpoint on the image" and enter it beside the 'true'
coordinate. A point that fails one of these is not a measurement of the image's accuracy: it is
the checker's to replace, and the block statistics are computed without it.

*How close is "the same point"?* Two reference positions nearer than :func:`separation` cannot
be told apart on an image that meets its tolerance: the image may place either feature anywhere
within about one tolerable RMSE, and a feature pointed on the image is uncertain by about a pixel
(2 px = the width of a well-defined point). So ``separation = max(k_tol x tolerance, k_px x GSD)``
(by default max(1 x tolerance, 2 px)): a copy of a good point shifted by a few millimetres, or a
GCP entered as a check point a centimetre away, is caught; two well-defined points a few metres
apart are not.

Pure numpy/scipy: arrays in, arrays out, no I/O. Memory stays a few arrays per point whatever
the layout (no pair list: a hostile cluster of a million points at one position would make
billions of pairs).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["MIN_SEPARATION", "nearest_gcp", "repeated_positions", "separation", "zero_residuals"]

#: the smallest separation used whatever the tolerance and GSD (1 mm): coordinates are given to it
MIN_SEPARATION = 0.001
#: |residual| below this on both axes is "zero" (metres: unit conversions leave ~1e-10)
ZERO = 1e-6


def separation(tolerance: float | None, gsd: float | None, *, tolerance_factor: float = 1.0,
               gsd_px: float = 2.0) -> float:
    """Distance below which two positions are one point: ``max(tolerance_factor x tolerance,
    gsd_px x GSD, 1 mm)`` (lengths in metres; an unknown tolerance or GSD drops its term)."""
    terms = [MIN_SEPARATION]
    if tolerance is not None and math.isfinite(tolerance) and tolerance > 0:
        terms.append(tolerance_factor * float(tolerance))
    if gsd is not None and math.isfinite(gsd) and gsd > 0:
        terms.append(gsd_px * float(gsd))
    return max(terms)


def repeated_positions(x: Any, y: Any, distance: float) -> np.ndarray:
    """For each point, the position (index) of the earlier point it repeats, else -1.

    In input order, a point repeats the earliest kept point nearer than ``distance``; a point with
    none is kept. The kept points are therefore exactly separated, and a point is only ever named a
    repeat of a point it is near (a chain A - B - C with A and C apart keeps A and C). Only points
    with a neighbour nearer than ``distance`` (one KD-tree query for all) are walked, through a grid
    of cells of that size: a cell holds at most a few kept points, so even a hostile cluster of a
    million points at one position costs one pass. Non-finite positions repeat nothing.
    """
    ax, ay = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    out = np.full(ax.size, -1, dtype=np.intp)
    if ax.size < 2 or not distance > 0:
        return out
    finite = np.flatnonzero(np.isfinite(ax) & np.isfinite(ay))
    if finite.size < 2:
        return out
    pts = np.column_stack([ax[finite], ay[finite]])
    d, j = cKDTree(pts).query(pts, k=2, distance_upper_bound=distance)
    own = np.arange(finite.size)
    # a point's own position may come second when another point sits exactly on it
    dist = np.where(j[:, 0] != own, d[:, 0], d[:, 1])
    cand = finite[dist < distance]  # ascending: input order
    cells: dict[tuple[int, int], list[int]] = {}
    cx = np.floor(ax[cand] / distance).astype(np.int64).tolist()
    cy = np.floor(ay[cand] / distance).astype(np.int64).tolist()
    for i, gx, gy in zip(cand.tolist(), cx, cy, strict=True):
        xi, yi = ax[i], ay[i]
        hit = -1
        for key in ((gx + a, gy + b) for a in (-1, 0, 1) for b in (-1, 0, 1)):
            for k in cells.get(key, ()):
                if (k < hit or hit < 0) and math.hypot(ax[k] - xi, ay[k] - yi) < distance:
                    hit = k
        if hit < 0:
            cells.setdefault((gx, gy), []).append(i)
        else:
            out[i] = hit
    return out


def nearest_gcp(x: Any, y: Any, gcp_x: Any, gcp_y: Any) -> tuple[np.ndarray, np.ndarray]:
    """(distance to the nearest GCP, its position in the GCP arrays) per point; inf / -1 without GCPs."""
    ax, ay = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    gx, gy = np.asarray(gcp_x, dtype=float), np.asarray(gcp_y, dtype=float)
    ok = np.isfinite(gx) & np.isfinite(gy)
    dist = np.full(ax.size, np.inf)
    which = np.full(ax.size, -1, dtype=np.intp)
    if not ok.any() or not ax.size:
        return dist, which
    pos = np.flatnonzero(ok)
    finite = np.isfinite(ax) & np.isfinite(ay)
    d, j = cKDTree(np.column_stack([gx[ok], gy[ok]])).query(
        np.column_stack([ax[finite], ay[finite]]), k=1
    )
    dist[finite] = d
    which[finite] = pos[j]
    return dist, which


def zero_residuals(dx: Any, dy: Any) -> np.ndarray:
    """Points whose planimetric residual is zero on both axes: the image position was entered as
    the reference (or the reference as the image position), not measured on the image."""
    ax, ay = np.abs(np.asarray(dx, dtype=float)), np.abs(np.asarray(dy, dtype=float))
    return (ax < ZERO) & (ay < ZERO)
