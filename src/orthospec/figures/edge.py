"""SVG figures of the edge chain: detection, ESF, LSF and MTF (seed 003 steps 5, 6-8, 10, 12).

Figures are built on :class:`matplotlib.figure.Figure` (Agg canvas, no pyplot state) and
written with a fixed ``svg.hashsalt`` and no date, so the same result gives byte-identical SVG.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..measures.edge import NYQUIST, EdgeResult

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

__all__ = [
    "FitCurves",
    "detection_svg",
    "detection_svg_from_arrays",
    "edge_figures",
    "esf_svg",
    "esf_svg_from_arrays",
    "lsf_svg",
    "lsf_svg_from_arrays",
    "mtf_svg",
    "mtf_svg_from_arrays",
]

_RC: dict[RcKeyType, Any] = {
    "svg.hashsalt": "orthospec-edge",
    "svg.fonttype": "none",
    "font.size": 9,
    "axes.grid": True,
    "grid.alpha": 0.3,
}
_COLOURS = {"spline": "tab:red", "fermi": "tab:blue"}
_MAX_POINTS = 4000


def _colour(fit: str) -> str:
    return _COLOURS.get(fit, _COLOURS["fermi"] if fit.startswith("fermi") else "tab:green")


def _svg(fig: Figure) -> str:
    FigureCanvasAgg(fig)
    buf = io.StringIO()
    with mpl.rc_context(_RC):
        fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": "orthospec"})
    return buf.getvalue()


def _figure() -> tuple[Figure, Axes]:
    with mpl.rc_context(_RC):
        fig = Figure(figsize=(6.0, 4.0), dpi=100)
        ax = fig.add_subplot(1, 1, 1)
    return fig, ax


def _status(result: EdgeResult) -> str:
    return (
        "valid"
        if result.valid
        else "INVALID: " + "; ".join(r.split(":")[0] for r in result.reasons)
    )


def detection_svg(roi: np.ndarray, result: EdgeResult) -> str:
    """ROI with per-line edge locations (kept and rejected) and the fitted line (step 5)."""
    with mpl.rc_context(_RC):
        fig, ax = _figure()
        ax.grid(False)
        ax.imshow(np.asarray(roi, dtype=float), cmap="gray", interpolation="nearest")
        k = result.line_kept
        if k.size:
            ax.plot(
                result.line_x[k],
                result.line_y[k],
                ".",
                ms=3,
                color="tab:red",
                label="edge location per line",
            )
            if (~k).any():
                ax.plot(
                    result.line_x[~k],
                    result.line_y[~k],
                    "x",
                    ms=4,
                    color="tab:orange",
                    label="rejected line",
                )
            if np.isfinite(result.fitted_x).all():
                ax.plot(
                    result.fitted_x,
                    result.fitted_y,
                    "-",
                    lw=1,
                    color="tab:green",
                    label="fitted edge line",
                )
        angle = "n/a" if result.angle_deg is None else f"{result.angle_deg:.2f}°"
        ax.set_title(
            f"Edge detection ({result.direction}, {angle}) — {_status(result)}", fontsize=8
        )
        ax.set_xlabel("x (column, px)")
        ax.set_ylabel("y (row, px)")
        if k.size:
            ax.legend(loc="lower right", fontsize=7)
        return _svg(fig)


def esf_svg(result: EdgeResult) -> str:
    """Normalised ESF samples at perpendicular distance with both fits (steps 6-8)."""
    with mpl.rc_context(_RC):
        fig, ax = _figure()
        if result.dark_level is not None and result.bright_level is not None and result.window_px:
            lo, hi = result.window_px
            span = result.bright_level - result.dark_level
            sel = (result.esf_d >= lo - 1) & (result.esf_d <= hi + 1)
            d, v = result.esf_d[sel], (result.esf_dn[sel] - result.dark_level) / span
            if d.size > _MAX_POINTS:  # deterministic thinning for file size
                step = int(np.ceil(d.size / _MAX_POINTS))
                d, v = d[::step], v[::step]
            ax.plot(d, v, ".", ms=1.5, color="0.5", label="pixels")
            for fit in result.fits.values():
                ax.plot(fit.x, fit.esf, "-", lw=1.2, color=_colour(fit.fit), label=f"{fit.fit} fit")
            for x, name, align in (
                (result.dark_start_px, "dark start ", "right"),
                (result.bright_start_px, " bright start", "left"),
            ):
                if x is not None:
                    ax.axvline(x, ls=":", lw=0.8, color="k")
                    ax.text(x, 1.03, name, fontsize=6, ha=align)
            ax.legend(loc="lower right", fontsize=7)
        ax.set_xlabel("distance from edge, perpendicular (px)")
        ax.set_ylabel("normalised DN")
        ax.set_title(f"Edge spread function — {_status(result)}", fontsize=8)
        return _svg(fig)


def lsf_svg(result: EdgeResult) -> str:
    """LSF of each fit with the FWHM marked (steps 10-11)."""
    with mpl.rc_context(_RC):
        fig, ax = _figure()
        for fit in result.fits.values():
            ax.plot(
                fit.x,
                fit.lsf,
                "-",
                lw=1.2,
                color=_colour(fit.fit),
                label=f"{fit.fit}: FWHM {fit.fwhm_px:.3f} px",
            )
            peak = float(np.max(fit.lsf))
            ax.hlines(
                peak / 2,
                fit.centre_px - fit.fwhm_px / 2,
                fit.centre_px + fit.fwhm_px / 2,
                color=_colour(fit.fit),
                lw=0.8,
                ls="--",
            )
        if result.fits:
            ax.legend(loc="upper right", fontsize=7)
        ax.set_xlabel("distance from edge, perpendicular (px)")
        ax.set_ylabel("LSF (1/px)")
        ax.set_title(f"Line spread function — {_status(result)}", fontsize=8)
        return _svg(fig)


def mtf_svg(result: EdgeResult) -> str:
    """MTF of each fit, Nyquist (0.5 cycles/px) marked (step 12)."""
    with mpl.rc_context(_RC):
        fig, ax = _figure()
        for fit in result.fits.values():
            ax.plot(
                fit.mtf_freq,
                fit.mtf,
                "-",
                lw=1.2,
                color=_colour(fit.fit),
                label=f"{fit.fit}: MTF@Ny {fit.mtf_nyquist:.3f}",
            )
            ax.plot([NYQUIST], [fit.mtf_nyquist], "o", ms=4, color=_colour(fit.fit))
        ax.axvline(NYQUIST, ls="--", lw=0.8, color="k")
        ax.text(NYQUIST, 1.02, "Nyquist", fontsize=7, ha="center")
        ax.set_xlim(0, 1.0)
        ax.set_ylim(0, 1.1)
        if result.fits:
            ax.legend(loc="upper right", fontsize=7)
        ax.set_xlabel("spatial frequency (cycles/px)")
        ax.set_ylabel("MTF")
        ax.set_title(f"Modulation transfer function — {_status(result)}", fontsize=8)
        return _svg(fig)


def edge_figures(roi: np.ndarray, result: EdgeResult) -> dict[str, str]:
    """All four figures, keyed by file stem: detection, esf, lsf, mtf."""
    return {
        "detection": detection_svg(roi, result),
        "esf": esf_svg(result),
        "lsf": lsf_svg(result),
        "mtf": mtf_svg(result),
    }


# --- the same figures from plain arrays (the report draws them from qcr.json, without the image)

_SMALL = (4.6, 3.1)  # inches: two figures side by side on an A4 page stay legible


@dataclass(frozen=True, eq=False)
class FitCurves:
    """One fitted ESF/LSF/MTF as stored in qcr.json (``details.edges.<id>.curves.fits``)."""

    fit: str
    x: np.ndarray  # px, perpendicular distance
    esf: np.ndarray  # normalised 0..1
    lsf: np.ndarray  # 1/px
    freq: np.ndarray  # cycles/px
    mtf: np.ndarray
    centre_px: float | None = None
    fwhm_px: float | None = None
    mtf_nyquist: float | None = None


def _small() -> tuple[Figure, Axes]:
    with mpl.rc_context(_RC):
        fig = Figure(figsize=_SMALL, dpi=100, layout="constrained")
        ax = fig.add_subplot(1, 1, 1)
    return fig, ax


def _finite(*arrays: Sequence[float | None] | np.ndarray) -> list[np.ndarray]:
    """Float arrays (None -> NaN) restricted to the positions where all are finite."""
    arrs = [np.array([np.nan if v is None else v for v in a], dtype=float) for a in arrays]
    ok = np.logical_and.reduce([np.isfinite(a) for a in arrs]) if arrs else np.zeros(0, bool)
    return [a[ok] for a in arrs]


def detection_svg_from_arrays(
    kept_x: Sequence[float],
    kept_y: Sequence[float],
    *,
    shape: tuple[int, int],
    rejected_x: Sequence[float] = (),
    rejected_y: Sequence[float] = (),
    fit_x: Sequence[float] = (),
    fit_y: Sequence[float] = (),
    title: str = "Edge detection",
) -> str:
    """Per-line edge locations and the fitted line in the ROI frame, without the image (step 5)."""
    kx, ky = _finite(kept_x, kept_y)
    rx, ry = _finite(rejected_x, rejected_y)
    fx, fy = _finite(fit_x, fit_y)
    with mpl.rc_context(_RC):
        fig, ax = _small()
        if fx.size >= 2:  # under the points, so that they stay visible along it
            ax.plot(fx, fy, "--", lw=0.8, color="tab:green", label="fitted edge line", zorder=2)
        ax.plot(kx, ky, ".", ms=3, color="tab:red", label="edge location per line", zorder=3)
        if rx.size:
            ax.plot(rx, ry, "x", ms=4, color="tab:orange", label="rejected line", zorder=3)
        rows, cols = int(shape[0]), int(shape[1])
        ax.set_xlim(-0.5, cols - 0.5)
        ax.set_ylim(rows - 0.5, -0.5)  # image convention: row 0 at the top
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(title, fontsize=8)
        ax.set_xlabel("x (column, px)")
        ax.set_ylabel("y (row, px)")
        if kx.size or rx.size:
            ax.legend(loc="best", fontsize=6.5)
        return _svg(fig)


def esf_svg_from_arrays(
    d: Sequence[float],
    v: Sequence[float],
    fits: Sequence[FitCurves],
    *,
    dark_start_px: float | None = None,
    bright_start_px: float | None = None,
    title: str = "Edge spread function",
) -> str:
    """Normalised ESF samples and the fitted ESFs, plateau starts marked (steps 6-8)."""
    dd, vv = _finite(d, v)
    with mpl.rc_context(_RC):
        fig, ax = _small()
        if dd.size:
            ax.plot(dd, vv, ".", ms=1.5, color="0.5", label="pixels (decimated)")
        for f in fits:
            x, e = _finite(f.x, f.esf)
            ax.plot(x, e, "-", lw=1.2, color=_colour(f.fit), label=f"{f.fit} fit")
        for start, name, align in (
            (dark_start_px, "dark start ", "right"),
            (bright_start_px, " bright start", "left"),
        ):
            if start is not None:
                ax.axvline(start, ls=":", lw=0.8, color="k")
                ax.text(start, 1.03, name, fontsize=6, ha=align)
        if dd.size or fits:
            ax.legend(loc="lower right", fontsize=6.5)
        ax.set_ylim(-0.12, 1.14)  # room for the plateau-start labels
        ax.set_xlabel("distance from edge, perpendicular (px)")
        ax.set_ylabel("normalised DN")
        ax.set_title(title, fontsize=8)
        return _svg(fig)


def lsf_svg_from_arrays(fits: Sequence[FitCurves], *, title: str = "Line spread function") -> str:
    """LSF of each fit with the FWHM drawn at half its peak (steps 10-11)."""
    with mpl.rc_context(_RC):
        fig, ax = _small()
        for f in fits:
            x, y = _finite(f.x, f.lsf)
            if not x.size:
                continue
            c = _colour(f.fit)
            label = f.fit if f.fwhm_px is None else f"{f.fit}: FWHM {f.fwhm_px:.3f} px"
            ax.plot(x, y, "-", lw=1.2, color=c, label=label)
            if f.fwhm_px is not None:
                mid = f.centre_px if f.centre_px is not None else float(x[int(np.argmax(y))])
                ax.annotate(
                    "",
                    xy=(mid - f.fwhm_px / 2, float(y.max()) / 2),
                    xytext=(mid + f.fwhm_px / 2, float(y.max()) / 2),
                    arrowprops={"arrowstyle": "<->", "color": c, "lw": 0.8},
                )
        if fits:
            ax.legend(loc="upper right", fontsize=6.5)
        ax.set_xlabel("distance from edge, perpendicular (px)")
        ax.set_ylabel("LSF (1/px)")
        ax.set_title(title, fontsize=8)
        return _svg(fig)


def mtf_svg_from_arrays(
    fits: Sequence[FitCurves], *, title: str = "Modulation transfer function"
) -> str:
    """MTF of each fit, Nyquist (0.5 cycles/px) marked with the value there (step 12)."""
    with mpl.rc_context(_RC):
        fig, ax = _small()
        for f in fits:
            q, m = _finite(f.freq, f.mtf)
            if not q.size:
                continue
            c = _colour(f.fit)
            label = f.fit if f.mtf_nyquist is None else f"{f.fit}: MTF@Nyquist {f.mtf_nyquist:.3f}"
            ax.plot(q, m, "-", lw=1.2, color=c, label=label)
            if f.mtf_nyquist is not None:
                ax.plot([NYQUIST], [f.mtf_nyquist], "o", ms=4, color=c)
        ax.axvline(NYQUIST, ls="--", lw=0.8, color="k")
        ax.text(NYQUIST, 1.02, "Nyquist", fontsize=7, ha="center")
        ax.set_xlim(0, 1.0)
        ax.set_ylim(0, 1.1)
        if fits:
            ax.legend(loc="upper right", fontsize=6.5)
        ax.set_xlabel("spatial frequency (cycles/px)")
        ax.set_ylabel("MTF")
        ax.set_title(title, fontsize=8)
        return _svg(fig)
