"""Accuracy figures as deterministic SVG text: checkpoint map, quadrants, residual histograms.

The checkpoint map follows JRC EUR 23638 EN Figure 5 ("Output from External QC Showing Check
Points, Discrepancies and GCPs"): points, discrepancy vectors exaggerated by a scale factor
with a scale arrow, GCPs. Same inputs give byte-identical SVG: Agg backend, fixed
``svg.hashsalt``, no date in the metadata. Key artists carry a ``gid`` so reports and tests
can find them (``checkpoints``, ``discrepancy-vectors``, ``scale-arrow``, ``gcps``...).

Bounded whatever the number of points (issue 14: 100,000 points made a 26 MB HTML and a 55 s
PDF): a map or quadrant figure draws at most :data:`MAX_MARKS` points, every flagged point always
and an evenly spread sample of the others (:func:`sample_points`), and says so in the figure
(``sample-note``); histograms bin every value into at most :data:`MAX_BINS` bins. Below the cap
the figures are exactly what they were.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import matplotlib

matplotlib.use("Agg", force=False)

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch

from ..errors import MeasureError

__all__ = ["MAX_BINS", "MAX_MARKS", "Sample", "checkpoint_map_svg", "quadrant_distribution_svg",
           "residual_histograms_svg", "sample_points"]

#: Points drawn per figure at most (flagged points besides, when they alone exceed it): each mark
#: costs SVG bytes and drawing time, in matplotlib and again in the PDF renderer.
MAX_MARKS = 1000
#: Unflagged points drawn at least when flagged points fill the cap, so the spread still shows.
MIN_SAMPLE = MAX_MARKS // 10
#: A sampled map labels this many flagged points regardless of crowding (the largest discrepancies),
#: the other flagged ones where they do not crowd, and no unflagged point (a label costs as much
#: to lay out as 30 marks).
MAX_FLAGGED_LABELS = 100
#: Bins per histogram at most: 'auto' bins are narrow when one outlier stretches the range.
MAX_BINS = 200

_RC: Any = {
    "svg.hashsalt": "orthospec",
    "svg.fonttype": "none",  # text stays text: smaller, searchable, font-independent
    "font.family": "DejaVu Sans",
    "figure.dpi": 100,
}


def _svg(fig: Figure) -> str:
    buf = io.StringIO()
    with plt.rc_context(_RC):
        fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": "orthospec"})
    plt.close(fig)
    return buf.getvalue()


def _arr(name: str, v: Any, n: int | None = None) -> np.ndarray:
    a = np.asarray(v, dtype=float).ravel()
    if n is not None and a.size != n:
        raise MeasureError(f"{name} has {a.size} values, expected {n}")
    if not np.isfinite(a).all():
        raise MeasureError(f"{name} contains non-finite values")
    return a


@dataclass(frozen=True)
class Sample:
    """Which points a figure draws: ``index`` into the inputs, the sampled others first and the
    must-draw ones last (flagged marks on top), each in curve order (the input order when every
    point is drawn), so shuffled inputs draw the same figure."""

    index: np.ndarray
    total: int
    must: int
    step: int = 1

    @property
    def drawn(self) -> int:
        return int(self.index.size)

    @property
    def thinned(self) -> bool:
        return self.drawn < self.total

    def note(self, what: str = "flagged") -> str:
        """The honest count the figure and its caption state (empty when every point is drawn)."""
        if not self.thinned:
            return ""
        return (f"{self.drawn:,} of {self.total:,} points drawn: all {self.must:,} {what}, "
                f"1 in {self.step:,} of the others (an even spatial sample)")


def _zorder(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Morton (Z-order) code of each point on a 65536 x 65536 grid over the points' extent: points
    close on the curve are close on the ground, so every k-th along it is a stratified sample."""
    def spread(v: np.ndarray) -> np.ndarray:
        lo, span = float(v.min()), float(np.ptp(v))
        q = np.zeros(v.size, dtype=np.uint64) if span <= 0 else \
            np.minimum((v - lo) / span * 65536.0, 65535.0).astype(np.uint64)
        for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
            q = (q | (q << np.uint64(shift))) & np.uint64(mask)
        return q

    return spread(x) | (spread(y) << np.uint64(1))


def sample_points(x: Any, y: Any, ids: Sequence[Any] | None = None, must: Any = None,
                  cap: int = MAX_MARKS) -> Sample:
    """Deterministic, evenly spread sample of the points (``x``, ``y``): every ``must`` point (a
    boolean mask) and every k-th of the others along a Z-order curve (ties by point id, else by
    input order), at most ``cap`` in all (at least :data:`MIN_SAMPLE` others when the must-draw
    points alone fill it).

    Every k-th along the curve is a spatially stratified sample: each part of the block keeps
    its share of the points, holes stay holes, and the same points give the same sample whatever
    their order.
    """
    ax_x = np.asarray(x, dtype=float).ravel()
    ax_y = np.asarray(y, dtype=float).ravel()
    n = ax_x.size
    keep = np.zeros(n, dtype=bool) if must is None else np.asarray(must, dtype=bool).ravel()
    if keep.size != n or ax_y.size != n:
        raise MeasureError(f"{keep.size} must-draw flags and {ax_y.size} y values for {n} points")
    if n <= cap:
        return Sample(np.arange(n), n, int(keep.sum()))
    tie = np.arange(n) if ids is None else np.asarray([str(i) for i in ids])
    order = np.lexsort((tie, _zorder(ax_x, ax_y)))
    must_idx = order[keep[order]]
    others = order[~keep[order]]
    room = min(max(cap - must_idx.size, MIN_SAMPLE), others.size)
    step = max(1, math.ceil(others.size / room)) if room else 0
    chosen = others[::step] if step else others[:0]
    return Sample(np.concatenate([chosen, must_idx]), n, int(must_idx.size), step)


def _label_order(red: np.ndarray, n: int) -> list[int]:
    return sorted(range(n), key=lambda k: (not red[k], k))  # flagged points first


def _uncrowded(xs: np.ndarray, ys: np.ndarray, red: np.ndarray, min_gap: float,
               always: int | None = None) -> list[int]:
    """Indices to label: flagged points always, others only at least ``min_gap`` from every label
    placed before. With ``always`` (a sampled map): the first ``always`` flagged points always,
    the other flagged ones where they do not crowd, unflagged ones never. Placed labels are kept
    in a grid of ``min_gap`` cells, so each test looks at 9 cells instead of every label (same
    result)."""
    grid: dict[tuple[int, int], list[tuple[float, float]]] = {}
    out: list[int] = []
    n_red = 0
    for i in _label_order(red, xs.size):
        if always is not None and not red[i]:
            break  # flagged points come first
        xi, yi = float(xs[i]), float(ys[i])
        cx, cy = math.floor(xi / min_gap), math.floor(yi / min_gap)
        forced = bool(red[i]) and (always is None or n_red < always)
        if not forced and any(math.hypot(xi - a, yi - b) < min_gap
                              for gx in (cx - 1, cx, cx + 1) for gy in (cy - 1, cy, cy + 1)
                              for a, b in grid.get((gx, gy), ())):
            continue
        n_red += bool(red[i])
        grid.setdefault((cx, cy), []).append((xi, yi))
        out.append(i)
    return out


def _title(ax: Any, title: str, note: str) -> None:
    """The axes title, and under it the sample note when not every point is drawn."""
    if not note:
        ax.set_title(title)
        return
    ax.set_title(title, pad=16)
    ax.text(0.5, 1.01, note, transform=ax.transAxes, ha="center", va="bottom", fontsize=7, gid="sample-note")


def _too_many_bins(v: np.ndarray, bins: int | str) -> bool:
    """Would the bins asked for exceed :data:`MAX_BINS`? (numpy 2 keeps ``"auto"`` to at most
    2 sqrt(n) bins itself, so asking it for the edges is cheap.)"""
    if isinstance(bins, int):
        return bins > MAX_BINS
    return int(np.histogram_bin_edges(v, bins=bins).size) - 1 > MAX_BINS


def _nice(v: float) -> float:
    """A 1-2-5 round number close to ``v`` (for the scale arrow)."""
    if v <= 0 or not math.isfinite(v):
        return 1.0
    e = math.floor(math.log10(v))
    for m in (1, 2, 5, 10):
        if m * 10**e >= v:
            return float(m * 10**e)
    return float(10 ** (e + 1))


def checkpoint_map_svg(
    x: Any,
    y: Any,
    dx: Any,
    dy: Any,
    *,
    ids: Sequence[Any] | None = None,
    gcp_x: Any = None,
    gcp_y: Any = None,
    scale: float | None = None,
    unit: str = "m",
    flagged: Sequence[Any] = (),
    title: str = "Checkpoints and discrepancies",
    polygon: Sequence[tuple[float, float]] | None = None,
    always: Sequence[Any] = (),
    max_points: int = MAX_MARKS,
    defect_cells: Sequence[tuple[Sequence[float], str]] = (),
) -> str:
    """Checkpoint map with discrepancy vectors (× ``scale``) and GCPs, as SVG text.

    ``scale`` defaults to one that makes the largest discrepancy 8 % of the map extent.
    ``flagged`` ids (e.g. blunder candidates) are drawn in red and always labelled; other labels
    are drawn only where they do not crowd an earlier one. The figure's shape follows the
    points' (and ``polygon``'s, the block outline) extent, so an elongated block is not drawn in
    a mostly empty square.

    More than ``max_points`` points: :func:`sample_points` picks the drawn ones (every flagged
    and ``always`` id, e.g. exclusion requests, and an even sample of the rest), the figure states
    the counts (``sample-note``) and the extent, scale and scale arrow still come from every point.
    ``defect_cells``: (left, bottom, right, top), label) of the inspection grid's marked cells in the
    block (docs/CHECKER.md), drawn as orange hatched squares (``inspection-defects``).
    """
    ax_x = _arr("x", x)
    n = ax_x.size
    if n == 0:
        raise MeasureError("no checkpoints to draw")
    ax_y, vdx, vdy = _arr("y", y, n), _arr("dx", dx, n), _arr("dy", dy, n)
    labels = [str(i) for i in ids] if ids is not None else [str(i) for i in range(n)]
    if len(labels) != n:
        raise MeasureError(f"{len(labels)} ids for {n} checkpoints")
    extent = max(float(np.ptp(ax_x)), float(np.ptp(ax_y)), 1e-9)
    dmax = float(np.hypot(vdx, vdy).max())
    if scale is None:
        scale = 0.08 * extent / dmax if dmax > 0 else 1.0
    if not (math.isfinite(scale) and scale > 0):
        raise MeasureError(f"scale must be positive, got {scale}")

    px = np.asarray([p[0] for p in polygon], dtype=float) if polygon else np.empty(0)
    py = np.asarray([p[1] for p in polygon], dtype=float) if polygon else np.empty(0)
    allx, ally = np.concatenate([ax_x, px]), np.concatenate([ax_y, py])
    wx, wy = max(float(np.ptp(allx)), 1e-9), max(float(np.ptp(ally)), 1e-9)
    height = float(np.clip(7.0 * wy / wx, 3.2, 9.0)) + 0.8  # room for title, labels, scale arrow
    red = np.isin(np.asarray(labels), [str(f) for f in flagged])
    must = red | np.isin(np.asarray(labels), [str(f) for f in always]) if len(always) else red
    sample = sample_points(ax_x, ax_y, labels, must, max_points)
    if sample.thinned:  # extent and scale above came from every point
        idx, k = sample.index, sample.drawn - sample.must
        top = idx[k:]  # the must-draw points, largest discrepancy first: they get the forced labels
        idx = np.concatenate(
            [idx[:k], top[np.argsort(-np.hypot(vdx[top], vdy[top]), kind="stable")]]
        )
        ax_x, ax_y, vdx, vdy, red = ax_x[idx], ax_y[idx], vdx[idx], vdy[idx], red[idx]
        labels = [labels[i] for i in idx]
        n = idx.size
    with plt.rc_context(_RC):
        fig, ax = plt.subplots(figsize=(7, height))
        if polygon:
            outline = ax.fill(
                px,
                py,
                facecolor="none",
                edgecolor="0.4",
                linestyle="--",
                linewidth=0.8,
                label="block outline",
                zorder=1,
            )
            for o in outline:
                o.set_gid("block-outline")
        if defect_cells:
            from matplotlib.collections import PatchCollection
            from matplotlib.patches import Rectangle

            rects = [Rectangle((b[0], b[1]), b[2] - b[0], b[3] - b[1]) for b, _ in defect_cells]
            coll = PatchCollection(
                rects,
                facecolor="tab:orange",
                edgecolor="tab:orange",
                alpha=0.5,
                hatch="////",
                zorder=2,
                label="inspection: marked cell",
            )
            coll.set_gid("inspection-defects")
            ax.add_collection(coll)
            ax.scatter(
                [], [], marker="s", color="tab:orange", alpha=0.5, label="inspection: marked cell"
            )
        pts = ax.scatter(
            ax_x, ax_y, s=18, c=np.where(red, "tab:red", "tab:blue"), zorder=3, label="check point"
        )
        pts.set_gid("checkpoints")
        q = ax.quiver(
            ax_x,
            ax_y,
            vdx * scale,
            vdy * scale,
            angles="xy",
            scale_units="xy",
            scale=1,
            color=np.where(red, "tab:red", "black"),
            width=0.003,
            zorder=4,
        )
        q.set_gid("discrepancy-vectors")
        min_gap = 0.045 * max(wx, wy)
        for i in _uncrowded(
            ax_x, ax_y, red, min_gap, MAX_FLAGGED_LABELS if sample.thinned else None
        ):
            ax.annotate(
                labels[i],
                (float(ax_x[i]), float(ax_y[i])),
                xytext=(3, 3),
                textcoords="offset points",
                fontsize=6,
                color="tab:red" if red[i] else "black",
            )
        if gcp_x is not None and gcp_y is not None:
            gx = _arr("gcp_x", gcp_x)
            gy = _arr("gcp_y", gcp_y, gx.size)
            g = ax.scatter(
                gx,
                gy,
                marker="^",
                s=40,
                facecolors="none",
                edgecolors="tab:green",
                zorder=2,
                label="GCP",
            )
            g.set_gid("gcps")
        ref_len = _nice(dmax if dmax > 0 else 1.0)
        span = max(wx, wy)
        x0 = float(allx.min())
        y0 = float(ally.min()) - 0.08 * span  # below the points and the outline
        arrow = FancyArrowPatch(
            (x0, y0),
            (x0 + ref_len * scale, y0),
            arrowstyle="->",
            mutation_scale=12,
            color="black",
            gid="scale-arrow",
        )
        ax.add_patch(arrow)
        ax.text(
            x0,
            y0 - 0.03 * span,
            f"{ref_len:g} {unit} discrepancy (vectors × {scale:.3g})",
            fontsize=8,
            gid="scale-label",
        )
        # ground scale bar (map distance, not exaggerated), right-aligned on the same line
        bar = _nice(0.2 * wx) if _nice(0.2 * wx) <= 0.3 * wx else _nice(0.1 * wx)
        x1 = float(allx.max())
        (sb,) = ax.plot(
            [x1 - bar, x1], [y0, y0], color="black", linewidth=2.5, solid_capstyle="butt"
        )
        sb.set_gid("map-scale-bar")
        ax.text(
            x1 - bar / 2,
            y0 - 0.03 * span,
            f"{bar:g} {unit}",
            fontsize=8,
            ha="center",
            gid="map-scale-label",
        )
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"Easting ({unit})")
        ax.set_ylabel(f"Northing ({unit})")
        _title(ax, title, sample.note("flagged or excluded" if len(always) else "flagged"))
        # the legend below the axes, never over points or the scale bars
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=4, fontsize=8, frameon=False)
        ax.ticklabel_format(useOffset=False, style="plain")
        fig.tight_layout()
        return _svg(fig)


def quadrant_distribution_svg(
    x: Any,
    y: Any,
    *,
    centre: tuple[float, float],
    shares: dict[str, float] | None = None,
    area: Sequence[tuple[float, float]] | None = None,
    min_share: float = 0.20,
    unit: str = "m",
    title: str = "Check point distribution by quadrant",
    ids: Sequence[Any] | None = None,
    max_points: int = MAX_MARKS,
) -> str:
    """Points with the quadrant split lines and each quadrant's share (JRC Figure 4).

    ``centre`` and ``shares`` come from :func:`orthospec.measures.distribution.checkpoint_distribution`;
    shares below ``min_share`` are printed in red. More than ``max_points`` points: an even
    spatial sample is drawn (:func:`sample_points`, ties by ``ids`` when given) and the figure
    says so; the shares are the caller's, from every point.
    """
    ax_x = _arr("x", x)
    ax_y = _arr("y", y, ax_x.size)
    if ax_x.size == 0:
        raise MeasureError("no checkpoints to draw")
    cx, cy = centre
    with plt.rc_context(_RC):
        fig, ax = plt.subplots(figsize=(6, 6))
        if area is not None:
            ring = np.asarray(area, dtype=float)
            (ln,) = ax.plot(
                np.r_[ring[:, 0], ring[0, 0]], np.r_[ring[:, 1], ring[0, 1]], color="grey", lw=1
            )
            ln.set_gid("area")
        sample = sample_points(ax_x, ax_y, ids, None, max_points)
        sx, sy = (ax_x[sample.index], ax_y[sample.index]) if sample.thinned else (ax_x, ax_y)
        ax.scatter(sx, sy, s=18, color="tab:blue", zorder=3).set_gid("checkpoints")
        ax.axvline(cx, color="black", lw=0.8, ls="--", gid="split-x")
        ax.axhline(cy, color="black", lw=0.8, ls="--", gid="split-y")
        if shares:
            xmin, xmax = min(ax_x.min(), cx), max(ax_x.max(), cx)
            ymin, ymax = min(ax_y.min(), cy), max(ax_y.max(), cy)
            pos = {
                "NE": ((cx + xmax) / 2, (cy + ymax) / 2),
                "NW": ((xmin + cx) / 2, (cy + ymax) / 2),
                "SW": ((xmin + cx) / 2, (ymin + cy) / 2),
                "SE": ((cx + xmax) / 2, (ymin + cy) / 2),
            }
            for q, (px, py) in pos.items():
                s = shares.get(q, 0.0)
                ax.text(
                    px,
                    py,
                    f"{q} {s:.0%}",
                    ha="center",
                    va="center",
                    fontsize=11,
                    color="tab:red" if s < min_share else "tab:green",
                    gid=f"share-{q}",
                )
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"Easting ({unit})")
        ax.set_ylabel(f"Northing ({unit})")
        _title(ax, title, sample.note())
        ax.ticklabel_format(useOffset=False, style="plain")
        fig.tight_layout()
        return _svg(fig)


def residual_histograms_svg(
    dx: Any,
    dy: Any,
    dz: Any = None,
    *,
    unit: str = "m",
    bins: int | str = "auto",
    title: str = "Check point discrepancies",
) -> str:
    """One histogram per axis (dx, dy and dz when given) with the mean and ±RMSE marked.

    Every value is binned (no sampling: a histogram's size is its bins'); at most
    :data:`MAX_BINS` bins per axis, so one far outlier does not make ``bins="auto"`` draw thousands.
    """
    vdx = _arr("dx", dx)
    vdy = _arr("dy", dy, vdx.size)
    series = [("dx", vdx), ("dy", vdy)]
    if dz is not None:
        series.append(("dz", _arr("dz", dz, vdx.size)))
    if vdx.size == 0:
        raise MeasureError("no discrepancies to draw")
    with plt.rc_context(_RC):
        fig, axes = plt.subplots(1, len(series), figsize=(4 * len(series), 3.5), squeeze=False)
        for ax, (name, v) in zip(axes[0], series, strict=True):
            _, _, patches = ax.hist(
                v, bins=MAX_BINS if _too_many_bins(v, bins) else bins, color="tab:blue", alpha=0.8
            )
            for p in patches:
                p.set_gid(f"hist-{name}-bar")
            rmse = float(np.sqrt(np.mean(v * v)))
            ax.axvline(float(v.mean()), color="black", lw=1, gid=f"mean-{name}")
            for s in (-rmse, rmse):
                ax.axvline(s, color="tab:red", lw=1, ls="--", gid=f"rmse-{name}")
            ax.set_xlabel(f"{name} ({unit})")
            ax.set_title(f"{name}: mean {v.mean():.3g}, RMSE {rmse:.3g}", fontsize=9)
        axes[0][0].set_ylabel("points")
        fig.suptitle(title)
        fig.tight_layout()
        return _svg(fig)
