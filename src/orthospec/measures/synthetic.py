"""Synthetic slanted edges and their analytic truth (for testing the edge chain).

Why: an edge measurement can only be trusted if it recovers a *known* system
response. The response an image actually has along the edge normal is the PSF
together with the square pixel's integration, projected on the normal; its closed
forms live in :mod:`orthospec.measures.psf` (the edge chain's physical fit uses the
same formulas). Every pixel value of an ideal rendered edge equals ESF(d) at the
perpendicular distance d of the pixel centre from the edge, which is what the
slanted-edge method samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize, signal

from ..errors import MeasureError
from .psf import gauss_pixel_esf, gauss_pixel_lsf, gauss_pixel_mtf

__all__ = [
    "EdgeTruth",
    "FamilyTruth",
    "PsfFamily",
    "edge_truth",
    "family_edge",
    "family_truth",
    "kernel_truth",
    "slanted_edge",
    "truth_esf",
    "truth_lsf",
    "truth_mtf",
    "unsharp_mask",
    "unsharp_truth",
]


def _check_sigma(sigma_px: float) -> None:
    if not np.isfinite(sigma_px) or sigma_px <= 0:
        raise MeasureError(f"sigma_px must be a positive number of pixels, got {sigma_px!r}")


def truth_lsf(d: np.ndarray, *, sigma_px: float, angle_deg: float) -> np.ndarray:
    """Analytic LSF (area 1, 1/px) of Gaussian PSF * square pixel along the edge normal."""
    _check_sigma(sigma_px)
    return gauss_pixel_lsf(d, sigma_px, angle_deg)


def truth_esf(d: np.ndarray, *, sigma_px: float, angle_deg: float) -> np.ndarray:
    """Analytic normalised ESF (0 dark .. 1 bright) along the edge normal; d > 0 is bright."""
    _check_sigma(sigma_px)
    return gauss_pixel_esf(d, sigma_px, angle_deg)


def truth_mtf(f: np.ndarray, *, sigma_px: float, angle_deg: float) -> np.ndarray:
    """Analytic MTF at spatial frequency f (cycles/px) along the edge normal."""
    _check_sigma(sigma_px)
    return gauss_pixel_mtf(f, sigma_px, angle_deg)


@dataclass(frozen=True)
class EdgeTruth:
    """Estimators of the true system response of a rendered edge (pixel units).

    ``sigma_px`` is the Gaussian PSF's sigma, or None for a measured kernel.
    """

    sigma_px: float | None
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
        return (
            float(truth_lsf(np.array([x]), sigma_px=sigma_px, angle_deg=angle_deg)[0])
            - level * peak
        )

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
        edge_slope_per_px=float(
            truth_lsf(np.array([0.0]), sigma_px=sigma_px, angle_deg=angle_deg)[0]
        ),
    )


def _render_kernel(psf: np.ndarray, psf_step_px: float, supersample: int) -> np.ndarray:
    """The kernel as the renderer applies it: resampled to 1/supersample px, >= 0, sum 1."""
    kernel = np.asarray(psf, dtype=float)
    if kernel.ndim != 2 or not np.isfinite(kernel).all() or kernel.sum() <= 0:
        raise MeasureError("psf must be a 2-D kernel of finite values with a positive sum")
    zoom = psf_step_px * supersample
    if zoom != 1.0:
        kernel = ndimage.zoom(kernel, zoom, order=1)
    kernel = np.clip(kernel, 0.0, None)
    return kernel / kernel.sum()


def _level_width(x: np.ndarray, y: np.ndarray, level: float) -> float:
    """Width of a single-peaked curve at ``level`` of its peak (outermost crossings, linear)."""
    h = level * float(y.max())
    above = np.flatnonzero(y >= h)
    i, j = int(above[0]), int(above[-1])
    xl = x[i - 1] + (h - y[i - 1]) * (x[i] - x[i - 1]) / (y[i] - y[i - 1])
    xr = x[j] + (h - y[j]) * (x[j + 1] - x[j]) / (y[j + 1] - y[j])
    return float(xr - xl)


def kernel_truth(
    psf: np.ndarray,
    *,
    angle_deg: float,
    psf_step_px: float = 1.0,
    supersample: int = 15,
    step_px: float = 0.002,
) -> EdgeTruth:
    """True estimators of an edge rendered by :func:`slanted_edge` with a measured ``psf``.

    Numerical, not closed-form: the kernel (as rendered) is projected on the edge normal
    (each sample's weight lands at its distance u = x cos t - y sin t, split linearly
    between the two nearest points of a ``step_px`` grid), then convolved with the
    pixel's footprint boxes |cos t| and |sin t| and with the renderer's 1/supersample
    px coverage ramp. MTF(f) = |sum k e^(-2 pi i f u)| |sinc(f cos t)| |sinc(f sin t)|
    |sinc(f / supersample)| exactly. RER is taken about the point where the ESF is 0.5
    (the LSF peak for a symmetric kernel).
    """
    if supersample < 1:
        raise MeasureError(f"supersample must be >= 1, got {supersample}")
    k = _render_kernel(psf, psf_step_px, supersample)
    h = 1.0 / supersample
    ny, nx = k.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    t = np.deg2rad(angle_deg)
    u = ((xx - (nx - 1) / 2) * np.cos(t) - (yy - (ny - 1) / 2) * np.sin(t)).ravel() * h
    w = k.ravel()
    a, b = abs(float(np.cos(t))), abs(float(np.sin(t)))
    reach = float(np.abs(u).max()) + a + b + h + 1.0
    n = int(np.ceil(reach / step_px))
    x = np.arange(-n, n + 1) * step_px
    pos = (u + n * step_px) / step_px
    i0 = np.floor(pos).astype(np.int64)
    frac = pos - i0
    lsf: np.ndarray = np.bincount(i0, weights=w * (1 - frac), minlength=x.size)[: x.size]
    lsf += np.bincount(i0 + 1, weights=w * frac, minlength=x.size)[: x.size]
    for width in (a, b, h):
        m = max(round(width / step_px), 1)
        if m > 1:
            lsf = np.convolve(lsf, np.full(m, 1.0 / m), mode="same")
    lsf /= lsf.sum() * step_px
    esf = np.cumsum(lsf) * step_px
    mid = float(np.interp(0.5, esf, x))
    e = np.interp([mid - 0.5, mid + 0.5], x, esf)
    otf = np.abs(np.sum(w * np.exp(-2j * np.pi * 0.5 * u)))
    return EdgeTruth(
        sigma_px=None,
        angle_deg=float(angle_deg),
        fwhm_px=_level_width(x, lsf, 0.5),
        width25_px=_level_width(x, lsf, 0.25),
        width80_px=_level_width(x, lsf, 0.80),
        rer=float(e[1] - e[0]),
        mtf_nyquist=float(
            otf * abs(np.sinc(0.5 * a)) * abs(np.sinc(0.5 * b)) * abs(np.sinc(0.5 * h))
        ),
        edge_slope_per_px=float(lsf.max()),
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
    reach = 0.5 * max(np.shape(psf)) * psf_step_px if psf is not None else 6.0 * float(sigma_px or 0.0)
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
        kernel = _render_kernel(psf, psf_step_px, s)
        # fftconvolve treats the outside as 0: pad by edge values first
        pad = max(kernel.shape) // 2 + 1
        padded = np.pad(scene, pad, mode="edge")
        blurred = signal.fftconvolve(padded, kernel, mode="same")[pad:-pad, pad:-pad]
    elif sigma_px is not None and sigma_px > 0:
        blurred = ndimage.gaussian_filter(
            scene, sigma=float(sigma_px) * s, mode="nearest", truncate=6.0
        )
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


def _gauss_taps(sigma_px: float, truncate: float = 4.0) -> tuple[np.ndarray, np.ndarray]:
    """The 1-D kernel ``scipy.ndimage.gaussian_filter`` applies: offsets and weights."""
    r = int(truncate * float(sigma_px) + 0.5)
    n = np.arange(-r, r + 1, dtype=float)
    w = np.exp(-0.5 * (n / sigma_px) ** 2)
    return n, w / w.sum()


def unsharp_mask(img: np.ndarray, *, amount: float, sigma_px: float) -> np.ndarray:
    """Sharpen as image processors do: img + amount * (img - G_sigma * img) on the pixel grid.

    A sharpened edge rings (negative LSF lobes, overshoot), so no blur by a positive PSF
    describes it: the test case for an edge chain's model choice.
    """
    a = np.asarray(img, dtype=float)
    return a + float(amount) * (a - ndimage.gaussian_filter(a, float(sigma_px), mode="nearest"))


def unsharp_truth(
    *,
    sigma_px: float,
    angle_deg: float,
    amount: float,
    mask_sigma_px: float,
    step_px: float = 0.002,
) -> EdgeTruth:
    """True estimators of a Gaussian-blurred edge (``slanted_edge``, no noise) sharpened by
    :func:`unsharp_mask`.

    The image is a function of the perpendicular distance d only, so the separable
    discrete filter h(m) h(n) acts on the ESF as point masses at u = m cos t - n sin t with
    weights h(m) h(n): ESF_s(d) = (1 + k) ESF(d) - k sum w ESF(d - u); likewise the LSF,
    and MTF_s(f) = MTF(f) |1 + k - k sum w cos(2 pi f u)| exactly (MTF(f): closed form).
    """
    _check_sigma(sigma_px)
    _check_sigma(mask_sigma_px)
    n, h = _gauss_taps(mask_sigma_px)
    t = np.deg2rad(angle_deg)
    u = (n[:, None] * np.cos(t) - n[None, :] * np.sin(t)).ravel()
    w = (h[:, None] * h[None, :]).ravel()
    reach = float(np.abs(u).max()) + 8.0 * sigma_px + 2.0
    x = np.arange(-reach, reach + step_px / 2, step_px)
    k = float(amount)

    def lsf_at(q: np.ndarray) -> np.ndarray:
        blur = sum(
            wi * gauss_pixel_lsf(q - ui, sigma_px, angle_deg) for ui, wi in zip(u, w, strict=True)
        )
        return (1.0 + k) * gauss_pixel_lsf(q, sigma_px, angle_deg) - k * blur

    def esf_at(q: np.ndarray) -> np.ndarray:
        blur = sum(
            wi * gauss_pixel_esf(q - ui, sigma_px, angle_deg) for ui, wi in zip(u, w, strict=True)
        )
        return (1.0 + k) * gauss_pixel_esf(q, sigma_px, angle_deg) - k * blur

    # only the central part of the LSF matters for the widths
    core = x[np.abs(x) <= 4.0 * sigma_px + 2.0]
    lsf = lsf_at(core)
    e = esf_at(np.array([-0.5, 0.5]))
    gain = abs(1.0 + k - k * float(np.sum(w * np.cos(np.pi * u))))
    return EdgeTruth(
        sigma_px=None,
        angle_deg=float(angle_deg),
        fwhm_px=_level_width(core, lsf, 0.5),
        width25_px=_level_width(core, lsf, 0.25),
        width80_px=_level_width(core, lsf, 0.80),
        rer=float(e[1] - e[0]),
        mtf_nyquist=float(gauss_pixel_mtf(np.array([0.5]), sigma_px, angle_deg)[0]) * gain,
        edge_slope_per_px=float(lsf.max()),
    )


# ---------------------------------------------------------------------------------------------
# PSF families by their optical transfer function (issue 31): truth and rendering from one 2-D OTF
#
# Why a second generator: the seven families of real systems (Gaussian, core + halo, defocus
# disk, motion across and along the edge, 3-tap MTFC sharpening, diffraction x jitter x
# along-track smear) are each known in closed form as an OTF, not as a kernel a supersampled
# renderer could apply without error (a diffraction PSF's tails reach far, a 3-tap filter acts
# on the pixel grid). The image of a straight edge depends on the perpendicular distance d of a
# pixel centre only, so every pixel is dark + (bright - dark) ESF(d), where the system ESF along
# the normal n = (cos t, -sin t) follows from the Fourier slice theorem:
# T(f) = OTF(f cos t, -f sin t) sinc(f cos t) sinc(f sin t) [x H_mtfc(f cos t, -f sin t)],
# inverted numerically on a fine grid. The truth (FWHM, RER, MTF@Ny = |T(0.5)|) comes from the
# same T, computed here and never by the measuring chain's own formulas (measures/psf.py).

_FAMILY_STEP = 1.0 / 128.0  # px, grid of the numerical ESF/LSF
_FAMILY_N = 1 << 17  # samples: a 1,024-px period, so the tails of a diffraction PSF wrap < 1e-4


def _disk_otf(r: np.ndarray, radius: float) -> np.ndarray:
    """OTF of a uniform disk of ``radius`` px at radial frequency r: 2 J1(2 pi R r) / (2 pi R r)."""
    from scipy.special import j1

    z = 2.0 * np.pi * radius * np.asarray(r, dtype=float)
    out = np.ones_like(z)
    nz = np.abs(z) > 1e-12
    out[nz] = 2.0 * j1(z[nz]) / z[nz]
    return out


def _airy_otf(r: np.ndarray, cutoff: float) -> np.ndarray:
    """Diffraction OTF of a circular pupil with cut-off ``cutoff`` cycles/px (1 / (lambda N) in
    pixel units): (2/pi)(acos v - v sqrt(1 - v^2)), v = r / cutoff, 0 beyond."""
    v = np.clip(np.abs(np.asarray(r, dtype=float)) / cutoff, 0.0, 1.0)
    return (2.0 / np.pi) * (np.arccos(v) - v * np.sqrt(1.0 - v * v))


@dataclass(frozen=True)
class PsfFamily:
    """One system of the benchmark grid, given by its parameters (px, cycles/px).

    ``kind``: ``gauss`` (sigma), ``halo`` (core sigma, halo sigma2, halo weight w), ``defocus``
    (disk radius, sigma), ``motion_x`` / ``motion_y`` (box length along image x / y, sigma),
    ``mtfc`` (sigma, 3-tap amount a: [-a, 1 + 2a, -a] along x and along y on the pixel grid),
    ``diffraction`` (cut-off in cycles/px, jitter sigma, along-track smear length along y).
    """

    kind: str
    sigma: float = 0.0
    sigma2: float = 0.0
    weight: float = 0.0
    radius: float = 0.0
    length: float = 0.0
    amount: float = 0.0
    cutoff: float = 0.0

    def otf(self, fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
        """The PSF's 2-D OTF (pixel aperture excluded; the MTFC filter included)."""
        r2 = fx * fx + fy * fy

        def g(s: float) -> np.ndarray:
            return np.exp(-2.0 * np.pi**2 * s * s * r2)

        k = self.kind
        if k == "gauss":
            return g(self.sigma)
        if k == "halo":
            return (1.0 - self.weight) * g(self.sigma) + self.weight * g(self.sigma2)
        if k == "defocus":
            return _disk_otf(np.sqrt(r2), self.radius) * g(self.sigma)
        if k == "motion_x":
            return np.sinc(self.length * fx) * g(self.sigma)
        if k == "motion_y":
            return np.sinc(self.length * fy) * g(self.sigma)
        if k == "mtfc":
            a = self.amount
            return (
                g(self.sigma)
                * (1 + 2 * a - 2 * a * np.cos(2 * np.pi * fx))
                * (1 + 2 * a - 2 * a * np.cos(2 * np.pi * fy))
            )
        if k == "diffraction":
            return _airy_otf(np.sqrt(r2), self.cutoff) * g(self.sigma) * np.sinc(self.length * fy)
        raise MeasureError(f"unknown PSF family {k!r}")

    def label(self) -> str:
        k = self.kind
        if k == "gauss":
            return f"gauss s{self.sigma:g}"
        if k == "halo":
            return f"halo s{self.sigma:g}+{self.weight:g}*s{self.sigma2:g}"
        if k == "defocus":
            return f"defocus R{self.radius:g} s{self.sigma:g}"
        if k in ("motion_x", "motion_y"):
            return f"{k} L{self.length:g} s{self.sigma:g}"
        if k == "mtfc":
            return f"mtfc a{self.amount:g} s{self.sigma:g}"
        return f"diffraction fc{self.cutoff:g} j{self.sigma:g} L{self.length:g}"


@dataclass(frozen=True, eq=False)
class FamilyTruth:
    """The system response of a :class:`PsfFamily` along an edge normal, and its estimators."""

    family: PsfFamily
    angle_deg: float
    x: np.ndarray  # px, perpendicular distance (bright side > 0)
    esf: np.ndarray
    lsf: np.ndarray
    fwhm_px: float
    rer: float
    mtf_nyquist: float

    def mtf(self, f: np.ndarray) -> np.ndarray:
        """|T(f)| at ``f`` cycles/px along the normal."""
        return np.abs(_normal_otf(self.family, self.angle_deg, np.asarray(f, dtype=float)))


def _normal_otf(fam: PsfFamily, angle_deg: float, f: np.ndarray) -> np.ndarray:
    t = np.deg2rad(angle_deg)
    fx, fy = f * np.cos(t), -f * np.sin(t)
    return fam.otf(fx, fy) * np.sinc(fx) * np.sinc(fy)


def family_truth(fam: PsfFamily, *, angle_deg: float) -> FamilyTruth:
    """ESF, LSF and the estimators of ``fam`` x square pixel along the normal of an edge at
    ``angle_deg`` (numerical inverse of the 1-D OTF on a 1/128-px grid, 1,024-px period).

    FWHM at half the LSF's peak (outermost crossings); RER = ESF(c + 0.5) - ESF(c - 0.5) about
    the point c where the ESF is 0.5 (every family here is symmetric, so c is the LSF's centre);
    MTF@Ny = |T(0.5)| exactly.
    """
    n, h = _FAMILY_N, _FAMILY_STEP
    f = np.fft.rfftfreq(n, h)
    spec = _normal_otf(fam, angle_deg, f).astype(complex)
    lsf = np.fft.fftshift(np.fft.irfft(spec, n)) / h
    x = (np.arange(n) - n // 2) * h
    esf = np.cumsum(lsf) * h
    esf = esf - 0.5 * lsf * h  # trapezoid: the value at x, not after it
    esf -= esf[0]
    esf /= esf[-1]
    mid = float(np.interp(0.5, esf[(x > -8) & (x < 8)], x[(x > -8) & (x < 8)]))
    core = np.abs(x) <= 100.0
    e = np.interp([mid - 0.5, mid + 0.5], x, esf)
    return FamilyTruth(
        family=fam,
        angle_deg=float(angle_deg),
        x=x[core],
        esf=esf[core],
        lsf=lsf[core],
        fwhm_px=_level_width(x[core], lsf[core], 0.5),
        rer=float(e[1] - e[0]),
        mtf_nyquist=float(np.abs(_normal_otf(fam, angle_deg, np.array([0.5])))[0]),
    )


def family_edge(
    fam: PsfFamily,
    shape: tuple[int, int],
    *,
    angle_deg: float,
    dark: float,
    bright: float,
    snr: float | None = None,
    bit_depth: int | None = None,
    offset_px: float = 0.0,
    rng: np.random.Generator | None = None,
    truth: FamilyTruth | None = None,
) -> np.ndarray:
    """Render an edge of ``fam``: every pixel is dark + (bright - dark) ESF(d) at the
    perpendicular distance d of its centre (as :func:`slanted_edge`: the edge turned by
    ``angle_deg`` from the columns, bright on the right), plus Gaussian noise of std
    (bright - dark) / snr, rounded and clipped to ``bit_depth`` (uint8 / uint16) when given.

    A 3-tap MTFC family is the sharpened product (the filter acts on the noise-free image; the
    noise is the product's). Beyond the +-100 px kept in the truth the ESF is taken as its end
    values (a diffraction tail still holds 1e-3 of the step there; nothing else does).
    """
    tr = truth if truth is not None else family_truth(fam, angle_deg=angle_deg)
    rows, cols = int(shape[0]), int(shape[1])
    yy, xx = np.mgrid[0:rows, 0:cols].astype(float)
    t = np.deg2rad(angle_deg)
    d = (xx - ((cols - 1) / 2.0 + offset_px)) * np.cos(t) - (yy - (rows - 1) / 2.0) * np.sin(t)
    img = dark + (bright - dark) * np.interp(d, tr.x, tr.esf)
    if snr is not None and math.isfinite(snr):
        gen = rng if rng is not None else np.random.default_rng(0)
        img = img + gen.normal(0.0, abs(bright - dark) / float(snr), size=img.shape)
    if bit_depth:
        full = float(2**bit_depth - 1)
        return np.clip(np.rint(img), 0, full).astype(np.uint8 if bit_depth <= 8 else np.uint16)
    return img
