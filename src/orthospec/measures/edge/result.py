"""What the edge chain returns: health checks, estimates, fitted curves and the result.

Also the vocabulary shared by the steps (fit names, the evaluation grid, the estimator keys
every ``to_dict()`` carries), so that no step imports another step for a constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

NYQUIST = 0.5  # cycles per pixel
SPLINE = "spline"
GRID = 0.01  # px, evaluation grid of fitted curves
MTF_FREQ = np.round(np.arange(0, 101) * 0.01, 10)  # reported MTF curve, cycles/px
PSF_FITS = (
    "gauss",
    "gauss-box",
    "gauss2",
    "gauss-usm",
    "gauss-disk",
    "airy",
    "gauss-mtfc",
)  # the physical models


@dataclass(frozen=True)
class HealthCheck:
    """One step-3 health check: what was measured, the limit, pass/fail and why."""

    name: str
    value: float | None
    op: str  # ">", ">=", "<=", "in"
    limit: float | tuple[float, float]
    unit: str
    passed: bool
    reason: str = ""

    def to_dict(self) -> dict[str, Any]:
        lim = list(self.limit) if isinstance(self.limit, tuple) else self.limit
        return {
            "name": self.name,
            "value": _f(self.value),
            "op": self.op,
            "limit": lim,
            "unit": self.unit,
            "passed": self.passed,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class Estimate:
    """One spatial-quality estimator with its unit and the fit that produced it."""

    name: str
    value: float
    unit: str
    fit: str
    u: float | None = None  # standard uncertainty (same unit), when the fit states one


@dataclass(frozen=True, eq=False)
class EdgeFit:
    """A fitted, normalised ESF (0..1) and what follows from it; curves on a 0.01 px grid."""

    fit: str
    x: np.ndarray  # px, perpendicular distance, dark < 0 < bright
    esf: np.ndarray
    lsf: np.ndarray  # 1/px
    centre_px: float
    mtf_freq: np.ndarray  # cycles/px
    mtf: np.ndarray
    rer: float
    fwhm_px: float
    width25_px: float
    width80_px: float
    mtf_nyquist: float
    edge_slope_per_px: float
    dark_level: float
    bright_level: float
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def effective_resolution_factor(self) -> float:
        """Factor for effective resolution (Passini, Jacobsen & Day; seed 004, section 4).

        "A sudden change of the gray values in object space is causing a continuous change
        of the gray values in a profile perpendicular to the edge. If this gray value
        profile is differentiated, it leads to the point spread function. The width of the
        point spread function leads to the factor for effective resolution (Jacobsen
        2008). This factor multiplied with the pixel size or the GSD leads to the effective
        resolution [...]. By simple theory this factor should not be below 1.0, but by
        image enhancement this can be".

        Read as: factor = width (FWHM) of the differentiated perpendicular profile (our
        LSF) in pixels, divided by the width an ideal sampler gives: a perfect square
        pixel with no blur has a 1-px box LSF, FWHM 1 px, factor 1.0 ("should not be
        below 1.0"); sharpening makes it < 1. Effective GSD = factor x GSD.
        """
        return self.fwhm_px / 1.0


@dataclass(frozen=True, eq=False)
class EdgeResult:
    """Everything the chain measured; estimators only when every health check passed."""

    valid: bool
    reasons: tuple[str, ...]
    checks: tuple[HealthCheck, ...]
    direction: str  # "across" (profile along x / columns) or "along" (profile along y / rows)
    transposed: bool
    polarity: str  # "dark_to_bright" or "bright_to_dark" along increasing x (or y)
    angle_deg: float | None  # edge to the along/across direction, >= 0
    shape: tuple[int, int]
    # per-line edge locations in ROI coordinates (x = column, y = row), and the fitted line
    line_x: np.ndarray
    line_y: np.ndarray
    line_kept: np.ndarray
    fitted_x: np.ndarray  # fitted line at the same points
    fitted_y: np.ndarray
    residual_rms_px: float | None
    # ESF samples (perpendicular distance px, DN) of the kept lines
    esf_d: np.ndarray
    esf_dn: np.ndarray
    dark_level: float | None
    bright_level: float | None
    dark_std: float | None
    bright_std: float | None
    dark_start_px: float | None
    bright_start_px: float | None
    window_px: tuple[float, float] | None
    fits: dict[str, EdgeFit]
    primary_fit: str
    estimates: tuple[Estimate, ...]
    gsd_m: float | None = None
    #: what a reader must know beside a valid result (e.g. an angle beyond the seed's 30 deg)
    warnings: tuple[str, ...] = ()

    def estimate(self, name: str, fit: str | None = None) -> Estimate | None:
        """The estimator ``name`` from ``fit`` (primary fit by default); None if invalid."""
        want = fit or self.primary_fit
        return next((e for e in self.estimates if e.name == name and e.fit == want), None)

    def _value(self, name: str) -> float | None:
        e = self.estimate(name)
        return None if e is None else e.value

    @property
    def rer(self) -> float | None:
        return self._value("rer")

    @property
    def fwhm_px(self) -> float | None:
        return self._value("fwhm_px")

    @property
    def mtf_nyquist(self) -> float | None:
        return self._value("mtf_nyquist")

    @property
    def effective_resolution_factor(self) -> float | None:
        return self._value("effective_resolution_factor")

    def check(self, name: str) -> HealthCheck:
        return next(c for c in self.checks if c.name == name)

    def to_dict(self) -> dict[str, Any]:
        """Flat, JSON-safe values (floats, str, bool, None); NaN becomes None."""
        out: dict[str, Any] = {
            "valid": self.valid,
            "reasons": "; ".join(self.reasons),
            "warnings": "; ".join(self.warnings) or None,
            "direction": self.direction,
            "transposed": self.transposed,
            "polarity": self.polarity,
            "angle_deg": _f(self.angle_deg),
            "lines": int(self.line_kept.size),
            "lines_kept": int(self.line_kept.sum()),
            "residual_rms_px": _f(self.residual_rms_px),
            "dark_level_dn": _f(self.dark_level),
            "bright_level_dn": _f(self.bright_level),
            "dark_std_dn": _f(self.dark_std),
            "bright_std_dn": _f(self.bright_std),
            "dark_start_px": _f(self.dark_start_px),
            "bright_start_px": _f(self.bright_start_px),
            "gsd_m": _f(self.gsd_m),
            "primary_fit": self.primary_fit,
        }
        model = next((self.fits[n] for n in PSF_FITS if n in self.fits), None)
        if model is not None:
            q = model.params
            out["psf_model"] = model.fit
            out["psf_model.sigma_px"] = _f(q["sigma_px"][0])
            out["psf_model.lack_of_fit_f"] = _f(q["lack_of_fit_f"])
            out["psf_model.p_value"] = _f(q["p_value"])
            out["psf_model.adequate"] = bool(q["adequate"])
            out["psf_model.cv_error"] = _f(q.get("cv_error_model"))
            out["spline.cv_error"] = _f(q.get("cv_error_spline"))
            out["psf_model.selection"] = q.get("selection")
            out["psf_model.candidates"] = ", ".join(sorted(q.get("candidates", {}))) or None
        for c in self.checks:
            out[f"check.{c.name}.value"] = _f(c.value)
            out[f"check.{c.name}.unit"] = c.unit
            out[f"check.{c.name}.passed"] = c.passed
        # the contract: every estimator key is present; null with the reason when invalid
        why = "; ".join(self.reasons)
        out["direction_convention"] = DIRECTION_CONVENTION
        for name, unit in ESTIMATORS.items():
            prim = self.estimate(name)
            out[name] = None if prim is None else _f(prim.value)
            out[f"{name}.unit"] = unit
            out[f"{name}.fit"] = None if prim is None else prim.fit
            out[f"{name}.u"] = None if prim is None else _f(prim.u)
            if prim is not None and out[name] is not None:
                out[f"{name}.reason"] = None
            elif not self.valid:
                out[f"{name}.reason"] = f"invalid edge: {why}"
            elif unit == "m" or unit == "1/m":
                out[f"{name}.reason"] = "no GSD given"
            else:
                out[f"{name}.reason"] = "could not be computed from the fit"
            for e in self.estimates:
                if e.name == name and e.fit != self.primary_fit:
                    out[f"{name}.{e.fit}"] = _f(e.value)
        out.update(self.axis_equivalents())
        return out

    def axis_equivalents(self) -> dict[str, float | None]:
        """FWHM, RER and MTF@Nyquist of the primary fit as a tool profiling along an image
        row (x) or column (y) would report them (all estimators here are normal to the edge).

        A row crosses the edge with a perpendicular step |n_x| per pixel (n the unit edge
        normal): widths along it are width / |n_x|, RER = ESF(c + 0.5 |n_x|) - ESF(c - 0.5
        |n_x|), MTF_x(0.5 cy/px) = MTF(0.5 / |n_x|) (null beyond the reported 1 cy/px).
        """
        out: dict[str, float | None] = {}
        fit = self.fits.get(self.primary_fit) if self.valid else None
        theta = math.radians(self.angle_deg) if self.angle_deg is not None else math.nan
        # the profile axis of the working frame is x unless the ROI was transposed
        comps = {"along_row": abs(math.cos(theta)), "along_column": abs(math.sin(theta))}
        if self.transposed:
            comps = {"along_row": comps["along_column"], "along_column": comps["along_row"]}
        for axis, n in comps.items():
            ok = fit is not None and math.isfinite(n) and n > 1e-6
            fw = rer = mtf = None
            if ok and fit is not None:
                fw = _f(fit.fwhm_px / n)
                e = np.interp([fit.centre_px - 0.5 * n, fit.centre_px + 0.5 * n], fit.x, fit.esf)
                rer = _f(e[1] - e[0])
                f_ax = NYQUIST / n
                mtf = (
                    _f(np.interp(f_ax, fit.mtf_freq, fit.mtf)) if f_ax <= fit.mtf_freq[-1] else None
                )
            out[f"fwhm_px.{axis}"] = fw
            out[f"rer.{axis}"] = rer
            out[f"mtf_nyquist.{axis}"] = mtf
        return out


DIRECTION_CONVENTION = (
    "widths, RER, slope and MTF are measured along the edge normal (perpendicular distance "
    "from the fitted edge line, cycles per pixel along the normal); *.along_row / "
    "*.along_column give the same response as seen along an image row (x) / column (y)"
)
ESTIMATORS = {  # name -> unit: the keys every to_dict() carries (null when not measured)
    "rer": "1",
    "fwhm_px": "px",
    "width25_px": "px",
    "width80_px": "px",
    "mtf_nyquist": "1",
    "edge_slope_per_px": "1/px",
    "effective_resolution_factor": "1",
    "overshoot_h": "1",
    "fwhm_m": "m",
    "width25_m": "m",
    "width80_m": "m",
    "edge_slope_per_m": "1/m",
    "effective_gsd_m": "m",
}


def _f(x: Any) -> Any:
    """A JSON-safe float: None for None, NaN and infinities."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None
