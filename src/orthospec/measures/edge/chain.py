"""The CEOS 12-step edge chain on one ROI: :func:`measure_edge`, one named call per seed step."""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from ...errors import MeasureError
from .bins import smoothing_spline, within_bin_std
from .esf import Areas, EsfSamples, esf_samples, saturation_levels, uniform_areas
from .estimators import PRIMARY, choose_primary, estimate_all
from .fits import fermi_fit, spline_fit, spline_uncertainty
from .health import health_checks
from .limits import EdgeLimits
from .locate import locate_line, orient
from .model import psf_fit
from .result import PSF_FITS, SPLINE, EdgeFit, EdgeResult


def measure_edge(
    roi: np.ndarray,
    *,
    gsd: float | None = None,
    nodata: float | None = None,
    bit_depth: int | None = None,
    saturation_dn: tuple[float | None, float | None] | None = None,
    limits: EdgeLimits | None = None,
    primary: str = "auto",
    **overrides: Any,
) -> EdgeResult:
    """Run the CEOS 12-step edge chain on one ROI.

    Parameters
    ----------
    roi
        2-D array (rows, columns) holding one straight edge; NaN (or ``nodata``, or masked:
        a ``numpy.ma`` array as :func:`orthospec.raster.roi.read_roi` returns) pixels are
        ignored. The data type sets the saturation levels and the quantisation noise floor.
    gsd
        Ground sample distance in metres per pixel; adds metre-valued estimators.
    bit_depth, saturation_dn
        Saturation levels (low, high) in DN. Default: low 0 and high
        ``2**bit_depth - 1``, or the integer dtype's maximum.
    limits
        Health-check limits and method settings (:class:`EdgeLimits`, each with its source);
        default the seed's.
    primary
        Which fit gives the reported estimators: ``"auto"`` (the physical PSF model when
        its chi2 test says it describes the ESF, else the spline), ``"spline"`` (always
        the model-free fit) or ``"model"`` (the PSF model even when the test rejects it).
    **overrides
        Single fields of :class:`EdgeLimits` (``min_snr=45``, ``fermi_terms=1``...) replacing
        those of ``limits``; any other name is a ``TypeError``.

    Returns
    -------
    EdgeResult

    Raises
    ------
    MeasureError
        When ``roi`` is not a 2-D numeric array of at least 5 x 5 pixels with finite values.
    """
    lim = EdgeLimits.merged(limits, overrides)
    if primary not in PRIMARY:
        raise MeasureError(f"primary must be one of {', '.join(PRIMARY)}, got {primary!r}")
    arr, img, quant = _prepare(roi, nodata, bit_depth, gsd)
    with one_blas_thread():
        return _chain(arr, img, quant, gsd, bit_depth, saturation_dn, lim, primary)


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """The chain's linear algebra (an eigen-decomposition per spline fit, QRs of the fits'
    Jacobians: matrices of a few hundred rows) on one BLAS thread, for the call only.

    Why: OpenBLAS's threads on such small matrices only spin beside the caller's own work; under
    load (issue 31) a library call took 0.56 s of CPU per ROI on average and up to 25 s, against
    0.13 s and 1.9 s on one thread. The CLI and ``check``'s workers set OPENBLAS_NUM_THREADS=1
    before numpy loads, so nothing is done there; elsewhere threadpoolctl sets it and puts the
    caller's setting back afterwards.
    """
    if os.environ.get("OPENBLAS_NUM_THREADS") == "1":
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):
        yield


def _chain(
    arr: np.ndarray,
    img: np.ndarray,
    quant: float,
    gsd: float | None,
    bit_depth: int | None,
    saturation_dn: tuple[float | None, float | None] | None,
    lim: EdgeLimits,
    primary: str,
) -> EdgeResult:
    """Steps 3-12 on the prepared ROI (:func:`measure_edge`)."""
    sat = saturation_levels(arr.dtype, bit_depth, saturation_dn)
    frame = orient(img)                                           # step 4
    line = locate_line(frame.work, refine=lim.refine_line)         # step 5
    samples = esf_samples(frame.work, line)                        # step 6
    areas = uniform_areas(samples, lim.bin_px, lim.plateau_px, sat)  # step 7
    fits = fit_esf(samples, areas, lim, line.angle_deg, quant)    # step 8
    checks = health_checks(line, areas, fits, quant, lim)          # step 3
    if SPLINE in fits and choose_primary(fits, primary) == SPLINE and areas.window is not None:
        fits[SPLINE] = _with_spline_uncertainty(fits, samples, areas, lim, quant)
    valid, reasons, chosen, estimates = estimate_all(checks, fits, primary, gsd)  # steps 9-12
    rows = line.rows.astype(float)
    lx, ly = frame.to_roi(rows, line.locs)
    fx, fy = frame.to_roi(rows, line.fitted_cols())
    return EdgeResult(
        valid=valid, reasons=reasons, checks=checks, direction=frame.direction,
        transposed=frame.transposed, polarity=frame.polarity, angle_deg=line.angle_deg,
        shape=(int(arr.shape[0]), int(arr.shape[1])),
        line_x=lx, line_y=ly, line_kept=line.kept, fitted_x=fx, fitted_y=fy,
        residual_rms_px=line.residual_rms_px if line.ok else None,
        esf_d=samples.d, esf_dn=samples.v,
        dark_level=_opt(areas.levels[0]), bright_level=_opt(areas.levels[1]),
        dark_std=_opt(areas.stds[0]), bright_std=_opt(areas.stds[1]),
        dark_start_px=_opt(areas.dark_start), bright_start_px=_opt(areas.bright_start),
        window_px=areas.window, fits=fits, primary_fit=chosen, estimates=estimates, gsd_m=gsd,
        warnings=_warnings(line.angle_deg, lim),
    )


def _warnings(angle_deg: float | None, lim: EdgeLimits) -> tuple[str, ...]:
    """Seed step 3d permits 0-30 deg (TBR); beyond it (up to ``max_angle_deg``) the edge is
    measured as accurately (issue 31 benchmark) and the result says so."""
    if angle_deg is not None and lim.standard_max_angle_deg < angle_deg <= lim.max_angle_deg:
        return (
            f"edge angle {angle_deg:.2f} deg is beyond the 0-{lim.standard_max_angle_deg:g} deg "
            "of CEOS step 3d (TBR); measured (the ESF is sampled as finely up to 45 deg)",
        )
    return ()


def fit_esf(
    s: EsfSamples, areas: Areas, lim: EdgeLimits, angle_deg: float | None, quant: float
) -> dict[str, EdgeFit]:
    """Step 8 on the trimmed ESF: Fermi-Dirac, smoothing spline and (with an angle) the PSF
    model; none without a window and ordered levels."""
    fits: dict[str, EdgeFit] = {}
    if not areas.fittable or areas.window is None or areas.uniform is None:
        return fits
    lo, hi = areas.window
    bw = lim.bin_px
    sel = (s.d >= lo) & (s.d <= hi)
    d, v = s.d[sel], s.v[sel]
    core = areas.core
    fermi = fermi_fit(d, v, bw, lo, hi, areas.levels, lim.fermi_terms, core)
    if fermi is not None:
        fits[fermi.fit] = fermi
    local = within_bin_std(s.d[areas.uniform], s.v[areas.uniform], bw)
    spl = smoothing_spline(d, v, bw, lo, hi, noise=local, core=core)
    if spl is not None:
        fits[SPLINE] = spline_fit(spl, lo, hi, areas.levels, bw)
    if angle_deg is not None:
        model = psf_fit(
            d,
            v,
            bw,
            lo,
            hi,
            areas.levels,
            angle_deg,
            sigma0=0.5 * (areas.bright_start - areas.dark_start),
            quant=quant,
            core=core,
        )
        if model is not None:
            fits[model.fit] = model
    return fits


def _with_spline_uncertainty(
    fits: dict[str, EdgeFit], s: EsfSamples, areas: Areas, lim: EdgeLimits, quant: float
) -> EdgeFit:
    """The spline fit with its standard uncertainties (only computed when it is the primary)."""
    lo, hi = areas.window  # type: ignore[misc]
    spl = fits[SPLINE]
    model = next((fits[n] for n in PSF_FITS if n in fits), None)
    cands = model.params.get("candidates", {}) if model is not None else {}
    noise = within_bin_std(s.d[areas.uniform], s.v[areas.uniform], lim.bin_px)
    unc = spline_uncertainty(
        s.d, s.v, lim.bin_px, lo, hi, areas.levels, noise, quant, spl, cands, areas.core
    )
    return dataclasses.replace(spl, params={**spl.params, **unc})


def _prepare(
    roi: np.ndarray | np.ma.MaskedArray,
    nodata: float | None,
    bit_depth: int | None,
    gsd: float | None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Malformed input raises; returns the array, its float copy with ``nodata`` and masked
    pixels as NaN, and the DN step of quantised data (integer DNs: its noise floor q / sqrt(12)
    never averages out)."""
    masked = np.ma.isMaskedArray(roi)
    invalid = np.ma.getmaskarray(roi) if masked else None
    arr = np.asarray(np.ma.getdata(roi) if masked else roi)
    if arr.ndim != 2:
        raise MeasureError(f"edge ROI must be a 2-D array, got {arr.ndim} dimension(s) {arr.shape}")
    if min(arr.shape) < 5:
        raise MeasureError(
            f"edge ROI {arr.shape[1]} x {arr.shape[0]} px is too small; "
            "expected at least 5 x 5 px (and > 20 lines to pass the checks)"
        )
    if not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise MeasureError(f"edge ROI must be numeric, got dtype {arr.dtype}")
    img = arr.astype(float)
    quant = (
        1.0
        if (bit_depth is not None or np.issubdtype(arr.dtype, np.integer) or _integer_valued(img))
        else 0.0
    )
    if nodata is not None:
        img[img == nodata] = np.nan
    if invalid is not None:
        img[invalid] = np.nan
    if not np.isfinite(img).any():
        raise MeasureError("edge ROI has no finite pixels")
    if gsd is not None and not (math.isfinite(gsd) and gsd > 0):
        raise MeasureError(f"gsd must be a positive number of metres per pixel, got {gsd!r}")
    return arr, img, quant


def _integer_valued(img: np.ndarray) -> bool:
    """A float band holding integer DNs (a uint band converted, or read masked as float): its
    rounding noise q / sqrt(12), q = 1 DN, is as real as an integer band's (issue 31)."""
    fin = img[np.isfinite(img)]
    return bool(fin.size) and bool(np.all(fin == np.round(fin))) and float(np.ptp(fin)) >= 2.0


def _opt(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)
