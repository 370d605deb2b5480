"""Seed steps 9-12 on a fitted ESF: RER, LSF, FWHM and widths, MTF; the primary fit; the
estimators reported (in px, and in metres with a GSD); the USGS two-direction RER.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...errors import MeasureError
from ..giqe import edge_overshoot
from .result import GRID, MTF_FREQ, NYQUIST, PSF_FITS, SPLINE, EdgeFit, Estimate, HealthCheck

PRIMARY = ("auto", "spline", "model")


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



def estimate_all(checks: tuple[HealthCheck, ...], fits: dict[str, EdgeFit], primary: str,
                 gsd: float | None) -> tuple[bool, tuple[str, ...], str, tuple[Estimate, ...]]:
    """Steps 9-12 for every fit, primary first, when every health check passed.

    Returns (valid, reasons, primary fit name, estimates): an estimator of the spline that
    cannot be computed makes the edge invalid; other fits' non-finite values are left out.
    """
    reasons = tuple(f"{c.name}: {c.reason}" for c in checks if not c.passed)
    chosen = choose_primary(fits, primary)
    if reasons:
        return False, reasons, chosen, ()
    ordered = sorted(fits.values(), key=lambda f: (f.fit != chosen, f.fit))  # primary first
    estimates = tuple(e for f in ordered for e in _estimates_of(f, gsd))
    bad = [e.name for e in estimates if e.fit == SPLINE and not math.isfinite(e.value)]
    if bad:
        return False, (f"estimators: could not be computed ({', '.join(bad)})",), chosen, ()
    return True, (), chosen, tuple(e for e in estimates if math.isfinite(e.value))


def choose_primary(fits: dict[str, EdgeFit], primary: str) -> str:
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


def make_fit(name: str, x: np.ndarray, esf: np.ndarray, lsf: np.ndarray, centre: float,
              esf_at: Any, levels: tuple[float, float], params: dict[str, Any],
              mtf_at: Any = None) -> EdgeFit:
    e = esf_at(np.array([centre - 0.5, centre + 0.5]))
    rer = float(e[1] - e[0])
    ip = int(np.argmax(lsf))
    if mtf_at is None:
        freq, mtf = _mtf(lsf, GRID)
    else:  # a model's exact transform, not one of its LSF truncated to the window
        freq = np.linspace(0.0, 1.0, 1001)
        mtf = mtf_at(freq)
    return EdgeFit(
        fit=name, x=x, esf=esf, lsf=lsf, centre_px=centre,
        mtf_freq=MTF_FREQ, mtf=np.interp(MTF_FREQ, freq, mtf),
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
    c = f.centre_px
    bright = edge_overshoot(lambda q: np.interp(q, f.x, f.esf), c)
    dark = edge_overshoot(lambda q: 1.0 - np.interp(2.0 * c - np.asarray(q), f.x, f.esf), c)
    return 0.5 * (bright + dark)


def fwhm_of(x: np.ndarray, lsf: np.ndarray) -> float:
    """FWHM (px) of an LSF sampled on ``x`` (nearest half-peak crossings either side of the peak)."""
    return _width(x, lsf, int(np.argmax(lsf)), 0.5)


def _width(x: np.ndarray, lsf: np.ndarray, ip: int, level: float) -> float:
    """Width of the LSF at ``level`` of its peak: nearest crossings either side, linear."""
    h = level * lsf[ip]
    left = np.flatnonzero(lsf[:ip] < h)
    right = np.flatnonzero(lsf[ip + 1 :] < h)
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
    u = f.params.get("u", {})
    uf = u.get("fwhm_px")
    out = [
        Estimate("rer", f.rer, "1", f.fit, u.get("rer")),
        Estimate("fwhm_px", f.fwhm_px, "px", f.fit, uf),
        Estimate("width25_px", f.width25_px, "px", f.fit),
        Estimate("width80_px", f.width80_px, "px", f.fit),
        Estimate("mtf_nyquist", f.mtf_nyquist, "1", f.fit, u.get("mtf_nyquist")),
        Estimate("edge_slope_per_px", f.edge_slope_per_px, "1/px", f.fit),
        Estimate("effective_resolution_factor", f.effective_resolution_factor, "1", f.fit, uf),
    ]
    if not f.fit.startswith("fermi"):  # H of the fits that can ring or follow the data
        out.append(Estimate("overshoot_h", _overshoot(f), "1", f.fit))
    if gsd is not None:
        out += [
            Estimate("fwhm_m", f.fwhm_px * gsd, "m", f.fit, None if uf is None else uf * gsd),
            Estimate("width25_m", f.width25_px * gsd, "m", f.fit),
            Estimate("width80_m", f.width80_px * gsd, "m", f.fit),
            Estimate("edge_slope_per_m", f.edge_slope_per_px / gsd, "1/m", f.fit),
            Estimate(
                "effective_gsd_m",
                f.effective_resolution_factor * gsd,
                "m",
                f.fit,
                None if uf is None else uf * gsd,
            ),
        ]
    return out


# ----------------------------------------------------------------------------------------
