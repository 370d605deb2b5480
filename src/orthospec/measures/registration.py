"""Band-to-band registration: sub-pixel shift by phase correlation (geometry, not radiometry).

Guizar-Sicairos, Thurman & Fienup (2008) upsampled DFT refinement; used for the band
misregistration of a scan (JRC EUR 23638 EN §6.3) and by image matching (measures/matching.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import MeasureError


@dataclass(frozen=True)
class Shift:
    """Displacement of a moving band relative to a reference band, in pixels.

    ``moving(row, col) ~= reference(row - dy, col - dx)``; ``peak`` is the normalised
    phase-correlation peak (1 = identical up to the shift, near 0 = no correlation).
    """

    dy: float
    dx: float
    peak: float

    @property
    def magnitude(self) -> float:
        return math.hypot(self.dy, self.dx)


def _upsampled_dft(
    data: np.ndarray, region: int, factor: float, offsets: tuple[float, float]
) -> np.ndarray:
    """Matrix-multiply DFT of ``data`` on a ``region``^2 grid upsampled by ``factor``.

    Guizar-Sicairos, Thurman & Fienup (2008), "Efficient subpixel image registration
    algorithms", Opt. Lett. 33(2): only the neighbourhood of the coarse peak is evaluated,
    as K_rows @ data @ K_cols^T. Computed with ``einsum`` (no BLAS): the products are small,
    and multi-threaded BLAS in every worker process oversubscribes the cores and makes the
    last digits depend on the thread count. Each complex product is four real ones: numpy's
    real sum-of-products loops are vectorised, its complex ones are not (2x faster).
    """
    kernels = []
    for axis in (0, 1):
        freq = np.fft.fftfreq(data.shape[axis], factor)
        kernels.append(
            np.exp(-2j * np.pi * (np.arange(region) - offsets[axis])[:, None] * freq[None, :])
        )
    rows = _complex_einsum("rm,mn->rn", kernels[0], data)
    return _complex_einsum("rn,cn->rc", rows, kernels[1])


def _complex_einsum(spec: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.einsum(spec, a, b)`` of two complex matrices through real einsums (no BLAS)."""
    ar, ai = np.ascontiguousarray(a.real), np.ascontiguousarray(a.imag)
    br, bi = np.ascontiguousarray(b.real), np.ascontiguousarray(b.imag)

    def e(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.einsum(spec, x, y, optimize=False)

    out = (e(ar, br) - e(ai, bi)).astype(np.complex128)
    out.imag = e(ar, bi) + e(ai, br)
    return out


def tapered_spectrum(image: np.ndarray) -> np.ndarray:
    """FFT of a demeaned, Hann-tapered image (the taper removes wrap-around edge effects)."""
    a = np.asarray(image, dtype=np.float64)
    if a.ndim != 2 or min(a.shape) < 8:
        raise MeasureError(f"phase correlation needs a 2-D array of at least 8x8, got {a.shape}")
    return np.fft.fft2((a - a.mean()) * _hann2d(*a.shape))


@lru_cache(maxsize=8)
def _hann2d(rows: int, cols: int) -> np.ndarray:
    """The 2-D Hann taper of a window shape (every window of an image, every image of a tile
    delivery has the same shape: built once)."""
    win = np.outer(np.hanning(rows), np.hanning(cols))
    win.flags.writeable = False
    return win


def phase_correlation(reference: np.ndarray, moving: np.ndarray, *, upsample: int = 20) -> Shift:
    """Sub-pixel shift of ``moving`` relative to ``reference`` by phase correlation.

    Both images are demeaned and tapered with a Hann window, the normalised cross-power
    spectrum gives the integer peak, which the upsampled DFT refines to 1/``upsample`` px.
    """
    ref, mov = np.asarray(reference), np.asarray(moving)
    if ref.shape != mov.shape or ref.ndim != 2:
        raise MeasureError(
            f"phase correlation needs two equal 2-D arrays of at least 8x8, "
            f"got {ref.shape} and {mov.shape}"
        )
    return phase_correlation_spectra(
        tapered_spectrum(ref), tapered_spectrum(mov), upsample=upsample
    )


def phase_correlation_spectra(f_ref: np.ndarray, f_mov: np.ndarray, *, upsample: int = 20) -> Shift:
    """:func:`phase_correlation` from :func:`tapered_spectrum` s (reuse the reference's)."""
    product = f_ref * f_mov.conj()
    product /= np.maximum(np.abs(product), 1e-12)
    cc = np.abs(np.fft.ifft2(product))
    top = int(np.argmax(cc))
    peak_idx = np.unravel_index(top, cc.shape)
    shape = np.array(cc.shape)
    shifts = np.array(peak_idx, dtype=np.float64)
    shifts[shifts > shape // 2] -= shape[shifts > shape // 2]
    peak = float(cc.flat[top])
    if upsample > 1:
        shifts = np.round(shifts * upsample) / upsample
        region = math.ceil(upsample * 1.5)
        centre = float(np.fix(region / 2.0))
        offsets = centre - shifts * upsample
        up = _upsampled_dft(
            product.conj(), region, upsample, (float(offsets[0]), float(offsets[1]))
        ).conj()
        mag = np.abs(up)
        best = int(np.argmax(mag))
        m = np.unravel_index(best, up.shape)
        shifts = shifts + (np.array(m, dtype=np.float64) - centre) / upsample
        peak = float(mag.flat[best]) / product.size
    # ``shifts`` registers moving onto reference; the displacement of moving is its negative
    return Shift(dy=float(-shifts[0]), dx=float(-shifts[1]), peak=peak)


# --------------------------------------------------------------------------- cloud mask
