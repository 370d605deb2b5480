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

import numpy as np
from scipy.special import ndtr

__all__ = [
    "footprint",
    "gauss_boxes_esf",
    "gauss_boxes_lsf",
    "gauss_pixel_esf",
    "gauss_pixel_lsf",
    "gauss_pixel_mtf",
]

_SQRT2PI = np.sqrt(2.0 * np.pi)


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


def _boxed(x: np.ndarray, s: float, widths: tuple[float, ...], order: int) -> np.ndarray:
    """Phi (order 0) or phi (order -1) convolved with unit-area boxes of ``widths``:
    each box is a central difference of the next antiderivative over its width."""
    ws = [float(w) for w in widths if w > _NARROW]
    n = len(ws)
    out = np.zeros_like(x)
    # sum over the 2^n corners of the central differences
    for corner in range(1 << n):
        shift, sign = 0.0, 1.0
        for k, w in enumerate(ws):
            if corner >> k & 1:
                shift += w / 2
            else:
                shift -= w / 2
                sign = -sign
        out += sign * _psi(n + order, x + shift, s)
    return out / float(np.prod(ws)) if n else out


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
