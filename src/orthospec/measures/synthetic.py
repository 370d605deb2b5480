"""Synthetic slanted edges and their analytic truth (for testing the edge chain).

Why: an edge measurement can only be trusted if it recovers a *known* system
response. The response an image actually has along the edge normal is the PSF
together with the square pixel's integration, projected on the normal:

* the projection of an isotropic Gaussian PSF (sigma) on any direction is a
  1-D Gaussian of the same sigma;
* the projection of a unit square pixel on a direction at angle ``theta`` to
  its side is the convolution of two boxes, of widths ``|cos theta|`` and
  ``|sin theta|`` (a trapezoid; a 1-px box only when theta = 0).

So along the normal LSF = G(sigma) * box(|cos t|) * box(|sin t|) and, by the
Fourier slice theorem, MTF(f) = exp(-2 pi^2 sigma^2 f^2) |sinc(f cos t)| |sinc(f sin t)|.
Every pixel value of an ideal rendered edge equals ESF(d) at the perpendicular
distance d of the pixel centre from the edge, which is what the slanted-edge
method samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize, signal
from scipy.special import ndtr

from ..errors import MeasureError

__all__ = [
    "EdgeTruth",
    "edge_truth",
    "slanted_edge",
    "truth_esf",
    "truth_lsf",
    "truth_mtf",
]

_SQRT2PI = np.sqrt(2.0 * np.pi)


def _footprint(angle_deg: float) -> tuple[float, float]:
    """Widths of the two boxes a unit square pixel projects to along the edge normal."""
    t = np.deg2rad(angle_deg)
    return float(abs(np.cos(t))), float(abs(np.sin(t)))


def _phi(x: np.ndarray, s: float) -> np.ndarray:
    return np.exp(-0.5 * (x / s) ** 2) / (_SQRT2PI * s)


def _psi1(x: np.ndarray, s: float) -> np.ndarray:
    """Antiderivative of the Gaussian CDF Phi(x/s) in x."""
    return x * ndtr(x / s) + s * s * _phi(x, s)


def _psi2(x: np.ndarray, s: float) -> np.ndarray:
    """Second antiderivative of Phi(x/s) in x."""
    return 0.5 * (x * x + s * s) * ndtr(x / s) + 0.5 * x * s * s * _phi(x, s)


def _check_sigma(sigma_px: float) -> None:
    if not np.isfinite(sigma_px) or sigma_px <= 0:
        raise MeasureError(f"sigma_px must be a positive number of pixels, got {sigma_px!r}")


def truth_lsf(d: np.ndarray, *, sigma_px: float, angle_deg: float) -> np.ndarray:
    """Analytic LSF (area 1, 1/px) of Gaussian PSF * square pixel along the edge normal."""
    _check_sigma(sigma_px)
    x = np.asarray(d, dtype=float)
    a, b = _footprint(angle_deg)
    s = float(sigma_px)
    if b < 1e-9:  # box(a) only: [Phi((x+a/2)/s) - Phi((x-a/2)/s)] / a
        return (ndtr((x + a / 2) / s) - ndtr((x - a / 2) / s)) / a
    h1, h2 = (a + b) / 2, (a - b) / 2
    return (_psi1(x + h1, s) - _psi1(x + h2, s) - _psi1(x - h2, s) + _psi1(x - h1, s)) / (a * b)


def truth_esf(d: np.ndarray, *, sigma_px: float, angle_deg: float) -> np.ndarray:
    """Analytic normalised ESF (0 dark .. 1 bright) along the edge normal; d > 0 is bright."""
    _check_sigma(sigma_px)
    x = np.asarray(d, dtype=float)
    a, b = _footprint(angle_deg)
    s = float(sigma_px)
    if b < 1e-9:
        return (_psi1(x + a / 2, s) - _psi1(x - a / 2, s)) / a
    h1, h2 = (a + b) / 2, (a - b) / 2
    return (_psi2(x + h1, s) - _psi2(x + h2, s) - _psi2(x - h2, s) + _psi2(x - h1, s)) / (a * b)


def truth_mtf(f: np.ndarray, *, sigma_px: float, angle_deg: float) -> np.ndarray:
    """Analytic MTF at spatial frequency f (cycles/px) along the edge normal."""
    _check_sigma(sigma_px)
    ff = np.asarray(f, dtype=float)
    a, b = _footprint(angle_deg)
    gauss = np.exp(-2.0 * np.pi**2 * sigma_px**2 * ff**2)
    return gauss * np.abs(np.sinc(ff * a)) * np.abs(np.sinc(ff * b))


@dataclass(frozen=True)
class EdgeTruth:
    """Analytic estimators of a Gaussian-PSF, square-pixel edge (pixel units)."""

    sigma_px: float
    angle_deg: float
    fwhm_px: float
    width25_px: float
    width80_px: float
    rer: float
    mtf_nyquist: float
    edge_slope_per_px: float


def _width_at(level: float, *, sigma_px: float, angle_deg: float) -> float:
    peak = float(truth_lsf(np.array([0.0]), sigma_px=sigma_px, angle_deg=angle_deg)[0])

    def g(x: float) -> float:
        return float(truth_lsf(np.array([x]), sigma_px=sigma_px, angle_deg=angle_deg)[0]) - level * peak

    hi = 1.0
    while g(hi) > 0:
        hi *= 2.0
    return 2.0 * optimize.brentq(g, 0.0, hi, xtol=1e-12)


def edge_truth(*, sigma_px: float, angle_deg: float) -> EdgeTruth:
    """FWHM, widths at 25/80 %, RER, MTF at Nyquist and slope of the analytic system response."""
    esf = truth_esf(np.array([-0.5, 0.5]), sigma_px=sigma_px, angle_deg=angle_deg)
    return EdgeTruth(
        sigma_px=float(sigma_px),
        angle_deg=float(angle_deg),
        fwhm_px=_width_at(0.5, sigma_px=sigma_px, angle_deg=angle_deg),
        width25_px=_width_at(0.25, sigma_px=sigma_px, angle_deg=angle_deg),
        width80_px=_width_at(0.80, sigma_px=sigma_px, angle_deg=angle_deg),
        rer=float(esf[1] - esf[0]),
        mtf_nyquist=float(truth_mtf(np.array([0.5]), sigma_px=sigma_px, angle_deg=angle_deg)[0]),
        edge_slope_per_px=float(truth_lsf(np.array([0.0]), sigma_px=sigma_px, angle_deg=angle_deg)[0]),
    )


def slanted_edge(
    shape: tuple[int, int] = (100, 100),
    *,
    angle_deg: float = 5.0,
    sigma_px: float | None = 0.8,
    psf: np.ndarray | None = None,
    psf_step_px: float = 1.0,
    dark: float | None = None,
    bright: float | None = None,
    snr: float | None = None,
    bit_depth: int | None = None,
    offset_px: float = 0.0,
    supersample: int = 15,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Render a straight edge, blur it, integrate over square pixels, add noise, quantise.

    The edge runs close to the image columns, turned by ``angle_deg`` from the
    vertical (row y has the edge at x = cx + offset + (y - cy) tan(angle)); bright
    is on the right. Transpose or flip the result for other orientations.

    Parameters
    ----------
    sigma_px, psf
        Gaussian PSF sigma in pixels, or a measured PSF kernel sampled every
        ``psf_step_px`` pixels (normalised to sum 1 here). Exactly one is used:
        ``psf`` when given. A kernel is resampled to the render's sub-pixel step
        (1 / ``supersample`` px) by linear interpolation, which widens a narrow core;
        sample it at that step to render it exactly.
    snr
        Signal-to-noise ratio as the CEOS seed defines it, (bright - dark) / mean
        noise std; Gaussian noise of std (bright - dark) / snr on every pixel.
    bit_depth
        8, 11 or 16 (any 1..16): round and clip to [0, 2**bit_depth - 1] and
        return uint8/uint16; None keeps float64.
    rng
        numpy Generator for the noise (seedable, deterministic).
    """
    rows, cols = (int(shape[0]), int(shape[1]))
    if rows < 2 or cols < 2:
        raise MeasureError(f"shape must be at least 2 x 2 pixels, got {shape!r}")
    if supersample < 1:
        raise MeasureError(f"supersample must be >= 1, got {supersample}")
    if bit_depth is not None and not 1 <= bit_depth <= 16:
        raise MeasureError(f"bit_depth must be in 1..16, got {bit_depth}")
    full = float(2**bit_depth - 1) if bit_depth else 500.0
    dark = 0.2 * full if dark is None else float(dark)
    bright = 0.8 * full if bright is None else float(bright)

    s = int(supersample)
    # render with a margin wide enough for the PSF, so the blur sees the edge continue
    if psf is not None:
        reach = 0.5 * max(np.shape(psf)) * psf_step_px
    else:
        reach = 6.0 * float(sigma_px or 0.0)
    m = int(np.ceil(reach)) + 1
    # sub-pixel centres in pixel coordinates (pixel centres at integers)
    sub = (np.arange(s) + 0.5) / s - 0.5
    y = (np.arange(-m, rows + m)[:, None] + sub[None, :]).ravel()
    x = (np.arange(-m, cols + m)[:, None] + sub[None, :]).ravel()
    cy, cx = (rows - 1) / 2.0, (cols - 1) / 2.0 + offset_px
    t = np.deg2rad(angle_deg)
    dist = (x[None, :] - cx) * np.cos(t) - (y[:, None] - cy) * np.sin(t)
    # area coverage of each sub-pixel by the bright half-plane (linear ramp over one sub-pixel)
    cover = np.clip(0.5 + dist * s, 0.0, 1.0)
    scene = dark + (bright - dark) * cover

    if psf is not None:
        kernel = np.asarray(psf, dtype=float)
        if kernel.ndim != 2 or kernel.sum() <= 0:
            raise MeasureError("psf must be a 2-D kernel with a positive sum")
        zoom = psf_step_px * s
        if zoom != 1.0:
            kernel = ndimage.zoom(kernel, zoom, order=1)
        kernel = np.clip(kernel, 0.0, None)
        kernel /= kernel.sum()
        # fftconvolve treats the outside as 0: pad by edge values first
        pad = max(kernel.shape) // 2 + 1
        padded = np.pad(scene, pad, mode="edge")
        blurred = signal.fftconvolve(padded, kernel, mode="same")[pad:-pad, pad:-pad]
    elif sigma_px is not None and sigma_px > 0:
        blurred = ndimage.gaussian_filter(scene, sigma=float(sigma_px) * s, mode="nearest",
                                          truncate=6.0)
    else:
        blurred = scene
    img = blurred.reshape(rows + 2 * m, s, cols + 2 * m, s).mean(axis=(1, 3))[m:-m, m:-m]

    if snr is not None:
        if snr <= 0:
            raise MeasureError(f"snr must be positive, got {snr}")
        gen = rng if rng is not None else np.random.default_rng(0)
        img = img + gen.normal(0.0, abs(bright - dark) / float(snr), size=img.shape)
    if bit_depth:
        img = np.clip(np.rint(img), 0, full)
        return img.astype(np.uint8 if bit_depth <= 8 else np.uint16)
    return img
