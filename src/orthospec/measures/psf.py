"""Closed forms of a Gaussian PSF integrated over a square pixel, along an edge normal.

Why here: the synthetic generator needs them as *truth* and the edge chain needs them
as a *model* (its physical fit); both must be the same formulas, so both import them.

* the projection of an isotropic Gaussian PSF (sigma) on any direction is a 1-D
  Gaussian of the same sigma;
* the projection of a unit square pixel on a direction at angle ``theta`` to its side
  is the convolution of two boxes of widths ``|cos theta|`` and ``|sin theta|`` (a
  trapezoid; a 1-px box only at theta = 0).

So along the normal LSF = G(sigma) * box(|cos t|) * box(|sin t|), the ESF is its
integral, and (Fourier slice theorem) MTF(f) = exp(-2 pi^2 sigma^2 f^2)
|sinc(f cos t)| |sinc(f sin t)|. Distances in px, frequencies in cycles/px.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "footprint",
    "gauss_boxes_esf",
    "gauss_boxes_lsf",
    "gauss_pixel_esf",
    "gauss_pixel_lsf",
    "gauss_pixel_mtf",
]

_SQRT2PI = np.sqrt(2.0 * np.pi)

# The standard normal CDF without scipy.special (importing it costs ~0.2 s CPU, more than an
# edge measurement): a quintic Hermite interpolant on a 1/64 grid over [-9, 9] of the exact
# values and first two derivatives (phi, -z phi), one polynomial per interval, evaluated by
# Horner. Error < 1e-15 (the interpolation error h^6 / 46,080 max|Phi^(6)| ~ 6e-16); beyond
# +-9 the CDF is 0 or 1 to 1e-19. One table lookup and ~15 array operations per call.
_ZMAX, _H = 9.0, 1.0 / 64.0


def _cdf_table() -> np.ndarray:
    z = np.linspace(-_ZMAX, _ZMAX, round(2 * _ZMAX / _H) + 1)
    y = np.array([0.5 * math.erfc(-float(t) / math.sqrt(2.0)) for t in z])
    d1 = np.exp(-0.5 * z * z) / _SQRT2PI * _H  # h Phi'
    d2 = -z * d1 * _H  # h^2 Phi''
    y0, y1, a0, a1, b0, b1 = y[:-1], y[1:], d1[:-1], d1[1:], d2[:-1], d2[1:]
    # p(u) = sum c_k u^k with p, p', p'' matching at u = 0 and u = 1
    c3 = 10 * (y1 - y0) - 6 * a0 - 4 * a1 - 1.5 * b0 + 0.5 * b1
    c4 = -15 * (y1 - y0) + 8 * a0 + 7 * a1 + 1.5 * b0 - b1
    c5 = 6 * (y1 - y0) - 3 * a0 - 3 * a1 - 0.5 * b0 + 0.5 * b1
    return np.stack([c5, c4, c3, 0.5 * b0, a0, y0])  # highest power first, one row each


_CDF = _cdf_table()
_LAST = _CDF.shape[1] - 1


def ndtr(z: np.ndarray) -> np.ndarray:
    """Standard normal CDF (as ``scipy.special.ndtr``, to 1e-15) of an array; NaN stays NaN."""
    t = (np.clip(np.asarray(z, dtype=float), -_ZMAX, _ZMAX) + _ZMAX) * (1.0 / _H)
    with np.errstate(invalid="ignore"):  # NaN: any interval, u = NaN gives NaN
        i = t.astype(np.intp)
    u = t - i
    out = _CDF[0].take(i, mode="clip")
    for row in _CDF[1:]:
        out *= u
        out += row.take(i, mode="clip")
    return out


def footprint(angle_deg: float) -> tuple[float, float]:
    """Widths (px) of the two boxes a unit square pixel projects to along the edge normal."""
    t = np.deg2rad(angle_deg)
    return float(abs(np.cos(t))), float(abs(np.sin(t)))


def _phi(x: np.ndarray, s: float) -> np.ndarray:
    return np.exp(-0.5 * (x / s) ** 2) / (_SQRT2PI * s)


def _psi(n: int, x: np.ndarray, s: float) -> np.ndarray:
    """n-th antiderivative in x of the Gaussian CDF Phi(x/s); n = -1 is the density, -2 its
    derivative.

    With z = x/s and the standard normal Phi, phi: psi_n(x) = s^n P_n(z) with
    P_1 = z Phi + phi, P_2 = (z^2 + 1)/2 Phi + z/2 phi, P_3 = (z^3 + 3z)/6 Phi + (z^2 + 2)/6 phi.
    """
    z = x / s
    if n == -1:
        return _phi(x, s)
    if n == -2:  # derivative of the density
        return -z / s * _phi(x, s)
    cdf = ndtr(z)
    pdf = np.exp(-0.5 * z * z) / _SQRT2PI
    if n == 0:
        return cdf
    if n == 1:
        return s * (z * cdf + pdf)
    if n == 2:
        return s * s * (0.5 * (z * z + 1.0) * cdf + 0.5 * z * pdf)
    if n == 3:
        return s**3 * ((z**3 + 3.0 * z) / 6.0 * cdf + (z * z + 2.0) / 6.0 * pdf)
    raise ValueError(f"antiderivative order {n} not available")


_NARROW = 1e-9  # px; a box narrower than this is a delta
# corner c of n boxes: bit k set = +w_k / 2 (else -w_k / 2, sign flipped)
_CORNERS = [(np.arange(1 << n)[:, None] >> np.arange(n)) & 1 for n in range(5)]
_SIGNS = [np.prod(np.where(b == 1, 1.0, -1.0), axis=1) for b in _CORNERS]


def _boxed(x: np.ndarray, s: float, widths: tuple[float, ...], order: int) -> np.ndarray:
    """Phi (order 0) or phi (order -1) convolved with unit-area boxes of ``widths``:
    each box is a central difference of the next antiderivative over its width."""
    ws = [float(w) for w in widths if w > _NARROW]
    n = len(ws)
    if not n:
        return _psi(order, x, s)
    # the 2^n corners of the central differences, all in one call of the antiderivative
    bits = _CORNERS[n]
    shifts = (bits - 0.5) @ np.asarray(ws)
    signs = _SIGNS[n]
    vals = _psi(n + order, x[..., None] + shifts, s)
    return (vals @ signs) / math.prod(ws)


def gauss_boxes_esf(d: np.ndarray, sigma_px: float, widths: tuple[float, ...]) -> np.ndarray:
    """Normalised ESF of a Gaussian (sigma) convolved with boxes of ``widths`` (px, up to 3)."""
    return _boxed(np.asarray(d, dtype=float), float(sigma_px), widths, 0)


def gauss_boxes_lsf(d: np.ndarray, sigma_px: float, widths: tuple[float, ...]) -> np.ndarray:
    """LSF (area 1, 1/px) of a Gaussian (sigma) convolved with boxes of ``widths``."""
    return _boxed(np.asarray(d, dtype=float), float(sigma_px), widths, -1)


def gauss_boxes_esf_dsigma(d: np.ndarray, sigma_px: float, widths: tuple[float, ...]) -> np.ndarray:
    """d ESF / d sigma of :func:`gauss_boxes_esf`: sigma times d LSF / dx (the heat equation,
    dG/d(sigma^2 / 2) = d^2 G / dx^2, commutes with the boxes). For analytic Jacobians."""
    return float(sigma_px) * _boxed(np.asarray(d, dtype=float), float(sigma_px), widths, -2)


def gauss_pixel_lsf(d: np.ndarray, sigma_px: float, angle_deg: float) -> np.ndarray:
    """LSF (area 1, 1/px) of a Gaussian PSF of ``sigma_px`` integrated over a square pixel."""
    return gauss_boxes_lsf(d, sigma_px, footprint(angle_deg))


def gauss_pixel_esf(d: np.ndarray, sigma_px: float, angle_deg: float) -> np.ndarray:
    """Normalised ESF (0 dark .. 1 bright, d > 0 bright) of the same system."""
    return gauss_boxes_esf(d, sigma_px, footprint(angle_deg))


def gauss_pixel_mtf(f: np.ndarray, sigma_px: float, angle_deg: float) -> np.ndarray:
    """MTF at spatial frequency ``f`` (cycles/px) of the same system."""
    ff = np.asarray(f, dtype=float)
    a, b = footprint(angle_deg)
    gauss = np.exp(-2.0 * np.pi**2 * float(sigma_px) ** 2 * ff**2)
    return gauss * np.abs(np.sinc(ff * a)) * np.abs(np.sinc(ff * b))
