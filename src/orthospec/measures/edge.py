"""Spatial quality from an edge target: the CEOS WGCV IVOS 12-step method.

Source: seed ``003_ceb4b69be8905903.txt`` (Lee & Helder 2015, "Edge target for
Spatial Quality", processing steps [RD5]); RER two-direction form from seed
``000_64edc9235d9ff7d6.txt`` (USGS); effective resolution from seed
``004_0930f95275292898.txt`` (Passini, Jacobsen, Day). ``docs/edge-method.md``
explains every choice where the seed says TBD/TBR/TBC.

The chain (seed step in brackets) on a 2-D ROI holding one straight edge:

* orientation [4a]: the ROI is transposed so that the edge runs near the
  columns (profile along x), and mirrored so that dark is left, bright right
  [4b]. Everything below runs in that working frame, so results do not depend
  on edge polarity or on transposing the image.
* per line [5a-c]: largest adjacent difference, cubic through the four pixels
  around it, edge at the cubic's inflection point.
* robust line [5d-f]: least squares of all locations, iteratively rejecting
  lines beyond 3 robust sigmas (1.4826 MAD, floor 0.05 px); angle to the
  along/across direction.
* ESF [6]: every pixel of the kept lines at its *perpendicular* distance
  ``d = (x - x_edge(y)) cos(theta)`` from the fitted line.
* plateaus [7]: cubic smoothing spline of the binned ESF; the starts of the dark
  and bright plateaus are the LSF's inflection points (extrema of ESF'');
  the uniform areas begin at 3x the start's distance from the centre (>= 1 px
  beyond it) or where the LSF falls below 2 % of its peak, whichever is further;
  the ESF is trimmed at max(``plateau_px``, 3x the start's distance, 1 px into
  the uniform area) beyond each start; the dark/bright levels and the
  uniformity (SNR) come from the uniform areas.
* fits [8]: a physical model (added): the PSF (Gaussian, Gaussian x box, or core +
  halo) integrated over the square pixel at the measured angle, primary when its
  lack-of-fit F test passes (else the spline); non-parametric (scipy ``make_smoothing_spline``, GCV, on the ESF
  binned at 1/``oversample`` px, weighted by counts) and parametric (sum of
  Fermi-Dirac functions); both normalised 0..1.
* RER [9] at +-0.5 px around the centre (LSF peak for the spline, ESF = 0.5
  for the parametric fit, as the seed says); LSF [10] by differentiation;
  FWHM and widths at 25 % / 80 % [11]; MTF [12] by FFT of the LSF normalised
  at zero frequency, value at Nyquist (0.5 cycles/px).

Health checks [3] fail with their measured values; then ``valid`` is False and
no estimator is reported. Only malformed input raises :class:`MeasureError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, stats
from scipy.interpolate import make_smoothing_spline

from ..errors import MeasureError
from .psf import footprint, gauss_boxes_esf, gauss_boxes_esf_dsigma, gauss_boxes_lsf

__all__ = [
    "EdgeFit",
    "EdgeResult",
    "Estimate",
    "HealthCheck",
    "measure_edge",
    "rer_two_directions",
]

NYQUIST = 0.5  # cycles per pixel
SPLINE = "spline"
_GRID = 0.01  # px, evaluation grid of fitted curves
_MTF_FREQ = np.round(np.arange(0, 101) * 0.01, 10)  # reported MTF curve, cycles/px


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
        return {"name": self.name, "value": _f(self.value), "op": self.op, "limit": lim,
                "unit": self.unit, "passed": self.passed, "reason": self.reason}


@dataclass(frozen=True)
class Estimate:
    """One spatial-quality estimator with its unit and the fit that produced it."""

    name: str
    value: float
    unit: str
    fit: str


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
            if ok:
                fw = _f(fit.fwhm_px / n)
                e = np.interp([fit.centre_px - 0.5 * n, fit.centre_px + 0.5 * n], fit.x, fit.esf)
                rer = _f(e[1] - e[0])
                f_ax = NYQUIST / n
                mtf = _f(np.interp(f_ax, fit.mtf_freq, fit.mtf)) if f_ax <= fit.mtf_freq[-1] else None
            out[f"fwhm_px.{axis}"] = fw
            out[f"rer.{axis}"] = rer
            out[f"mtf_nyquist.{axis}"] = mtf
        return out


DIRECTION_CONVENTION = (
    "widths, RER, slope and MTF are measured along the edge normal (perpendicular distance "
    "from the fitted edge line, cycles per pixel along the normal); *.along_row / "
    "*.along_column give the same response as seen along an image row (x) / column (y)")
ESTIMATORS = {  # name -> unit: the keys every to_dict() carries (null when not measured)
    "rer": "1", "fwhm_px": "px", "width25_px": "px", "width80_px": "px", "mtf_nyquist": "1",
    "edge_slope_per_px": "1/px", "effective_resolution_factor": "1", "overshoot_h": "1",
    "fwhm_m": "m", "width25_m": "m", "width80_m": "m", "edge_slope_per_m": "1/m",
    "effective_gsd_m": "m",
}


def rer_two_directions(rer_x: Any, rer_y: Any) -> np.ndarray:
    """USGS RER = sqrt(RER_x * RER_y), the geometric mean of the two directions (seed 000).

    "RER is a geometric mean of normalized edge response differences measured in two
    directions of image pixels (X and Y) at points distanced from the edge by -0.5 and
    0.5 GSD: RER = sqrt([ERx(0.5) - ERx(-0.5)][ERy(0.5) - ERy(-0.5)])".
    """
    x = np.asarray(rer_x, dtype=float)
    y = np.asarray(rer_y, dtype=float)
    if np.any(x < 0) or np.any(y < 0):
        raise MeasureError("RER values must be >= 0 to take their geometric mean")
    return np.sqrt(x * y)


# ----------------------------------------------------------------------------------------
# the chain


def measure_edge(
    roi: np.ndarray,
    *,
    gsd: float | None = None,
    nodata: float | None = None,
    bit_depth: int | None = None,
    saturation_dn: tuple[float | None, float | None] | None = None,
    min_snr: float = 50.0,
    min_contrast_dn: float = 50.0,
    max_angle_deg: float = 30.0,
    min_edge_length_px: int = 20,
    min_plateau_width_px: float = 5.0,
    max_straightness_px: float = 1.0,
    max_outlier_fraction: float = 0.2,
    min_supersampling: float = 0.8,
    max_saturated_fraction: float = 0.01,
    plateau_px: float = 1.0,
    oversample: int = 10,
    fermi_terms: int = 3,
    refine_line: bool = True,
    primary: str = "auto",
) -> EdgeResult:
    """Run the CEOS 12-step edge chain on one ROI.

    Parameters
    ----------
    roi
        2-D array (rows, columns) holding one straight edge; NaN (or ``nodata``)
        pixels are ignored.
    gsd
        Ground sample distance in metres per pixel; adds metre-valued estimators.
    bit_depth, saturation_dn
        Saturation levels (low, high) in DN. Default: low 0 and high
        ``2**bit_depth - 1``, or the integer dtype's maximum.
    min_snr, min_contrast_dn, max_angle_deg, min_edge_length_px, min_plateau_width_px
        Step-3 limits of the seed (SNR > 50, DN difference > 50, 0-30 deg,
        > 10-20 px -> 20 by default, > 5 px).
    max_straightness_px, max_outlier_fraction
        Straightness: the largest residual of a kept line from the fitted line
        (seed: "by one pixel") and the share of lines rejected as outliers.
    min_supersampling
        Share of 1/``oversample`` px ESF bins within +-2 px of the edge that
        hold samples; fails for an edge too close to 0 deg to super-sample.
    plateau_px
        Least distance beyond each plateau start kept in the trimmed ESF (seed step 7b,
        "1 pixel (TBR)"); the trim reaches at least 3x the start's distance further out.
    fermi_terms
        Number of Fermi-Dirac terms of the parametric fit (1 = plain Fermi-Dirac).
    primary
        Which fit gives the reported estimators: ``"auto"`` (the physical PSF model when
        its chi2 test says it describes the ESF, else the spline), ``"spline"`` (always
        the model-free fit) or ``"model"`` (the PSF model even when the test rejects it).
    refine_line
        Refine the step-5 line (offset and slope) by one least-squares fit of a Fermi-Dirac
        edge to all pixels within 5 px of it (added step, see docs); False keeps the
        seed's line of per-line cubic locations.

    Returns
    -------
    EdgeResult

    Raises
    ------
    MeasureError
        When ``roi`` is not a 2-D numeric array of at least 5 x 5 pixels with finite values.
    """
    if primary not in _PRIMARY:
        raise MeasureError(f"primary must be one of {', '.join(_PRIMARY)}, got {primary!r}")
    arr = np.asarray(roi)
    if arr.ndim != 2:
        raise MeasureError(f"edge ROI must be a 2-D array, got {arr.ndim} dimension(s) {arr.shape}")
    if min(arr.shape) < 5:
        raise MeasureError(f"edge ROI {arr.shape[1]} x {arr.shape[0]} px is too small; "
                           "expected at least 5 x 5 px (and > 20 lines to pass the checks)")
    if not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise MeasureError(f"edge ROI must be numeric, got dtype {arr.dtype}")
    sat_lo, sat_hi = _saturation(arr.dtype, bit_depth, saturation_dn)
    # DN step of quantised data (integer DNs): its noise floor q / sqrt(12) never averages out
    quant = 1.0 if (bit_depth is not None or np.issubdtype(arr.dtype, np.integer)) else 0.0
    img = arr.astype(float)
    if nodata is not None:
        img[img == nodata] = np.nan
    if not np.isfinite(img).any():
        raise MeasureError("edge ROI has no finite pixels")
    if gsd is not None and not (math.isfinite(gsd) and gsd > 0):
        raise MeasureError(f"gsd must be a positive number of metres per pixel, got {gsd!r}")

    # step 4a: along/across; 4b: bright/dark side -> working frame (edge ~ vertical, dark left)
    ex = np.nansum(np.diff(img, axis=1) ** 2)
    ey = np.nansum(np.diff(img, axis=0) ** 2)
    transposed = bool(ey > ex)
    work = img.T if transposed else img
    mirrored = bool(np.nansum(np.diff(work, axis=1)) < 0)
    if mirrored:
        work = work[:, ::-1]
    work = np.ascontiguousarray(work)
    direction = "along" if transposed else "across"
    polarity = "bright_to_dark" if mirrored else "dark_to_bright"
    ncol = work.shape[1]

    def to_roi(r: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Working (row, col) -> ROI (x, y)."""
        cc = (ncol - 1) - c if mirrored else c
        return (r, cc) if transposed else (cc, r)

    # step 5a-c: per-line edge location
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
    n_kept = int(kept.sum())
    line_ok = n_kept >= 3 and math.isfinite(c1)
    if line_ok and refine_line:
        c0, c1 = _refine_line(work, rows[kept], c0, c1)
    theta = math.atan(c1) if line_ok else math.nan
    angle = abs(math.degrees(theta)) if line_ok else None

    lx, ly = to_roi(rows.astype(float), locs)
    fit_c = c0 + c1 * rows if line_ok else np.full(rows.size, np.nan)
    fx, fy = to_roi(rows.astype(float), fit_c)

    # step 6: ESF samples at perpendicular distance
    d = np.empty(0)
    v = np.empty(0)
    row_dmin = row_dmax = np.empty(0)
    if line_ok:
        kr = rows[kept]
        cols = np.arange(ncol, dtype=float)
        dd = (cols[None, :] - (c0 + c1 * kr[:, None])) * math.cos(theta)
        vv = work[kr, :]
        fin = np.isfinite(vv)
        d, v = dd[fin], vv[fin]
        row_dmin = np.where(fin, dd, np.inf).min(axis=1)
        row_dmax = np.where(fin, dd, -np.inf).max(axis=1)
        order = np.argsort(d, kind="stable")
        d, v = d[order], v[order]

    # step 7: plateau starts from a first spline fit
    dark_start = bright_start = math.nan
    window: tuple[float, float] | None = None
    fits: dict[str, EdgeFit] = {}
    levels = (math.nan, math.nan)
    stds = (math.nan, math.nan)
    sat_frac = math.nan
    coverage = math.nan
    widths = (math.nan, math.nan)
    if d.size >= 20:
        bw = 1.0 / oversample
        coverage = _coverage(d, bw, 2.0)
        first = _spline(d, v, bw, -12.0, 12.0)
        if first is not None:
            dark_start, bright_start = _plateau_starts(first, d)
        if math.isfinite(dark_start) and math.isfinite(bright_start):
            # the uniform areas begin at 3x the start's distance from the centre (>= 1 px
            # beyond it; at the LSF inflection a Gaussian's ESF tail still holds ~16 % of
            # the step, at 3 sigma 0.1 %), or further out where the LSF has a long tail
            # (below 2 % of its peak only there)
            centre = 0.5 * (dark_start + bright_start)
            tail_d, tail_b = _tail_ends(first, d, dark_start, bright_start)
            dark_edge = centre + min(3.0 * (dark_start - centre), dark_start - centre - 1.0)
            bright_edge = centre + max(3.0 * (bright_start - centre), bright_start - centre + 1.0)
            if math.isfinite(tail_d):
                dark_edge = min(dark_edge, tail_d)
            if math.isfinite(tail_b):
                bright_edge = max(bright_edge, tail_b)
            # trim (7b-c): keep at least plateau_px beyond each start, at least 4x the
            # start's distance from the centre, and 1 px of uniform area (tails not cut)
            lo = max(min(dark_start - plateau_px, centre + 4.0 * (dark_start - centre),
                         dark_edge - 1.0), float(d[0]))
            hi = min(max(bright_start + plateau_px, centre + 4.0 * (bright_start - centre),
                         bright_edge + 1.0), float(d[-1]))
            window = (lo, hi)
            dark_side = d <= dark_edge
            bright_side = d >= bright_edge
            dsel = dark_side & (d >= lo)
            bsel = bright_side & (d <= hi)
            if dsel.any() and bsel.any():
                levels = (float(v[dsel].mean()), float(v[bsel].mean()))
            if dark_side.sum() > 1 and bright_side.sum() > 1:
                stds = (float(v[dark_side].std(ddof=1)), float(v[bright_side].std(ddof=1)))
                sat_frac = max(_saturated(v[dark_side], sat_lo, sat_hi),
                               _saturated(v[bright_side], sat_lo, sat_hi))
            widths = (float(np.median(dark_start - row_dmin)),
                      float(np.median(row_dmax - bright_start)))
            if all(math.isfinite(x) for x in levels) and levels[1] > levels[0]:
                sel = (d >= lo) & (d <= hi)
                fermi = _fermi_fit(d[sel], v[sel], bw, lo, hi, levels, fermi_terms)
                if fermi is not None:
                    fits[fermi.fit] = fermi
                local = _within_bin_std(d[dsel | bsel], v[dsel | bsel], bw)
                spl = _spline(d[sel], v[sel], bw, lo, hi, noise=local)
                if spl is not None:
                    fits[SPLINE] = _spline_fit(spl, lo, hi, levels, bw)
                if angle is not None:
                    model = _psf_fit(d[sel], v[sel], bw, lo, hi, levels, angle,
                                     sigma0=0.5 * (bright_start - dark_start), quant=quant)
                    if model is not None:
                        fits[model.fit] = model

    contrast = levels[1] - levels[0]
    # noise floor: the quantisation noise q / sqrt(12) of integer DNs, else 1e-6 of the
    # contrast, so that a noise-free edge has a finite SNR (JSON-safe, check consistent)
    noise = max((stds[0] + stds[1]) / 2.0, quant / math.sqrt(12.0), 1e-6 * abs(contrast))
    snr = contrast / noise if noise > 0 else math.nan

    # step 3: health checks
    checks = (
        _chk("edge_length", n_kept, ">=", min_edge_length_px, "px",
             "too few lines with a detectable edge"),
        _chk("straightness", max_resid if line_ok else None, "<=", max_straightness_px, "px",
             "per-line edge locations do not lie on one straight line"),
        _chk("outliers", (1 - n_kept / rows.size) if rows.size else None, "<=",
             max_outlier_fraction, "1", "too many lines rejected as outliers"),
        _chk("angle", angle, "in", (0.0, max_angle_deg), "deg",
             "edge angle to the along/across direction out of range"),
        _chk("supersampling", coverage, ">=", min_supersampling, "1",
             "ESF bins near the edge left empty (edge too close to 0 deg or too short)"),
        _chk("contrast", contrast, ">", min_contrast_dn, "DN",
             "DN difference between bright and dark too small"),
        _chk("snr", snr, ">", min_snr, "1",
             "bright/dark areas not uniform or too noisy: SNR = dDN / mean(std) too low"),
        _chk("saturation", sat_frac, "<=", max_saturated_fraction, "1",
             "saturated (or zero-filled) pixels in the bright or dark area"),
        _chk("dark_width", widths[0], ">", min_plateau_width_px, "px", "dark area too narrow"),
        _chk("bright_width", widths[1], ">", min_plateau_width_px, "px",
             "bright area too narrow"),
        _chk("fit", float(SPLINE in fits), ">=", 1.0, "1",
             "the ESF could not be fitted (no plateau or no transition found)"),
    )
    reasons = tuple(f"{c.name}: {c.reason}" for c in checks if not c.passed)
    valid = not reasons

    estimates: tuple[Estimate, ...] = ()
    chosen = _choose_primary(fits, primary)
    if valid:
        ordered = sorted(fits.values(), key=lambda f: (f.fit != chosen, f.fit))  # primary first
        estimates = tuple(e for f in ordered for e in _estimates_of(f, gsd))
        if any(not math.isfinite(e.value) for e in estimates if e.fit == SPLINE):
            bad = [e.name for e in estimates if e.fit == SPLINE and not math.isfinite(e.value)]
            valid = False
            reasons = (f"estimators: could not be computed ({', '.join(bad)})",)
            estimates = ()
        else:
            estimates = tuple(e for e in estimates if math.isfinite(e.value))

    return EdgeResult(
        valid=valid, reasons=reasons, checks=checks, direction=direction,
        transposed=transposed, polarity=polarity, angle_deg=angle,
        shape=(int(arr.shape[0]), int(arr.shape[1])),
        line_x=lx, line_y=ly, line_kept=kept, fitted_x=fx, fitted_y=fy,
        residual_rms_px=resid_rms if line_ok else None,
        esf_d=d, esf_dn=v,
        dark_level=_opt(levels[0]), bright_level=_opt(levels[1]),
        dark_std=_opt(stds[0]), bright_std=_opt(stds[1]),
        dark_start_px=_opt(dark_start), bright_start_px=_opt(bright_start),
        window_px=window, fits=fits, primary_fit=chosen, estimates=estimates, gsd_m=gsd,
    )


# ----------------------------------------------------------------------------------------
# steps

_PRIMARY = ("auto", "spline", "model")


def _choose_primary(fits: dict[str, EdgeFit], primary: str) -> str:
    """The spline unless the PSF model is asked for, or (auto) passed its chi2 test."""
    model = next((fits[n] for n in PSF_FITS if n in fits), None)
    if model is None or primary == "spline":
        return SPLINE
    if primary == "model" or model.params.get("adequate"):
        return model.fit
    cv_m, cv_s = model.params.get("cv_error_model"), model.params.get("cv_error_spline")
    if cv_m is not None and cv_s is not None and cv_m <= cv_s:
        return model.fit
    return SPLINE


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
        return a + b * _logistic(d / s) - vs

    p0 = np.array([c0 + c1 * ym, c1, lo, hi - lo, 0.5])
    try:
        res = optimize.least_squares(resid, p0, x_scale=np.array([1.0, 0.01, hi - lo, hi - lo, 0.5]),
                                     max_nfev=200)
    except (ValueError, np.linalg.LinAlgError):
        return c0, c1
    k0, k1 = float(res.x[0]), float(res.x[1])
    new0 = k0 - k1 * ym
    span = float(ys.max() - ys.min())
    moved = max(abs(new0 - c0 + (k1 - c1) * y) for y in (ys.min(), ys.max()))
    if not (res.status > 0 and np.all(np.isfinite(res.x)) and res.x[4] > 0 and moved <= 1.0
            and span > 0):
        return c0, c1
    return new0, k1


def _within_bin_std(d: np.ndarray, v: np.ndarray, bw: float) -> float:
    """Pooled scatter of the pixels about their ESF-bin means: the noise the ESF fit sees
    (local to the edge, unlike the whole-side std of the SNR check)."""
    if d.size < 3:
        return math.nan
    idx = _bin_index(d, bw)
    n = np.bincount(idx)
    mean = np.bincount(idx, weights=v) / np.maximum(n, 1)
    dof = int(d.size - np.count_nonzero(n))
    if dof < 2:
        return math.nan
    return float(np.sqrt(np.sum((v - mean[idx]) ** 2) / dof))


def _bin_index(d: np.ndarray, bw: float) -> np.ndarray:
    """Bins of ``bw`` px centred on multiples of bw (symmetric about 0), counted from 0."""
    idx = np.floor(d / bw + 0.5).astype(np.int64)
    return idx - idx.min()


def _bins(d: np.ndarray, v: np.ndarray, bw: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bin the ESF at ``bw`` px: mean distance, mean value and count of each non-empty bin."""
    idx = _bin_index(d, bw)
    n = np.bincount(idx)
    sd = np.bincount(idx, weights=d)
    sv = np.bincount(idx, weights=v)
    nz = n > 0
    return sd[nz] / n[nz], sv[nz] / n[nz], n[nz].astype(float)


def _coverage(d: np.ndarray, bw: float, half: float) -> float:
    """Share of bins within +-half px of the edge that hold at least one sample."""
    sel = np.abs(d) <= half
    nb = round(2 * half / bw) + 1
    if not sel.any():
        return 0.0
    idx = np.floor(d[sel] / bw + 0.5).astype(np.int64)
    return float(np.unique(idx).size / nb)


_TAIL = 0.02  # the uniform areas begin where the LSF is below 2 % of its peak
_CHI2_TRIGGER = 0.1  # GCV fits below this interpolate noise (seen: 0.07; normal: 0.2-1)
_CHI2_TARGET = 0.4  # where such a fit is moved to (typical chi2 / bins of good fits)


def _spline(d: np.ndarray, v: np.ndarray, bw: float, lo: float, hi: float,
            noise: float = math.nan) -> Any:
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
    xb, yb, nb = _bins(d[sel], v[sel], bw)
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


def _plateau_starts(spl: Any, d: np.ndarray) -> tuple[float, float]:
    """Seed 7a: LSF inflection points (extrema of ESF'') either side of the LSF peak."""
    lo, hi = max(float(d[0]), -12.0), min(float(d[-1]), 12.0)
    x = np.arange(lo, hi + _GRID / 2, _GRID)
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


def _tail_ends(spl: Any, d: np.ndarray, dark_start: float, bright_start: float,
               frac: float = _TAIL) -> tuple[float, float]:
    """First points beyond the plateau starts where the first-pass LSF falls below ``frac``
    of its peak (NaN if it never does within the data / 12 px)."""
    lo, hi = max(float(d[0]), -12.0), min(float(d[-1]), 12.0)
    x = np.arange(lo, hi + _GRID / 2, _GRID)
    lsf = spl.derivative(1)(x)
    between = (x >= dark_start) & (x <= bright_start)
    if not between.any():
        return math.nan, math.nan
    thr = frac * float(lsf[between].max())
    left = np.flatnonzero((x < dark_start) & (lsf < thr))
    right = np.flatnonzero((x > bright_start) & (lsf < thr))
    # a sharpened edge rings: a negative LSF lobe (over/undershoot) right after the
    # transition is part of the edge response, not of the uniform area
    reach = round(3.0 / _GRID)
    tail_b = math.nan
    if right.size:
        i = int(right[0])
        neg = np.flatnonzero(lsf[i:i + reach] < -thr)
        if neg.size:
            j = i + int(neg[0])
            while j + 1 < x.size and lsf[j + 1] < -thr:
                j += 1
            i = j + 1 if j + 1 < x.size else j
        tail_b = float(x[i])
    tail_d = math.nan
    if left.size:
        i = int(left[-1])
        neg = np.flatnonzero(lsf[max(i - reach, 0):i + 1][::-1] < -thr)
        if neg.size:
            j = i - int(neg[0])
            while j - 1 >= 0 and lsf[j - 1] < -thr:
                j -= 1
            i = j - 1 if j > 0 else j
        tail_d = float(x[i])
    return tail_d, tail_b


def _spline_fit(spl: Any, lo: float, hi: float, levels: tuple[float, float],
                bw: float) -> EdgeFit:
    dark, bright = levels
    x = np.arange(lo, hi + _GRID / 2, _GRID)
    esf = (spl(x) - dark) / (bright - dark)
    lsf = spl.derivative(1)(x) / (bright - dark)
    centre = float(x[np.argmax(lsf)])  # seed 9b: the LSF top is the RER centre

    def esf_at(p: np.ndarray) -> np.ndarray:
        return (spl(p) - dark) / (bright - dark)

    return _make_fit(SPLINE, x, esf, lsf, centre, esf_at, levels,
                     {"bin_px": bw, "smoothing": "GCV, weights = samples per bin"})


def _fermi(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    a = p[0]
    out = np.full_like(x, a, dtype=float)
    for b, c, s in p[1:].reshape(-1, 3):
        out += b * _logistic((x - c) / s)
    return out


def _dfermi(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    out = np.zeros_like(x, dtype=float)
    for b, c, s in p[1:].reshape(-1, 3):
        out += b / (4.0 * s) / np.cosh(0.5 * (x - c) / s) ** 2
    return out


def _logistic(z: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * z))


def _fermi_fit(d: np.ndarray, v: np.ndarray, bw: float, lo: float, hi: float,
               levels: tuple[float, float], terms: int) -> EdgeFit | None:
    """Parametric ESF: a + sum_i b_i / (1 + exp(-(x - c_i) / s_i)) (Fermi-Dirac terms)."""
    xb, yb, nb = _bins(d, v, bw)
    dark, bright = levels
    span = bright - dark

    sw = np.sqrt(nb)

    def jac(p: np.ndarray) -> np.ndarray:
        cols = [sw]
        for b, c, s in p[1:].reshape(-1, 3):
            z = (xb - c) / s
            lg = _logistic(z)
            dl = lg * (1.0 - lg)
            cols += [lg * sw, -b * dl / s * sw, -b * dl * z / s * sw]
        return np.column_stack(cols)

    def fit(p0: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
        try:
            res = optimize.least_squares(
                lambda p: (_fermi(xb, p) - yb) * sw, np.clip(p0, lower, upper),
                jac=jac, bounds=(lower, upper), x_scale="jac", max_nfev=1000)
        except (ValueError, np.linalg.LinAlgError):
            return None
        return res.x if res.status >= 0 and np.all(np.isfinite(res.x)) else None

    big = 10 * abs(span) + 1
    p1 = fit(np.array([dark, span, 0.0, 0.5]),
             np.array([dark - big, 0.0, lo, 0.02]), np.array([bright + big, 3 * big, hi, 10.0]))
    if p1 is None:
        return None
    p, name = p1, "fermi"
    if terms > 1:
        cs = np.linspace(-0.3, 0.3, terms) * p1[3] + p1[2]
        ss = p1[3] * np.geomspace(0.6, 1.6, terms)
        p0 = np.concatenate([[p1[0]], np.column_stack([np.full(terms, p1[1] / terms), cs, ss]).ravel()])
        lower = np.concatenate([[dark - big], np.tile([0.0, lo, 0.1], terms)])
        upper = np.concatenate([[bright + big], np.tile([1.2 * span, hi, 10.0], terms)])
        pn = fit(p0, lower, upper)
        # a term narrower than 0.05 px with a visible step is a spike fitted to noise
        if pn is not None and not np.any((pn[3::3] < 0.05) & (np.abs(pn[1::3]) > 0.05 * span)):
            p, name = pn, f"fermi{terms}"
    a = float(p[0])
    b_tot = float(p[1::3].sum()) if name != "fermi" else float(p[1])
    if b_tot <= 0:
        return None
    x = np.arange(lo, hi + _GRID / 2, _GRID)

    def esf_at(q: np.ndarray) -> np.ndarray:
        return (_fermi(np.asarray(q, dtype=float), p) - a) / b_tot

    esf = esf_at(x)
    lsf = np.zeros_like(x)
    for b, c, s in p[1:].reshape(-1, 3):
        z = (x - c) / s
        lsf += b / (4.0 * s) / np.cosh(0.5 * z) ** 2
    lsf /= b_tot
    # seed 9d: for a parametric ESF the RER centre is 0.5 on the normalised DN
    try:
        centre = float(optimize.brentq(lambda q: float(esf_at(np.array([q]))[0]) - 0.5, lo, hi))
    except ValueError:
        centre = float(x[np.argmax(lsf)])
    return _make_fit(name, x, esf, lsf, centre, esf_at, (a, a + b_tot),
                     {"terms": (p.size - 1) // 3, "params": [float(q) for q in p]})


_ADEQUATE_P = 1e-3  # lack-of-fit p-value below which the PSF model does not describe the ESF
_RICHER_P = 1e-3  # likelihood-ratio p-value needed to prefer a richer PSF model
PSF_FITS = ("gauss", "gauss-box", "gauss2", "gauss-usm", "gauss-disk")
_MODEL_TEXT = {
    "gauss": "Gaussian PSF x square pixel at the edge angle",
    "gauss-box": "Gaussian PSF x box (defocus/motion smear) x square pixel at the edge angle",
    "gauss2": "two Gaussian PSFs (core and halo, the halo may be shifted) x square pixel",
    "gauss-usm": "Gaussian PSF x square pixel, sharpened by an unsharp mask (1 + k) - k G(sigma_m)",
    "gauss-disk": "Gaussian PSF x uniform disk (defocus) x square pixel at the edge angle",
}
# a uniform disk of radius R projects on a line to the semicircle density
# (2 / (pi R^2)) sqrt(R^2 - u^2); Gauss-Chebyshev (2nd kind) nodes u_i = R cos t_i,
# t_i = i pi / 13, weights 2/13 sin^2 t_i integrate it (ESF error < 1e-8 for sigma 0.5, R 2;
# < 1e-4 down to sigma 0.2)
_DISK_T = np.arange(1, 13) * np.pi / 13
_DISK_U = np.cos(_DISK_T)
_DISK_W = 2.0 / 13 * np.sin(_DISK_T) ** 2


def _components(kind: str, q: np.ndarray) -> list[tuple[float, float, float, float]]:
    """(sigma px, weight, shift px, extra box width px) of each PSF component, shape params q."""
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
    return [(float(q[0]), float(q[2]), 0.0, 0.0), (float(q[1]), 1.0 - float(q[2]), float(q[3]), 0.0)]


def _per_component(fn: Any, x: np.ndarray, c: float, comps: list[tuple[float, float, float, float]],
                   fp: tuple[float, float]) -> list[np.ndarray]:
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
            out[i] = vals[j * n:(j + 1) * n]
    return out  # type: ignore[return-value]


def _model_esf(kind: str, x: np.ndarray, p: np.ndarray, fp: tuple[float, float]) -> np.ndarray:
    """a + b * sum_k w_k ESF_k(x - c - shift_k): PSF components x the pixel footprint ``fp``."""
    a, b, c = p[0], p[1], p[2]
    comps = _components(kind, p[3:])
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
    comps = _components(kind, q)
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


def _psf_fit(d: np.ndarray, v: np.ndarray, bw: float, lo: float, hi: float,
             levels: tuple[float, float], angle_deg: float, sigma0: float,
             quant: float = 0.0) -> EdgeFit | None:
    """Physical ESF model: the PSF integrated over the square pixel at the measured angle
    (closed forms, ``psf.py``), the PSF being one Gaussian, a Gaussian smeared by a box
    (defocus, motion: a flat-topped LSF) or two Gaussians (core and halo).

    Why: the non-parametric spline spends its freedom on noise; a model with the pixel's
    known footprint and 1-4 shape parameters is the efficient estimator when it holds.
    Which model, and whether it holds, is tested, not assumed:

    * the Gaussian is the null model; the box or the halo replaces it when the likelihood
      ratio says so at p < 0.001 (the lower AIC if both do). A richer model fitted to a
      Gaussian LSF is poorly determined (at SNR 50 a 5 % FWHM scatter instead of 1 %),
      so it must earn its place; at p < 0.05 the Gaussian grid got worse and the
      defocus/motion grid no better (docs/edge-method.md);
    * the chosen model must pass the classical lack-of-fit F test: scatter of the bin
      means about the model against the pure error (scatter of the pixels' residuals
      within their bins), so no separate noise estimate is needed.
      ``params["adequate"]`` is p >= 0.001; only then may the model be the primary fit.
    """
    xb, yb, nb = _bins(d, v, bw)
    idx = _bin_index(d, bw)
    if xb.size < 12 or d.size - xb.size < 10:
        return None
    dark, bright = levels
    span = bright - dark
    sw = np.sqrt(nb)
    big = 10 * abs(span) + 1
    fp = footprint(angle_deg)
    base_lo = [dark - big, 0.0, lo]
    base_hi = [bright + big, 3 * big, hi]

    def fit(kind: str, p0: list[float], lower: list[float],
            upper: list[float]) -> tuple[np.ndarray, float] | None:
        lo_b, hi_b = np.array(base_lo + lower), np.array(base_hi + upper)
        try:
            res = optimize.least_squares(
                lambda p: (_model_esf(kind, xb, p, fp) - yb) * sw,
                np.clip(np.array(p0, dtype=float), lo_b, hi_b),
                jac=lambda p: _model_jac(kind, xb, p, fp) * sw[:, None],
                bounds=(lo_b, hi_b), x_scale="jac", max_nfev=400)
        except (ValueError, np.linalg.LinAlgError):
            return None
        if res.status < 0 or not np.all(np.isfinite(res.x)):
            return None
        return res.x, float(2.0 * res.cost)

    def pure_error(kind: str, p: np.ndarray) -> float:
        e = v - _model_esf(kind, d, p, fp)
        eb = np.bincount(idx, weights=e) / np.maximum(np.bincount(idx), 1)
        return float(np.sum((e - eb[idx]) ** 2) / (d.size - xb.size))

    s0 = min(max(sigma0, 0.05), 8.0)
    one = fit("gauss", [dark, span, 0.0 if lo < 0 < hi else 0.5 * (lo + hi), s0], [0.02], [10.0])
    if one is None:
        return None
    kind, (p, _) = "gauss", one
    var_pe = pure_error(kind, p)
    if not var_pe > 0:
        return None
    # quantisation-aware variance of a bin mean: the noise averages down with the bin's
    # count, the rounding of a noise-free (or low-noise) plateau does not (same DN on
    # every pixel): var_b = var_pe / n_b + q^2 / 12, q the DN step (0 for float data)
    qv = quant**2 / 12.0

    def chi(kind: str, p: np.ndarray, var: float) -> float:
        r = _model_esf(kind, xb, p, fp) - yb
        return float(np.sum(r**2 / (var / nb + qv)))

    a0, b0, c0, g = (float(q) for q in p)
    # a component must be seen inside the window: +-2 sigma, the shift and the box in it
    # (a halo wider than the window trades off against the levels and spoils the RER)
    half = 0.5 * (hi - lo)
    wide = max(half / 2.0, 1.5 * g)
    richer = {
        "gauss-box": fit("gauss-box", [a0, b0, c0, 0.7 * g, 2.0 * g], [0.02, 0.0],
                         [wide, max(half, 3.0 * g)]),
        "gauss2": fit("gauss2", [a0, b0, c0, 0.8 * g, min(2.5 * g, wide), 0.8, 0.0],
                      [0.02, 0.02, 0.0, -half / 2.0], [wide, wide, 1.0, half / 2.0]),
        "gauss-usm": fit("gauss-usm", [a0, b0, c0, g, min(1.5, wide), 0.5],
                         [0.02, 0.3, 0.0], [wide, wide, 5.0]),
    }
    base_chi = chi(kind, p, var_pe)
    # the disk (defocus) is the other flat-topped PSF: fitted only when the box beats the
    # Gaussian (a Gaussian edge seldom does; the disk's radius is degenerate at 0)
    box = richer["gauss-box"]
    if box is not None and base_chi - chi("gauss-box", box[0], var_pe) > stats.chi2.isf(_RICHER_P, 1):
        richer["gauss-disk"] = fit("gauss-disk", [a0, b0, c0, 0.6 * g, 1.2 * g], [0.2, 0.0],
                                   [wide, max(half, 3.0 * g)])
    best_aic = base_chi + 2 * p.size
    for name, got in richer.items():
        if got is None:
            continue
        q, _ = got
        extra = q.size - 4
        chi_q = chi(name, q, var_pe)
        aic = chi_q + 2 * q.size
        if base_chi - chi_q > stats.chi2.isf(_RICHER_P, extra) and aic < best_aic:
            kind, p, best_aic = name, q, aic
    if kind != "gauss":
        var_pe = pure_error(kind, p)
    dof = (xb.size - p.size, d.size - xb.size)
    f_stat = chi(kind, p, var_pe) / dof[0]
    p_value = float(stats.f.sf(f_stat, *dof))
    # out-of-sample comparison with the spline, needed (and paid for) only when the model
    # fails its lack-of-fit test
    cv_model = cv_spline = None
    if p_value < _ADEQUATE_P:
        cv_model, cv_spline = _cv_errors(xb, yb, nb, var_pe, qv, kind, p, fp, base_lo, base_hi)
    a, b_tot, c = float(p[0]), float(p[1]), float(p[2])
    if b_tot <= 0:
        return None
    comps = sorted(_components(kind, p[3:]))
    x = np.arange(lo, hi + _GRID / 2, _GRID)

    def esf_at(q: np.ndarray) -> np.ndarray:
        return (_model_esf(kind, np.asarray(q, dtype=float), p, fp) - a) / b_tot

    lsf = np.zeros_like(x)
    for sig, w, shift, box in comps:
        lsf += w * gauss_boxes_lsf(x - c - shift, sig, (*fp, box))

    def mtf_at(f: np.ndarray) -> np.ndarray:
        f = np.asarray(f, dtype=float)
        otf = sum(w * np.exp(-2.0 * np.pi**2 * sig**2 * f**2 - 2j * np.pi * f * shift) * np.sinc(f * box)
                  for sig, w, shift, box in comps)
        return np.abs(otf) * np.abs(np.sinc(f * fp[0])) * np.abs(np.sinc(f * fp[1]))

    # seed 9d: for a parametric ESF the RER centre is 0.5 on the normalised DN
    centre = c
    if kind == "gauss2":
        try:
            centre = float(optimize.brentq(lambda q: float(esf_at(np.array([q]))[0]) - 0.5, lo, hi))
        except ValueError:
            centre = c
    return _make_fit(kind, x, esf_at(x), lsf, centre, esf_at, (a, a + b_tot), {
        "model": _MODEL_TEXT[kind],
        "sigma_px": [q[0] for q in comps], "weights": [q[1] for q in comps],
        "shift_px": [q[2] for q in comps], "box_px": [q[3] for q in comps],
        **({"disk_radius_px": float(p[4])} if kind == "gauss-disk" else {}),
        **({"usm_amount": float(p[5]), "usm_sigma_px": float(p[4])} if kind == "gauss-usm" else {}),
        "footprint_px": list(fp), "bin_px": bw, "noise_dn": math.sqrt(var_pe),
        "lack_of_fit_f": f_stat, "dof": list(dof), "p_value": p_value,
        "adequate": p_value >= _ADEQUATE_P, "quantisation_dn": quant,
        "cv_error_model": cv_model, "cv_error_spline": cv_spline,
    }, mtf_at=mtf_at)


_CV_FOLDS = 5


def _cv_errors(xb: np.ndarray, yb: np.ndarray, nb: np.ndarray, var_pe: float, qv: float,
               kind: str, p: np.ndarray, fp: tuple[float, float], base_lo: list[float],
               base_hi: list[float]) -> tuple[float, float]:
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
    err_m = np.zeros(xb.size)
    err_s = np.zeros(xb.size)
    fold = np.arange(xb.size) % _CV_FOLDS
    for k in range(_CV_FOLDS):
        tr, te = fold != k, fold == k
        xt, yt, wt = xb[tr], yb[tr], sw[tr]
        try:
            res = optimize.least_squares(
                lambda q, xt=xt, yt=yt, wt=wt: (_model_esf(kind, xt, q, fp) - yt) * wt,
                np.clip(p, lo_b, hi_b), bounds=(lo_b, hi_b), x_scale="jac", max_nfev=100)
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
    return (float(np.mean(err_m[inner] / var_b[inner])), float(np.mean(err_s[inner] / var_b[inner])))


def _make_fit(name: str, x: np.ndarray, esf: np.ndarray, lsf: np.ndarray, centre: float,
              esf_at: Any, levels: tuple[float, float], params: dict[str, Any],
              mtf_at: Any = None) -> EdgeFit:
    e = esf_at(np.array([centre - 0.5, centre + 0.5]))
    rer = float(e[1] - e[0])
    ip = int(np.argmax(lsf))
    if mtf_at is None:
        freq, mtf = _mtf(lsf, _GRID)
    else:  # a model's exact transform, not one of its LSF truncated to the window
        freq = np.linspace(0.0, 1.0, 1001)
        mtf = mtf_at(freq)
    return EdgeFit(
        fit=name, x=x, esf=esf, lsf=lsf, centre_px=centre,
        mtf_freq=_MTF_FREQ, mtf=np.interp(_MTF_FREQ, freq, mtf),
        rer=rer,
        fwhm_px=_width(x, lsf, ip, 0.5),
        width25_px=_width(x, lsf, ip, 0.25),
        width80_px=_width(x, lsf, ip, 0.80),
        mtf_nyquist=float(np.interp(NYQUIST, freq, mtf)),
        edge_slope_per_px=float(lsf[ip]),
        dark_level=float(levels[0]), bright_level=float(levels[1]),
        params=params,
    )


def _overshoot(f: EdgeFit) -> float:
    """GIQE overshoot H of the normalised fitted ESF (``giqe.edge_overshoot``), the mean of
    the bright side's overshoot and the dark side's undershoot (mirrored), so that H does
    not depend on the edge's polarity (identical for a symmetric edge response)."""
    from .giqe import edge_overshoot

    c = f.centre_px
    bright = edge_overshoot(lambda q: np.interp(q, f.x, f.esf), c)
    dark = edge_overshoot(lambda q: 1.0 - np.interp(2.0 * c - np.asarray(q), f.x, f.esf), c)
    return 0.5 * (bright + dark)


def _width(x: np.ndarray, lsf: np.ndarray, ip: int, level: float) -> float:
    """Width of the LSF at ``level`` of its peak: nearest crossings either side, linear."""
    h = level * lsf[ip]
    left = np.flatnonzero(lsf[:ip] < h)
    right = np.flatnonzero(lsf[ip + 1:] < h)
    if not left.size or not right.size:
        return math.nan
    i = int(left[-1])
    j = int(right[0]) + ip + 1
    xl = x[i] + (h - lsf[i]) * (x[i + 1] - x[i]) / (lsf[i + 1] - lsf[i])
    xr = x[j - 1] + (h - lsf[j - 1]) * (x[j] - x[j - 1]) / (lsf[j] - lsf[j - 1])
    return float(xr - xl)


def _mtf(lsf: np.ndarray, dx: float) -> tuple[np.ndarray, np.ndarray]:
    """Seed 12: |FFT(LSF)| normalised at zero frequency (zero-padded for resolution)."""
    n = 1 << max(15, math.ceil(math.log2(lsf.size)) + 1)
    spec = np.abs(np.fft.rfft(lsf, n))
    freq = np.fft.rfftfreq(n, dx)
    return freq, spec / spec[0] if spec[0] > 0 else spec * math.nan


def _estimates_of(f: EdgeFit, gsd: float | None) -> list[Estimate]:
    out = [
        Estimate("rer", f.rer, "1", f.fit),
        Estimate("fwhm_px", f.fwhm_px, "px", f.fit),
        Estimate("width25_px", f.width25_px, "px", f.fit),
        Estimate("width80_px", f.width80_px, "px", f.fit),
        Estimate("mtf_nyquist", f.mtf_nyquist, "1", f.fit),
        Estimate("edge_slope_per_px", f.edge_slope_per_px, "1/px", f.fit),
        Estimate("effective_resolution_factor", f.effective_resolution_factor, "1", f.fit),
    ]
    if not f.fit.startswith("fermi"):  # H of the fits that can ring or follow the data
        out.append(Estimate("overshoot_h", _overshoot(f), "1", f.fit))
    if gsd is not None:
        out += [
            Estimate("fwhm_m", f.fwhm_px * gsd, "m", f.fit),
            Estimate("width25_m", f.width25_px * gsd, "m", f.fit),
            Estimate("width80_m", f.width80_px * gsd, "m", f.fit),
            Estimate("edge_slope_per_m", f.edge_slope_per_px / gsd, "1/m", f.fit),
            Estimate("effective_gsd_m", f.effective_resolution_factor * gsd, "m", f.fit),
        ]
    return out


# ----------------------------------------------------------------------------------------
# helpers


def _saturation(dtype: np.dtype, bit_depth: int | None,
                given: tuple[float | None, float | None] | None) -> tuple[float | None, float | None]:
    if given is not None:
        return given
    hi: float | None = None
    if bit_depth is not None:
        hi = float(2**bit_depth - 1)
    elif np.issubdtype(dtype, np.integer):
        hi = float(np.iinfo(dtype).max)
    lo = 0.0 if (bit_depth is not None or np.issubdtype(dtype, np.unsignedinteger)) else None
    return lo, hi


def _saturated(vals: np.ndarray, lo: float | None, hi: float | None) -> float:
    """Share of one side's pixels at (or beyond) a saturation level."""
    sat = np.zeros(vals.size, dtype=bool)
    if lo is not None:
        sat |= vals <= lo
    if hi is not None:
        sat |= vals >= hi
    return float(sat.mean()) if vals.size else math.nan


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


def _opt(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _f(x: Any) -> Any:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None
