"""Luminosity of RGB orthoimages (Rec. ITU-R BT.601 luma), exact for unsigned bands."""

from __future__ import annotations

import numpy as np

from .counting import SLAB_PIXELS, scratch

#: Rec. ITU-R BT.601 luma weights used for the luminosity histogram (R, G, B).
LUMA_WEIGHTS: tuple[float, float, float] = (0.299, 0.587, 0.114)


def luminosity(r: np.ndarray, g: np.ndarray, b: np.ndarray, dtype: np.dtype | str) -> np.ndarray:
    """Rec.601 luma Y = 0.299 R + 0.587 G + 0.114 B rounded half up, in the bands' dtype.

    Unsigned integer bands are computed exactly in integers,
    Y = (299 R + 587 G + 114 B + 500) // 1000, so ties round up with no float error.
    """
    dt = np.dtype(dtype)
    if dt.kind == "u" and dt.itemsize <= 2:
        y = r.astype(np.uint32) * np.uint32(299)
        y += g.astype(np.uint32) * np.uint32(587)
        y += b.astype(np.uint32) * np.uint32(114)
        y += np.uint32(500)
        y //= np.uint32(1000)
        return y.astype(dt)
    wr, wg, wb = LUMA_WEIGHTS
    yf = r.astype(np.float64) * wr + g.astype(np.float64) * wg + b.astype(np.float64) * wb
    yf = np.floor(yf + 0.5)
    if dt.kind in "ui":
        info = np.iinfo(dt)
        np.clip(yf, info.min, info.max, out=yf)
    return yf.astype(dt)


#: The Rec. 601 weights in thousandths, for the exact integer luminosity.
_LUMA_PER_MILLE = np.array([299, 587, 114], dtype=np.uint32)


def luminosity_block(
    r: np.ndarray,
    g: np.ndarray,
    b: np.ndarray,
    dtype: np.dtype | str,
    *,
    out: np.ndarray | None = None,
    planes: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`luminosity` of whole 2-D blocks, worked through in cache-sized slabs of rows.

    Same values; unsigned bands reuse two uint32 work buffers of ``SLAB_PIXELS`` (no fresh
    temporaries per operation), which made the luminosity histogram about 25 % cheaper.
    ``out`` (the blocks' shape, ``dtype``) receives the values instead of a new array.
    ``planes``, when r, g and b are the consecutive planes of one (3, rows, cols) array, lets
    one ``einsum`` pass form 299 R + 587 G + 114 B (exact in uint32: at most 1000 x 65535),
    about 10 % faster than three multiplications and two additions.
    """
    dt = np.dtype(dtype)
    y = np.empty(r.shape, dtype=dt) if out is None else out
    step = max(1, SLAB_PIXELS // max(r.shape[-1], 1))
    if not (dt.kind == "u" and dt.itemsize <= 2 and r.ndim == 2):
        for r0 in range(0, r.shape[0], step):
            sl = slice(r0, r0 + step)
            y[sl] = luminosity(r[sl], g[sl], b[sl], dt)
        return y
    a = scratch("luminosity-sum", (step, r.shape[1]), np.uint32)
    t = scratch("luminosity-term", (step, r.shape[1]), np.uint32)
    if planes is not None and planes.shape == (3, *r.shape) and planes.dtype == r.dtype:
        for r0 in range(0, r.shape[0], step):
            sl = slice(r0, r0 + step)
            acc = a[: r[sl].shape[0]]
            np.einsum(
                "i,ijk->jk",
                _LUMA_PER_MILLE,
                planes[:, sl],
                dtype=np.uint32,
                casting="unsafe",
                out=acc,
            )  # unsafe: the uint8/16 values widen
            acc += np.uint32(500)
            acc //= np.uint32(1000)
            y[sl] = acc
        return y
    for r0 in range(0, r.shape[0], step):
        sl = slice(r0, r0 + step)
        n = r[sl].shape[0]
        acc, tmp = a[:n], t[:n]
        np.multiply(r[sl], np.uint32(299), out=acc)
        np.multiply(g[sl], np.uint32(587), out=tmp)
        acc += tmp
        np.multiply(b[sl], np.uint32(114), out=tmp)
        acc += tmp
        acc += np.uint32(500)
        acc //= np.uint32(1000)
        y[sl] = acc
    return y
