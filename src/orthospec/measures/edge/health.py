"""Seed step 3: the health checks of an edge ROI, against :class:`EdgeLimits`.

Every check reports what was measured, the limit, pass/fail and why; a failed check makes the
edge invalid (no estimator reported), it never raises.
"""

from __future__ import annotations

import math

from .esf import Areas
from .limits import EdgeLimits
from .locate import EdgeLine
from .result import SPLINE, EdgeFit, HealthCheck


def health_checks(line: EdgeLine, areas: Areas, fits: dict[str, EdgeFit], quant: float,
                  lim: EdgeLimits) -> tuple[HealthCheck, ...]:
    """Step 3a-f (and the added checks) on the located line, the uniform areas and the fits."""
    n_rows = line.rows.size
    contrast = areas.levels[1] - areas.levels[0]
    return (
        _chk("edge_length", line.n_kept, ">=", lim.min_edge_length_px, "px",
             "too few lines with a detectable edge"),
        _chk("straightness", line.max_residual_px if line.ok else None, "<=", lim.max_straightness_px,
             "px", "per-line edge locations do not lie on one straight line"),
        _chk("outliers", (1 - line.n_kept / n_rows) if n_rows else None, "<=",
             lim.max_outlier_fraction, "1", "too many lines rejected as outliers"),
        _chk("angle", line.angle_deg, "in", (0.0, lim.max_angle_deg), "deg",
             "edge angle to the along/across direction out of range"),
        _chk("sampling", areas.gap, "<=", lim.max_sampling_gap_px, "px",
             "the lines sample the ESF too coarsely near the edge (edge too close to 0 or 45 deg, "
             "or to a slope p/q repeated by too few lines)"),
        _chk("contrast", contrast, ">", lim.min_contrast_dn, "DN",
             "DN difference between bright and dark too small"),
        _chk("snr", snr(contrast, areas.stds, quant), ">", lim.min_snr, "1",
             "bright/dark areas not uniform or too noisy: SNR = dDN / mean(std) too low"),
        _chk("saturation", areas.saturated, "<=", lim.max_saturated_fraction, "1",
             "saturated (or zero-filled) pixels in the bright or dark area"),
        _chk("dark_width", areas.widths[0], ">", lim.min_plateau_width_px, "px", "dark area too narrow"),
        _chk("bright_width", areas.widths[1], ">", lim.min_plateau_width_px, "px",
             "bright area too narrow"),
        _chk("fit", float(SPLINE in fits), ">=", 1.0, "1",
             "the ESF could not be fitted (no plateau or no transition found)"),
    )


def snr(contrast: float, stds: tuple[float, float], quant: float) -> float:
    """Seed 3b: SNR = dDN / ((std_bright + std_dark) / 2).

    Noise floor: the quantisation noise q / sqrt(12) of integer DNs, else 1e-6 of the
    contrast, so that a noise-free edge has a finite SNR (JSON-safe, check consistent).
    """
    noise = max((stds[0] + stds[1]) / 2.0, quant / math.sqrt(12.0), 1e-6 * abs(contrast))
    return contrast / noise if noise > 0 else math.nan


def _chk(name: str, value: float | None, op: str, limit: float | tuple[float, float],
         unit: str, why: str) -> HealthCheck:
    val = None if value is None or (isinstance(value, float) and math.isnan(value)) else float(value)
    if val is None:
        return HealthCheck(name, None, op, limit, unit, False, f"not measurable; {why}")
    if op == "in":
        lo, hi = limit  # type: ignore[misc]
        ok = lo <= val <= hi
        text = f"{val:.4g} {unit} not in [{lo:g}, {hi:g}]"
    else:
        lim = float(limit)  # type: ignore[arg-type]
        ok = {">": val > lim, ">=": val >= lim, "<=": val <= lim}[op]
        text = f"{val:.4g} {unit} is not {op} {lim:g}"
    return HealthCheck(name, val, op, limit, unit, bool(ok), "" if ok else f"{text}; {why}")
