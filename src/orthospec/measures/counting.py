"""Counting pixel values fast: the one-bin-per-DN layout, bincount through a reused buffer,
Pillow's C byte histogram, and the per-thread work arrays a streaming scan reuses.

Pure numeric layer: nothing here opens a file or starts a thread. A caller that runs its own
threads may lend one for counting long arrays in two halves (:func:`counting_helper`): bincount's
loop releases the GIL, so a second core halves the time; without a helper everything is counted
in the calling thread (the counts are the same either way).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from concurrent.futures import Executor
from contextlib import contextmanager
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import DTypeLike

#: Pixels per slab of the per-pixel noise and luminosity arithmetic: float32 temporaries of
#: this size stay in the CPU cache, which matters more than anything when several worker
#: processes share the memory bandwidth.
SLAB_PIXELS = 1 << 16


def histogram_layout(dtype: np.dtype | str) -> tuple[int, int] | None:
    """(offset, bins) of the one-bin-per-DN histogram of an integer dtype up to 16 bits, else
    None."""
    dt = np.dtype(dtype)
    if dt.kind == "b":
        return 0, 2
    if dt.kind not in "ui" or dt.itemsize > 2:
        return None
    bins = 1 << (8 * dt.itemsize)
    return (-(bins // 2) if dt.kind == "i" else 0), bins


def _as_bin_index(values: np.ndarray) -> np.ndarray:
    """Map integer DNs to histogram bin indices without widening (signed -> offset binary)."""
    if values.dtype == np.int8:
        return values.view(np.uint8) ^ np.uint8(0x80)
    if values.dtype == np.int16:
        return values.view(np.uint16) ^ np.uint16(0x8000)
    if values.dtype == np.bool_:
        return values.view(np.uint8)
    return values


_BINCOUNT_SLICE = 1 << 18  # elements per bincount call, converted into a reused intp buffer
_buffers = threading.local()


def _intp_buffer() -> np.ndarray:
    """This thread's reusable intp buffer for bincount's input.

    Without it bincount converts every slice into a fresh intp array (MBs): allocating and
    page-faulting that temporary cost more than the counting itself in a streaming scan.
    """
    buf = getattr(_buffers, "intp", None)
    if buf is None:
        buf = _buffers.intp = np.empty(_BINCOUNT_SLICE, dtype=np.intp)
    return buf


def scratch(name: str, shape: tuple[int, ...], dtype: DTypeLike) -> np.ndarray:
    """This thread's reusable work array ``name`` of ``shape`` (contents undefined).

    A streaming scan needs the same temporaries for every chunk (the luminosity, the darkest
    colour value): a fresh multi-MB array per chunk is memory the kernel zeroes and maps page
    by page and takes back on free, a few % of a full scan's CPU. One per thread, so the
    counting threads never share one; it lives as long as its thread.
    """
    store: dict[str, np.ndarray] | None = getattr(_buffers, "scratch", None)
    if store is None:
        store = _buffers.scratch = {}
    dt = np.dtype(dtype)
    n = math.prod(shape)
    buf = store.get(name)
    if buf is None or buf.dtype != dt or buf.size < n:
        buf = store[name] = np.empty(n, dtype=dt)
    return buf[:n].reshape(shape)


def _bincount_serial(out: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``out += np.bincount(values, minlength=out.size)`` slice by slice through the buffer."""
    buf = _intp_buffer()
    for i in range(0, values.size, _BINCOUNT_SLICE):
        part = values[i : i + _BINCOUNT_SLICE]
        b = buf[: part.size]
        b[...] = part
        out += np.bincount(b, minlength=out.size)
    return out


#: Arrays at least this long are counted in two halves, one in the helper thread lent by
#: :func:`counting_helper`: bincount's counting loop and the dtype conversion release the GIL,
#: so a second core halves the time.
PARALLEL_BINCOUNT_MIN = 1 << 20


@contextmanager
def counting_helper(pool: Executor | None) -> Iterator[None]:
    """Let this thread count long arrays in two halves, one of them in ``pool`` (None: alone).

    The pool belongs to the caller (the raster scan owns its threads, raster/scan.py); only the
    thread that entered the block uses it, so counting threads that already run in parallel
    are not given one.
    """
    before = getattr(_buffers, "helper", None)
    _buffers.helper = pool
    try:
        yield
    finally:
        _buffers.helper = before


def _bincount_into(out: np.ndarray, values: np.ndarray) -> None:
    """Add the counts of ``values`` to ``out`` (integer counts: any split gives the same sum)."""
    helper: Executor | None = getattr(_buffers, "helper", None)
    if values.size < PARALLEL_BINCOUNT_MIN or helper is None:
        _bincount_serial(out, values)
        return
    half = values.size // 2 // _BINCOUNT_SLICE * _BINCOUNT_SLICE or values.size // 2
    other = helper.submit(_bincount_serial, np.zeros_like(out), values[half:])
    _bincount_serial(out, values[:half])
    out += other.result()


#: Largest array Pillow counts in one call (its image width is a C int).
_PILLOW_MAX = 2**31 - 1


@lru_cache(maxsize=1)
def _pillow_image() -> Any:
    """``PIL.Image`` when Pillow is installed (it is, as WeasyPrint's dependency), else None."""
    try:
        from PIL import Image
    except ImportError:  # numpy's bincount counts instead (same counts, slower)
        return None
    return Image


def _pillow_counts(v: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray | None:
    """Counts of the 256 byte values of a contiguous 1-D uint8 array where ``mask`` (bool or
    uint8, same size) is non-zero.

    Pillow's C ``Image.histogram`` of a zero-copy ``"L"`` view of the bytes (``frombuffer``
    maps the array's memory, no copy): a plain count loop over the bytes, about 3x less CPU
    than np.bincount, which must first widen every value to an intp index. None when Pillow
    is not installed or the array does not fit one image row.
    """
    image = _pillow_image()
    if image is None or not 0 < v.size <= _PILLOW_MAX:
        return None
    size = (int(v.size), 1)
    im = image.frombuffer("L", size, v, "raw", "L", 0, 1)
    if mask is None:
        counts = im.histogram()
    else:
        m = np.ascontiguousarray(mask).ravel().view(np.uint8)  # non-zero: count this pixel
        counts = im.histogram(image.frombuffer("L", size, m, "raw", "L", 0, 1))
    return np.array(counts, dtype=np.int64)


def fast_bincount(values: np.ndarray, bins: int) -> np.ndarray:
    """``np.bincount(values, minlength=bins)`` for unsigned 8/16-bit values, 3-7x faster.

    Bytes are counted by Pillow's C histogram (:func:`_pillow_counts`); without Pillow, and
    for 16-bit values, bytes are counted in pairs (a uint16 view, 65536 bins, folded back to
    256) and long arrays go through bincount in slices converted into one reused intp buffer.
    """
    v = np.ascontiguousarray(values).ravel()
    if v.dtype == np.uint8 and bins == 256:
        counts = _pillow_counts(v)
        if counts is not None:
            return counts
    return numpy_bincount(v, bins)


def numpy_bincount(values: np.ndarray, bins: int) -> np.ndarray:
    """:func:`fast_bincount` by numpy alone (16-bit values; bytes when Pillow is missing)."""
    v = np.ascontiguousarray(values).ravel()
    if (
        v.size <= _BINCOUNT_SLICE
    ):  # a small block: the 65536 pair bins would cost more than they save
        return np.bincount(v, minlength=bins).astype(np.int64, copy=False)
    out = np.zeros(bins, dtype=np.int64)
    if v.dtype.itemsize == 1 and bins == 256:
        if v.size % 2:
            out[int(v[-1])] += 1
            v = v[:-1]
        acc = np.zeros(65536, dtype=np.int64)
        _bincount_into(acc, v.view(np.uint16))
        folded = acc.reshape(256, 256)
        out += folded.sum(axis=0) + folded.sum(axis=1)
        return out
    _bincount_into(out, v)
    return out
