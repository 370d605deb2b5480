"""Automatic edges: find the straight edges of a target image and measure each one.

Why: a real edge target (Baotou: a rotated four-panel checkerboard, zero fill outside)
holds several edges, two directions and fill; the CEOS chain (``measure_edge``) needs one
straight edge per ROI, and guessing windows by hand is slow and error-prone. Here:

1. valid pixels: finite and not ``nodata``; without a nodata value a zero fill is
   detected (exact zeros connected to the border, >= 2 % of the image: a rotated target
   resampled into a rectangle); the fill and a 2-px rim inside it are excluded (rim
   pixels mix target and fill);
2. edge pixels: scikit-image Canny (sigma 1.5 px) inside the eroded valid area;
3. lines: probabilistic Hough segments, merged when their directions agree within 4 deg
   and their distances from the origin within 3 px, then refined by a total-least-squares
   fit to the Canny pixels within 1.5 px (a RANSAC-like consensus refit);
4. extent: the contrast across each line is sampled every pixel along it; runs of one
   sign (a checkerboard edge flips polarity at the target centre) at least
   ``min_length_px`` long are the edges;
5. ROI: a band of half-width w around the run, restricted to the run's side of every
   other line (no second edge in the band) and to valid pixels; everything else NaN.
   w grows over ``half_widths`` and the widest band whose edge passes every CEOS health
   check is kept (the last one tried is reported with its reasons when none passes);
   growing stops at a failure a wider band cannot fix (angle, straightness, sampling,
   SNR, contrast, saturation).

Edges whose profile runs along image x (edge near the columns) give the response in X,
the others in Y; for a north-up image X is easting and Y northing. The USGS combined RER
(seed ``000_64edc9235d9ff7d6.txt``: "RER is a geometric mean of normalized edge
response differences measured in two directions of image pixels (X and Y)",
RER = sqrt([ER_x(0.5) - ER_x(-0.5)][ER_y(0.5) - ER_y(-0.5)])) is the geometric mean of
the median valid RER of each direction.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from ..errors import MeasureError
from .edge import EdgeResult, measure_edge, rer_two_directions

__all__ = ["FoundEdge", "TargetEdges", "find_edges", "measure_target", "zero_fill"]


@dataclass(frozen=True, eq=False)
class FoundEdge:
    """One straight edge found in the image, the ROI grown around it and its measurement."""

    x0: float  # segment end points, image pixel coordinates (x = column, y = row)
    y0: float
    x1: float
    y1: float
    line_angle_deg: float  # direction of the edge line from the image x axis, 0..180
    axis: str  # "x" (profile along x: easting) or "y" (profile along y: northing)
    window: tuple[int, int, int, int]  # x0, y0, x1, y1 of the ROI (x1, y1 exclusive)
    half_width_px: float
    result: EdgeResult | None = None
    roi: np.ndarray | None = None  # the measured pixels (NaN outside the band), for figures

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "segment": [round(v, 3) for v in (self.x0, self.y0, self.x1, self.y1)],
            "line_angle_deg": round(self.line_angle_deg, 4),
            "axis": self.axis,
            "direction": "easting" if self.axis == "x" else "northing",
            "roi": list(self.window),
            "half_width_px": self.half_width_px,
        }
        if self.result is not None:
            out.update(self.result.to_dict())
        return out


@dataclass(frozen=True, eq=False)
class TargetEdges:
    """All edges of a target, and the USGS two-direction RER."""

    edges: tuple[FoundEdge, ...]
    rer_x: float | None
    rer_y: float | None
    rer_combined: float | None
    reason: str
    nodata: float | None = None
    fill_detected: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {
            "edges": [e.to_dict() for e in self.edges],
            "rer_x": self.rer_x, "rer_y": self.rer_y, "rer_combined": self.rer_combined,
            "rer_combined.reason": self.reason or None,
            "nodata": self.nodata, "zero_fill_detected": self.fill_detected,
            "rer_combined.definition": "sqrt(RER_x * RER_y), USGS (seed 000); RER_x / RER_y: "
                                       "median over the valid edges profiled along x / y",
        }


def zero_fill(img: np.ndarray, min_share: float = 0.02) -> float | None:
    """0 if the image has a zero fill: pixels exactly 0, connected to the image border,
    at least ``min_share`` of the image (a rotated target resampled into a rectangle);
    else None. Zero inside the target (a dark panel at 0) is not connected to the border."""
    zero = np.asarray(img) == 0
    if zero.mean() < min_share:
        return None
    lab, _ = ndimage.label(zero)
    border = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
    border = border[border > 0]
    share = float(np.isin(lab, border).mean()) if border.size else 0.0
    return 0.0 if share >= min_share else None


def _valid_mask(img: np.ndarray, nodata: float | None) -> np.ndarray:
    ok = np.isfinite(img)
    if nodata is not None:
        ok &= img != nodata
    return ok


def _merge_segments(segs: list[tuple[tuple[int, int], tuple[int, int]]],
                    max_dangle: float = 4.0, max_drho: float = 3.0) -> list[list[int]]:
    """Group Hough segments that lie on one line (normal angle and distance)."""
    info = []
    for (x0, y0), (x1, y1) in segs:
        th = math.atan2(x1 - x0, -(y1 - y0)) % math.pi  # normal direction, 0..pi
        rho = x0 * math.cos(th) + y0 * math.sin(th)
        info.append((th, rho, math.hypot(x1 - x0, y1 - y0)))
    order = sorted(range(len(segs)), key=lambda i: -info[i][2])
    groups: list[list[int]] = []
    heads: list[tuple[float, float]] = []
    for i in order:
        th, rho, _ = info[i]
        for g, (th0, rho0) in enumerate(heads):
            dth = (th - th0 + math.pi / 2) % math.pi - math.pi / 2
            r = rho if abs(th - th0) < math.pi / 2 else -rho
            if abs(math.degrees(dth)) <= max_dangle and abs(r - rho0) <= max_drho:
                groups[g].append(i)
                break
        else:
            groups.append([i])
            heads.append((th, rho))
    return groups


def _fit_line(px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total least squares: a point on the line and its unit direction (x, y)."""
    c = px.mean(axis=0)
    _, _, vt = np.linalg.svd(px - c, full_matrices=False)
    return c, vt[0]


def _sample(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear samples, NaN where any neighbour is NaN or outside."""
    h, w = img.shape
    inside = (x >= 0) & (x <= w - 1) & (y >= 0) & (y <= h - 1)
    out = ndimage.map_coordinates(np.nan_to_num(img, nan=0.0), [y, x], order=1, mode="nearest")
    bad = ndimage.map_coordinates((~np.isfinite(img)).astype(float), [y, x], order=1,
                                  mode="nearest") > 0
    return np.where(inside & ~bad, out, np.nan)


def find_edges(image: np.ndarray, *, nodata: float | None = None, sigma: float = 1.5,
               min_length_px: float = 20.0) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    """Straight edge segments: (point, unit direction, t_start, t_end) along each line."""
    img = np.asarray(image, dtype=float)
    if img.ndim != 2 or min(img.shape) < 10:
        raise MeasureError(f"target image must be 2-D and at least 10 x 10 px, got {img.shape}")
    valid = _valid_mask(img, nodata)
    if valid.sum() < 100:
        raise MeasureError("target image has fewer than 100 valid (finite, not nodata) pixels")
    lines = _edge_lines(img, valid, sigma, min_length_px)
    return _segments(np.where(valid, img, np.nan), lines, min_length_px)


def _edge_lines(img: np.ndarray, valid: np.ndarray, sigma: float,
                min_length_px: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Canny edges inside the target, probabilistic Hough segments merged into lines, each line
    refitted on the Canny pixels near it: (point, unit direction) per distinct line."""
    from skimage.feature import canny
    from skimage.transform import probabilistic_hough_line

    inner = ndimage.binary_erosion(valid, iterations=3)
    filled = np.where(valid, img, float(np.median(img[valid])))
    # hysteresis thresholds relative to the strongest gradient inside the target
    gmax = float(ndimage.gaussian_gradient_magnitude(filled, sigma)[inner].max(initial=0.0))
    if not gmax > 0:
        return []
    edges = canny(filled, sigma=sigma, mask=inner, low_threshold=0.15 * gmax,
                  high_threshold=0.3 * gmax)
    if edges.sum() < min_length_px:
        return []
    segs = probabilistic_hough_line(edges, threshold=8, line_length=max(int(min_length_px // 2), 5),
                                    line_gap=3, rng=0)
    ey, ex = np.nonzero(edges)
    pts = np.column_stack([ex, ey]).astype(float)
    lines: list[tuple[np.ndarray, np.ndarray]] = []
    for group in _merge_segments(segs):
        ends = np.array([p for i in group for p in segs[i]], dtype=float)
        c, u = _fit_line(ends)
        for _ in range(2):  # consensus refit on the Canny pixels near the line
            n = np.array([-u[1], u[0]])
            near = pts[np.abs((pts - c) @ n) <= 1.5]
            if len(near) < min_length_px / 2:
                break
            c, u = _fit_line(near)
        if u[1] < 0 or (u[1] == 0 and u[0] < 0):
            u = -u
        if not any(abs(float(u @ u2)) > math.cos(math.radians(4)) and
                   abs(float((c - c2) @ np.array([-u2[1], u2[0]]))) < 3.0 for c2, u2 in lines):
            lines.append((c, u))
    return lines


def _segments(work: np.ndarray, lines: list[tuple[np.ndarray, np.ndarray]],
              min_length_px: float) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    """The runs of each line where the two sides differ (2-4 px either side, one sign, more than
    half the line's median contrast) for at least ``min_length_px``: the edge segments."""
    out = []
    h, w = work.shape
    reach = math.hypot(h, w)
    for c, u in lines:
        n = np.array([-u[1], u[0]])
        t = np.arange(-reach, reach + 0.5, 1.0)
        px, py = c[0] + t * u[0], c[1] + t * u[1]
        k = np.arange(2.0, 5.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns: outside
            hi = np.nanmean(np.stack([_sample(work, px + s * n[0], py + s * n[1]) for s in k]), axis=0)
            lo = np.nanmean(
                np.stack([_sample(work, px - s * n[0], py - s * n[1]) for s in k]), axis=0
            )
        con = hi - lo
        fin = np.isfinite(con)
        if not fin.any():
            continue
        level = 0.5 * float(np.median(np.abs(con[fin])))
        sign = np.where(fin & (np.abs(con) > level), np.sign(con), 0.0)
        # runs of one sign
        i = 0
        while i < t.size:
            if sign[i] == 0:
                i += 1
                continue
            j = i
            while j + 1 < t.size and sign[j + 1] == sign[i]:
                j += 1
            if t[j] - t[i] + 1 >= min_length_px:
                out.append((c, u, float(t[i]), float(t[j])))
            i = j + 1
    return out


# health checks that a wider band can turn to pass (more plateau, more of the transition)
_WIDTH_CHECKS = {"dark_width", "bright_width", "fit"}


def _band_mask(
    shape: tuple[int, int],
    c: np.ndarray,
    u: np.ndarray,
    t0: float,
    t1: float,
    half: float,
    others: list[tuple[np.ndarray, np.ndarray]],
) -> np.ndarray:
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    rel_x, rel_y = xx - c[0], yy - c[1]
    along = rel_x * u[0] + rel_y * u[1]
    across = -rel_x * u[1] + rel_y * u[0]
    band = (along >= t0) & (along <= t1) & (np.abs(across) <= half)
    mid = c + 0.5 * (t0 + t1) * u
    for c2, u2 in others:
        n2 = np.array([-u2[1], u2[0]])
        side = float((mid - c2) @ n2)
        if abs(side) < 1.0:
            continue
        dist = (xx - c2[0]) * n2[0] + (yy - c2[1]) * n2[1]
        band &= np.sign(dist) == np.sign(side)
        band &= np.abs(dist) >= 3.0
    return band


def measure_target(
    image: np.ndarray,
    *,
    nodata: float | None = None,
    gsd: float | None = None,
    half_widths: tuple[float, ...] = (9.0, 13.0, 18.0),
    min_length_px: float = 20.0,
    **measure_kw: Any,
) -> TargetEdges:
    """Find every straight edge of a target image, grow a passing ROI around each, measure it.

    ``measure_kw`` goes to :func:`orthospec.measures.edge.measure_edge` (``limits=EdgeLimits(...)``
    or single limits). ``image`` may be a ``numpy.ma`` array (as :func:`orthospec.raster.roi.read_roi`
    returns it): its masked pixels are invalid like ``nodata``, and when any pixel is masked no
    zero fill is searched for (the file declares its invalid pixels).
    """
    img = np.asarray(np.ma.getdata(image), dtype=float)
    masked = np.ma.getmaskarray(image) if np.ma.isMaskedArray(image) else None
    declared = masked is not None and bool(masked.any())
    if masked is not None and declared:
        img = np.where(masked, np.nan, img)
    fill = None
    if nodata is None and not declared:
        nodata = fill = zero_fill(img)
    found = find_edges(img, nodata=nodata, min_length_px=min_length_px)
    valid = ndimage.binary_erosion(_valid_mask(img, nodata), iterations=2)
    lines: list[tuple[Any, Any]] = []
    for c, u, _, _ in found:
        if not any(c is c2 for c2, _ in lines):
            lines.append((c, u))
    edges: list[FoundEdge] = []
    for c, u, t0, t1 in found:
        others = [(c2, u2) for c2, u2 in lines if c2 is not c]
        best = _grow(img, valid, (c, u, t0, t1), others, half_widths, gsd, measure_kw)
        if best is not None:
            edges.append(best)
    edges = _one_per_edge(edges)
    edges.sort(key=lambda e: (e.axis, e.y0, e.x0))
    return _combined(tuple(edges), nodata, fill is not None)


def _one_per_edge(
    edges: list[FoundEdge], max_dangle: float = 3.0, max_offset: float = 3.0
) -> list[FoundEdge]:
    """One measurement per physical edge (issue 31): found edges whose lines agree within
    ``max_dangle`` deg and ``max_offset`` px and whose segments overlap along the line are the same
    edge found twice (noise splits a line's Hough segments or its contrast run); the valid one
    with the longest segment is kept. An invalid line whose ROI lies mostly inside a valid
    edge's ROI is noise crossing that edge (seen at SNR 30), not another edge. Runs of a
    checkerboard line on either side of the centre (opposite polarity, no overlap) stay apart."""

    def seg(e: FoundEdge) -> tuple[np.ndarray, np.ndarray, float]:
        p0, p1 = np.array([e.x0, e.y0]), np.array([e.x1, e.y1])
        return p0, p1, float(np.hypot(*(p1 - p0)))

    def same(a: FoundEdge, b: FoundEdge) -> bool:
        dang = abs((a.line_angle_deg - b.line_angle_deg + 90.0) % 180.0 - 90.0)
        if dang > max_dangle:
            return False
        a0, a1, la = seg(a)
        b0, b1, _ = seg(b)
        u = (a1 - a0) / max(la, 1e-9)
        n = np.array([-u[1], u[0]])
        if max(abs(float((b0 - a0) @ n)), abs(float((b1 - a0) @ n))) > max_offset:
            return False
        t = sorted([float((b0 - a0) @ u), float((b1 - a0) @ u)])
        return t[1] > 0.0 and t[0] < la  # overlap along the line

    def inside(a: FoundEdge, b: FoundEdge) -> bool:
        """b is an invalid short line mostly inside a valid edge's ROI (noise crossing it)."""
        if not (a.result is not None and a.result.valid) or (
            b.result is not None and b.result.valid
        ):
            return False
        ax0, ay0, ax1, ay1 = a.window
        bx0, by0, bx1, by1 = b.window
        ov = max(0, min(ax1, bx1) - max(ax0, bx0)) * max(0, min(ay1, by1) - max(ay0, by0))
        return ov >= 0.5 * max((bx1 - bx0) * (by1 - by0), 1)

    def rank(e: FoundEdge) -> tuple[bool, float]:
        return (bool(e.result is not None and e.result.valid), seg(e)[2])

    kept: list[FoundEdge] = []
    for e in sorted(edges, key=rank, reverse=True):
        if not any(same(e, k) or inside(k, e) for k in kept):
            kept.append(e)
    return kept


def _grow(
    img: np.ndarray,
    valid: np.ndarray,
    seg: tuple[np.ndarray, np.ndarray, float, float],
    others: list[tuple[np.ndarray, np.ndarray]],
    half_widths: tuple[float, ...],
    gsd: float | None,
    measure_kw: dict[str, Any],
) -> FoundEdge | None:
    """The ROI of one edge segment: bands of growing half width around it (away from the other
    lines), measured until one passes and the next no longer does; the widest passing one, else
    the last tried."""
    c, u, t0, t1 = seg
    best: FoundEdge | None = None
    for half in half_widths:
        band = _band_mask(img.shape, c, u, t0 + 2.0, t1 - 2.0, half, others) & valid
        if band.sum() < 50:
            continue
        rows, cols = np.nonzero(band)
        y0, y1, x0, x1 = int(rows.min()), int(rows.max()) + 1, int(cols.min()), int(cols.max()) + 1
        roi = np.where(band, img, np.nan)[y0:y1, x0:x1]
        try:
            res = measure_edge(roi, gsd=gsd, **measure_kw)
        except MeasureError:
            continue
        axis = "y" if res.transposed else "x"
        p0, p1 = c + t0 * u, c + t1 * u
        cand = FoundEdge(
            float(p0[0]),
            float(p0[1]),
            float(p1[0]),
            float(p1[1]),
            math.degrees(math.atan2(u[1], u[0])) % 180.0,
            axis,
            (x0, y0, x1, y1),
            half,
            res,
            roi,
        )
        if res.valid or best is None or not (best.result and best.result.valid):
            best = cand
        elif best.result is not None and best.result.valid:
            break  # grown past the widest passing band
        failed = {c.name for c in res.checks if not c.passed}
        if not res.valid and not failed <= _WIDTH_CHECKS:
            break  # a wider band does not fix the angle, straightness or sampling
    return best


def _combined(edges: tuple[FoundEdge, ...], nodata: float | None, fill: bool) -> TargetEdges:
    """USGS two-direction RER over the valid edges: median RER_x, RER_y, sqrt of their product."""
    per_axis: dict[str, list[float]] = {"x": [], "y": []}
    for e in edges:
        if e.result is not None and e.result.valid and e.result.rer is not None:
            per_axis[e.axis].append(e.result.rer)
    rx = float(np.median(per_axis["x"])) if per_axis["x"] else None
    ry = float(np.median(per_axis["y"])) if per_axis["y"] else None
    reason = ""
    combined = None
    if rx is not None and ry is not None:
        combined = float(rer_two_directions(rx, ry))
    else:
        missing = [a for a, v in (("X (easting)", rx), ("Y (northing)", ry)) if v is None]
        reason = f"no valid edge profiled along {' and '.join(missing)}"
    return TargetEdges(edges, rx, ry, combined, reason, nodata, fill)
