"""Radiometric measures of orthoimages (JRC EUR 23638 EN §3.2, §6.3), computed block by block.

Pure numeric layer: the accumulators take numpy blocks of pixels plus validity masks and merge,
so a reader can stream a file of any size through them with bounded memory and several workers
can merge partial results. Nothing here opens a file.

Conventions (they match GDAL's exact statistics, ``gdalinfo -stats`` / ``ComputeStatistics``
with ``approx_ok = FALSE``):

* statistics are *exact* (every pixel, never overviews) and the standard deviation is the
  *population* one (divide by N);
* invalid pixels are excluded band by band: pixels equal to the band's nodata value (and NaN
  for floating-point bands); the reader passes a mask instead when the band has no nodata but
  a per-dataset mask or an alpha band, as GDAL does;
* integer bands of at most 16 bits are accumulated as a full histogram, one bin per DN, from
  which min, max, mean and std follow exactly (no rounding drift, any merge order);
* other bands (32-bit integers, floats) use Chan et al.'s pairwise merge of (n, mean, M2) in
  float64, and their histogram is a second pass with ``FLOAT_HISTOGRAM_BINS`` equal bins from
  the exact min to the exact max.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from ..errors import MeasureError

#: Rec. ITU-R BT.601 luma weights used for the luminosity histogram (R, G, B).
LUMA_WEIGHTS: tuple[float, float, float] = (0.299, 0.587, 0.114)

#: Number of equal bins of the histogram of floating-point (and 32-bit integer) bands.
FLOAT_HISTOGRAM_BINS = 256

#: Side of the square windows of the local-standard-deviation noise estimator.
NOISE_WINDOW = 8

#: Percentile of the local standard deviations taken as the noise of homogeneous areas.
NOISE_PERCENTILE = 10.0

#: Tail share used for the robust DRA margins (0.1 % of the valid pixels at each side).
ROBUST_TAIL = 0.001

#: A noise block of integers whose invalid pixels are at most 1 in this many is added whole and
#: the few neighbourhoods and windows touching them are taken out afterwards (same sums).
SPARSE_INVALID = 64

#: (dy, dx, weight) of Immerkaer's 3x3 difference-of-Laplacians kernel [[1,-2,1],[-2,4,-2],[1,-2,1]].
_LAPLACIAN_TAPS = tuple(
    (dy, dx, (1 if dy and dx else -2 if dy or dx else 4)) for dy in (-1, 0, 1) for dx in (-1, 0, 1)
)

# log-spaced bins for the histogram of local standard deviations (0.5 % relative resolution)
_LOCAL_STD_EDGES = np.geomspace(1e-3, 1e6, 4201)
_LOG_STEP = math.log(1e6 / 1e-3) / 4200

#: Pixels per slab of the per-pixel noise and luminosity arithmetic: float32 temporaries of
#: this size stay in the CPU cache, which matters more than anything when several worker
#: processes share the memory bandwidth.
SLAB_PIXELS = 1 << 16


def histogram_layout(dtype: np.dtype | str) -> tuple[int, int] | None:
    """(offset, bins) of the one-bin-per-DN histogram of an integer dtype up to 16 bits, else None."""
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


def scratch(name: str, shape: tuple[int, ...], dtype: np.dtype | str) -> np.ndarray:
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


#: Arrays at least this long are counted in two halves, one in a helper thread: bincount's
#: counting loop and the dtype conversion release the GIL, so a second core halves the time.
PARALLEL_BINCOUNT_MIN = 1 << 20
_helper: dict[str, Any] = {"pid": None, "pool": None}


def _helper_pool() -> Any:
    """One helper thread per process (re-created after a fork: threads do not survive it)."""
    if _helper["pid"] != os.getpid():
        from concurrent.futures import ThreadPoolExecutor

        _helper["pool"] = ThreadPoolExecutor(max_workers=1, thread_name_prefix="orthospec-count")
        _helper["pid"] = os.getpid()
    return _helper["pool"]


@contextmanager
def serial_counting() -> Iterator[None]:
    """Count without the helper thread in this thread (its caller already runs in parallel)."""
    before = getattr(_buffers, "serial", False)
    _buffers.serial = True
    try:
        yield
    finally:
        _buffers.serial = before


def _bincount_into(out: np.ndarray, values: np.ndarray) -> None:
    """Add the counts of ``values`` to ``out`` (integer counts: any split gives the same sum)."""
    if (
        values.size < PARALLEL_BINCOUNT_MIN
        or (os.cpu_count() or 1) < 2
        or getattr(_buffers, "serial", False)
    ):
        _bincount_serial(out, values)
        return
    half = values.size // 2 // _BINCOUNT_SLICE * _BINCOUNT_SLICE or values.size // 2
    other = _helper_pool().submit(_bincount_serial, np.zeros_like(out), values[half:])
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


@dataclass
class HistogramAccumulator:
    """Exact per-DN histogram of one integer band; merges by adding counts."""

    offset: int
    counts: np.ndarray
    total: int = 0

    @classmethod
    def for_dtype(cls, dtype: np.dtype | str) -> HistogramAccumulator:
        layout = histogram_layout(dtype)
        if layout is None:
            raise MeasureError(f"dtype {np.dtype(dtype)} has no exact per-DN histogram (>16 bit)")
        offset, bins = layout
        return cls(offset=offset, counts=np.zeros(bins, dtype=np.int64))

    def add(self, data: np.ndarray, valid: np.ndarray | None = None) -> None:
        """Add a block; ``valid`` (bool, same shape) selects the pixels to count."""
        self.total += int(data.size)
        if valid is not None:
            # Selecting the valid pixels copies them (a slow boolean gather); usually all or
            # nearly all are valid: count everything, then take the few invalid ones back out.
            invalid = int(valid.size - np.count_nonzero(valid))
            if invalid == 0:
                valid = None
            elif (counts := self._masked_bytes(data, valid)) is not None:
                self.counts += counts  # 8-bit: Pillow counts under the mask, no selection
                return
            elif invalid <= valid.size // 4:
                counts = fast_bincount(_as_bin_index(data.ravel()), self.counts.size)
                counts -= fast_bincount(_as_bin_index(data[~valid]), self.counts.size)
                self.counts += counts
                return
        values = data.ravel() if valid is None else data[valid]
        if values.size:
            self.counts += fast_bincount(_as_bin_index(values), self.counts.size)

    def _masked_bytes(self, data: np.ndarray, valid: np.ndarray) -> np.ndarray | None:
        """Counts of an 8-bit block's valid pixels by Pillow's masked histogram, else None."""
        if self.counts.size != 256 or data.dtype.itemsize != 1 or data.shape != valid.shape:
            return None
        values = _as_bin_index(np.ascontiguousarray(data).ravel())
        return _pillow_counts(values, valid)

    def add_where(self, data: np.ndarray, selector: np.ndarray) -> None:
        """Add the pixels of a block where ``selector`` (uint8 or bool, same shape) is non-zero.

        For bytes the selector is Pillow's histogram mask as it is: the luminosity passes the
        darkest of the three colour values, non-zero exactly where no band holds nodata 0,
        without a comparison pass or a list of the invalid pixels.
        """
        if self.counts.size == 256 and data.dtype.itemsize == 1 and data.shape == selector.shape:
            counts = _pillow_counts(_as_bin_index(np.ascontiguousarray(data).ravel()), selector)
            if counts is not None:
                self.total += int(data.size)
                self.counts += counts
                return
        self.add(data, selector != 0)

    def add_excluding(self, data: np.ndarray, invalid: np.ndarray) -> None:
        """Add a block except the pixels at the flat indices ``invalid`` (few, e.g. nodata)."""
        self.total += int(data.size)
        flat = data.ravel()
        counts = fast_bincount(_as_bin_index(flat), self.counts.size)
        if invalid.size:
            counts -= fast_bincount(_as_bin_index(flat[invalid]), self.counts.size)
        self.counts += counts

    def merge(self, other: HistogramAccumulator) -> HistogramAccumulator:
        if other.offset != self.offset or other.counts.size != self.counts.size:
            raise MeasureError("cannot merge histograms of different layouts")
        self.counts += other.counts
        self.total += other.total
        return self

    def exclude_value(self, value: float | None) -> int:
        """Drop the bin of ``value`` (the band's nodata) and return how many pixels it held."""
        if value is None or not np.isfinite(value) or value != int(value):
            return 0
        idx = int(value) - self.offset
        if not 0 <= idx < self.counts.size:
            return 0
        n = int(self.counts[idx])
        self.counts[idx] = 0
        return n

    def moments(self) -> Moments:
        """Exact count, min, max, mean and population std from the histogram.

        The sums S1 = sum(count * DN) and S2 = sum(count * DN^2) are exact integers, so the
        mean S1 / n and the variance (n * S2 - S1^2) / n^2 are the exact rationals, each
        rounded once to a float: no cancellation, and the same bits on every machine (a float
        dot product through BLAS summed in an order that depends on its thread count).
        """
        n = int(self.counts.sum())
        if n == 0:
            return Moments()
        nz = np.flatnonzero(self.counts)
        weights = self.counts[nz].astype(np.int64)
        dn = nz.astype(np.int64) + self.offset
        # int64 is exact while n * max|DN|^2 < 2^63 (a 16-bit image below 2.1e9 pixels);
        # Python ints beyond that
        top = max(abs(int(dn[0])), abs(int(dn[-1])), 1)
        if n * top * top < 2**63:
            s1, s2 = int(np.dot(weights, dn)), int(np.dot(weights, dn * dn))
        else:
            w, d = weights.astype(object), dn.astype(object)
            s1, s2 = int(np.dot(w, d)), int(np.dot(w, d * d))
        var = (n * s2 - s1 * s1) / (n * n)  # int / int: Python rounds the exact quotient once
        return Moments(n=n, mean=s1 / n, m2=var * n, vmin=float(dn[0]), vmax=float(dn[-1]))


@dataclass
class Moments:
    """Count, mean, sum of squared deviations, min and max; merged pairwise (Chan et al. 1979)."""

    n: int = 0
    mean: float = 0.0
    m2: float = 0.0
    vmin: float = math.inf
    vmax: float = -math.inf

    def add(self, data: np.ndarray, valid: np.ndarray | None = None) -> None:
        values = data.ravel() if valid is None else data[valid]
        if values.size == 0:
            return
        v = values.astype(np.float64, copy=False)
        mean = float(v.mean())
        block = Moments(
            n=int(v.size),
            mean=mean,
            m2=float(np.square(v - mean).sum()),
            vmin=float(v.min()),
            vmax=float(v.max()),
        )
        self.merge(block)

    def merge(self, other: Moments) -> Moments:
        if other.n == 0:
            return self
        if self.n == 0:
            self.n, self.mean, self.m2 = other.n, other.mean, other.m2
            self.vmin, self.vmax = other.vmin, other.vmax
            return self
        n = self.n + other.n
        delta = other.mean - self.mean
        self.mean += delta * other.n / n
        self.m2 += other.m2 + delta * delta * self.n * other.n / n
        self.n = n
        self.vmin = min(self.vmin, other.vmin)
        self.vmax = max(self.vmax, other.vmax)
        return self

    @property
    def std(self) -> float:
        """Population standard deviation (divide by N), as GDAL reports it."""
        return math.sqrt(max(self.m2, 0.0) / self.n) if self.n else math.nan


@dataclass
class BinnedHistogramAccumulator:
    """Histogram with equal bins over [lo, hi] (second pass for float / 32-bit bands)."""

    lo: float
    hi: float
    bins: int = FLOAT_HISTOGRAM_BINS
    counts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        if self.counts.size == 0:
            self.counts = np.zeros(self.bins, dtype=np.int64)

    def add(self, data: np.ndarray, valid: np.ndarray | None = None) -> None:
        values = data.ravel() if valid is None else data[valid]
        if values.size == 0:
            return
        hi = self.hi if self.hi > self.lo else self.lo + 1.0
        counts, _ = np.histogram(values, bins=self.bins, range=(self.lo, hi))
        self.counts += counts

    def merge(self, other: BinnedHistogramAccumulator) -> BinnedHistogramAccumulator:
        self.counts += other.counts
        return self

    @property
    def edges(self) -> np.ndarray:
        hi = self.hi if self.hi > self.lo else self.lo + 1.0
        return np.linspace(self.lo, hi, self.bins + 1)


@dataclass
class NoiseAccumulator:
    """Two noise estimators that stream over blocks and merge.

    * Immerkær (1996) fast noise variance: sigma = sqrt(pi/2) * sum|I * N| / (6 * M), where N is
      the 3x3 difference-of-Laplacians kernel [[1,-2,1],[-2,4,-2],[1,-2,1]] (it cancels any
      locally linear signal) and M the number of 3x3 neighbourhoods with all pixels valid.
    * Homogeneous areas: the sample std (ddof=1) of every fully valid, non-overlapping
      ``NOISE_WINDOW`` x ``NOISE_WINDOW`` window goes into a log-binned histogram; the
      ``NOISE_PERCENTILE``-th percentile of those local stds, divided by the same percentile of
      the std of pure Gaussian noise of unit sigma over such a window (chi distribution), is
      the estimate. It is unbiased on a flat image with Gaussian noise and robust to textures
      that cover less than ~90 % of the image.
    """

    sum_abs: float = 0.0
    n_lap: int = 0
    local_counts: np.ndarray = field(
        default_factory=lambda: np.zeros(_LOCAL_STD_EDGES.size - 1, dtype=np.int64)
    )
    n_flat: int = 0  # windows whose local std is below the first edge (perfectly flat)

    def add(self, block: np.ndarray, valid: np.ndarray | None = None) -> None:
        """Add a 2-D block; worked through in cache-sized slabs of rows (same result)."""
        block = np.asarray(block)
        if block.ndim != 2:
            raise MeasureError(f"noise needs a 2-D block, got shape {block.shape}")
        h, w = block.shape
        k = NOISE_WINDOW
        invalid = None
        if valid is not None and block.dtype.kind in "uib" and block.dtype.itemsize <= 2:
            # integer sums are exact in any order: a few invalid pixels (scattered nodata DNs)
            # are taken out afterwards instead of masking every neighbourhood and window
            bad = np.flatnonzero(~valid)
            if bad.size * SPARSE_INVALID <= valid.size:
                invalid, valid = np.divmod(bad, w), None
        slab = max(k, (SLAB_PIXELS // max(w, 1)) // k * k)
        stds = []
        # a float block's invalid pixels (NaN, +/-Inf) enter the whole-block arithmetic and
        # leave it through ``valid``: their inf - inf is no warning worth printing
        with np.errstate(invalid="ignore", over="ignore"):
            for r0 in range(0, h, slab):
                r1 = min(h, r0 + slab)
                self._laplacian(block, valid, max(r0, 1), min(r1, h - 1))
                stds.append(self._local_std(block, valid, r0, min(r1, (h // k) * k)))
        sd = np.concatenate(stds) if len(stds) > 1 else stds[0] if stds else None
        if invalid is not None and invalid[0].size:
            sd = self._exclude_invalid(block, *invalid, sd)
        # binned once per block: a few numpy calls on 1/64 of the pixels, not per slab
        if sd is not None:
            self._bin_local_stds(sd)

    def _exclude_invalid(
        self, block: np.ndarray, rows: np.ndarray, cols: np.ndarray, sd: np.ndarray | None
    ) -> np.ndarray | None:
        """Take the neighbourhoods and windows touching the invalid pixels (``rows``,
        ``cols``) back out of an integer block added whole; the local stds that remain.

        The same sums and windows as masking: the Immerkaer sums are exact integers (below
        2^53, so their float total does not depend on the order), and the local stds are
        binned into counts, so removing windows from the list equals never listing them.
        """
        h, w = block.shape
        if h >= 3 and w >= 3:
            # centres of the 3x3 neighbourhoods holding an invalid pixel, inside [1, h-2] x [1, w-2]
            off = np.array([-1, 0, 1])
            cy = (rows[:, None, None] + off[None, :, None]).repeat(3, axis=2).ravel()
            cx = (cols[:, None, None] + off[None, None, :]).repeat(3, axis=1).ravel()
            inside = (cy >= 1) & (cy <= h - 2) & (cx >= 1) & (cx <= w - 2)
            centres = np.unique(cy[inside] * w + cx[inside])
            cy, cx = np.divmod(centres, w)
            lap = np.zeros(centres.size, dtype=np.int64)
            for dy, dx, weight in _LAPLACIAN_TAPS:
                lap += weight * block[cy + dy, cx + dx].astype(np.int64)
            self.sum_abs -= float(np.abs(lap).sum(dtype=np.int64))
            self.n_lap -= int(centres.size)
        if sd is None:
            return None
        k = NOISE_WINDOW
        th, tw = h // k, w // k
        if not th or not tw:
            return sd
        keep = np.ones((th, tw), dtype=bool)
        inside = (rows < th * k) & (cols < tw * k)
        keep[rows[inside] // k, cols[inside] // k] = False
        return sd[keep.ravel()]

    def _laplacian(self, block: np.ndarray, valid: np.ndarray | None, c0: int, c1: int) -> None:
        """Immerkær sums for the centre rows [c0, c1) (their 3x3 neighbourhoods)."""
        if c1 <= c0 or block.shape[1] < 3:
            return
        # integers of at most 16 bits in integers (|lap| <= 8 * range: int16 for bytes, int32
        # for 16 bits) summed in int64, about 4x faster than float32 for bytes. The sums are
        # the same exact integers float32 + a float64 sum gave (every |lap| < 2^24, every
        # partial sum < 2^53), so sigma does not change; other dtypes stay in float32.
        src = block[c0 - 1 : c1 + 1]
        if src.dtype.kind in "uib" and src.dtype.itemsize <= 2:
            a = src.astype(np.int16 if src.dtype.itemsize == 1 else np.int32)
            total_dtype: type = np.int64
            d = a[:, :-2] + a[:, 2:]
            d -= a[:, 1:-1]  # twice instead of 2 * a: no temporary (exact in integers)
            d -= a[:, 1:-1]
            lap = d[:-2] + d[2:]
            lap -= d[1:-1]
            lap -= d[1:-1]
        else:  # float32 exactly as before (x - 2a rounds differently from (x - a) - a)
            a = src.astype(np.float32)
            total_dtype = np.float64
            d = a[:, :-2] + a[:, 2:]
            d -= 2.0 * a[:, 1:-1]
            lap = d[:-2] + d[2:]
            lap -= 2.0 * d[1:-1]
        np.abs(lap, out=lap)
        if valid is None:
            self.sum_abs += float(lap.sum(dtype=total_dtype))
            self.n_lap += lap.size
            return
        v = valid[c0 - 1 : c1 + 1]
        r = v[:, :-2] & v[:, 1:-1] & v[:, 2:]
        ok = r[:-2] & r[1:-1] & r[2:]
        n_ok = int(np.count_nonzero(ok))
        # all valid (the usual case): the same sum without copying the selected values
        self.sum_abs += float((lap if n_ok == ok.size else lap[ok]).sum(dtype=total_dtype))
        self.n_lap += n_ok

    def _local_std(
        self, block: np.ndarray, valid: np.ndarray | None, r0: int, r1: int
    ) -> np.ndarray:
        """Local stds of the fully valid NOISE_WINDOW squares in rows [r0, r1) (multiples
        of k), flat."""
        k = NOISE_WINDOW
        ww = (block.shape[1] // k) * k
        if r1 <= r0 or not ww:
            return np.zeros(0)
        sub = block[r0:r1, :ww]
        if sub.dtype.kind in "uib" and sub.dtype.itemsize <= 2:
            sd = _window_std_exact(sub, k)
        else:
            tiles = sub.astype(np.float32).reshape((r1 - r0) // k, k, ww // k, k)
            sd = tiles.std(axis=(1, 3), ddof=1)  # float32, centred: precise enough
        if valid is not None:
            vt = valid[r0:r1, :ww].reshape((r1 - r0) // k, k, ww // k, k).all(axis=(1, 3))
            sd = sd[vt]
        return sd.ravel()

    def _bin_local_stds(self, sd: np.ndarray) -> None:
        """Add local stds to the log-binned histogram (below the first edge: ``n_flat``)."""
        flat = sd < _LOCAL_STD_EDGES[0]
        self.n_flat += int(np.count_nonzero(flat))
        pos = sd[~flat]
        if pos.size:
            idx = np.floor(np.log(pos / _LOCAL_STD_EDGES[0]) / _LOG_STEP).astype(np.intp)
            np.clip(idx, 0, self.local_counts.size - 1, out=idx)
            self.local_counts += np.bincount(idx, minlength=self.local_counts.size)

    def merge(self, other: NoiseAccumulator) -> NoiseAccumulator:
        self.sum_abs += other.sum_abs
        self.n_lap += other.n_lap
        self.local_counts += other.local_counts
        self.n_flat += other.n_flat
        return self

    @property
    def immerkaer_sigma(self) -> float | None:
        if self.n_lap == 0:
            return None
        return math.sqrt(math.pi / 2.0) * self.sum_abs / (6.0 * self.n_lap)

    @property
    def homogeneous_sigma(self) -> float | None:
        n = int(self.local_counts.sum()) + self.n_flat
        if n == 0:
            return None
        target = NOISE_PERCENTILE / 100.0 * n
        if target <= self.n_flat:
            return 0.0
        cum = np.cumsum(self.local_counts) + self.n_flat
        i = int(np.searchsorted(cum, target))
        i = min(i, self.local_counts.size - 1)
        before = cum[i - 1] if i > 0 else self.n_flat
        frac = (target - before) / max(int(self.local_counts[i]), 1)
        lo, hi = _LOCAL_STD_EDGES[i], _LOCAL_STD_EDGES[i + 1]
        value = float(lo * (hi / lo) ** frac)  # log interpolation inside the bin
        return value / _chi_quantile_factor()


def _window_std_exact(sub: np.ndarray, k: int) -> np.ndarray:
    """Sample std (ddof=1) of each k x k window of a block of integers of at most 16 bits.

    Sums and sums of squares are exact integers in float64 (at most 64 * 65535^2 < 2^53), so
    ``n * S2 - S1^2`` has no rounding at all; rows are added first (whole-row vector adds), then
    groups of k columns: about 4x faster than ``std`` over a 4-D view.
    """
    rows, width = sub.shape
    if sub.dtype.itemsize == 1 and sub.dtype.kind in "ub" and k <= 16:
        return _window_std_bytes(sub.view(np.uint8), k)
    a = sub.reshape(rows // k, k, width)
    s1 = a[:, 0].astype(np.float64)
    s2 = s1 * s1
    for i in range(1, k):
        x = a[:, i].astype(np.float64)
        s1 += x
        x *= x
        s2 += x
    s1 = s1.reshape(rows // k, width // k, k).sum(axis=2)
    s2 = s2.reshape(rows // k, width // k, k).sum(axis=2)
    n = k * k
    return np.sqrt(np.maximum(n * s2 - s1 * s1, 0.0) / (n * (n - 1)))


def _window_std_bytes(sub: np.ndarray, k: int) -> np.ndarray:
    """:func:`_window_std_exact` of uint8 data in narrow integers, about 2x faster.

    Column sums of k <= 16 rows fit uint16 (16 * 255) and uint32 (16 * 255^2), window sums
    int64: the same exact integers as the float64 path, so the same stds to the last bit.
    """
    rows, width = sub.shape
    a = sub.reshape(rows // k, k, width)
    s1 = a.sum(axis=1, dtype=np.uint16)
    s2 = np.multiply(a, a, dtype=np.uint16).sum(axis=1, dtype=np.uint32)
    t1 = s1.reshape(rows // k, width // k, k).sum(axis=2, dtype=np.int64)
    t2 = s2.reshape(rows // k, width // k, k).sum(axis=2, dtype=np.int64)
    n = k * k
    return np.sqrt(np.maximum(n * t2 - t1 * t1, 0) / (n * (n - 1)))


#: sqrt(chi2.ppf(0.10, 63) / 63): the 10th percentile of the sample std of 64 unit-Gaussian
#: values. A constant so workers need not import scipy.stats (~1 s); a test recomputes it.
_CHI_FACTOR_8X8_P10 = 0.8829112978780186


def _chi_quantile_factor() -> float:
    """Percentile of the sample std of NOISE_WINDOW^2 unit Gaussian values (chi distribution)."""
    if NOISE_WINDOW == 8 and NOISE_PERCENTILE == 10.0:
        return _CHI_FACTOR_8X8_P10
    from scipy.stats import chi2

    dof = NOISE_WINDOW * NOISE_WINDOW - 1
    return math.sqrt(float(chi2.ppf(NOISE_PERCENTILE / 100.0, dof)) / dof)


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


@dataclass(frozen=True)
class GreyRange:
    """The available grey levels of a band: bit depth and where it came from."""

    bit_depth: int | None
    source: str  # "argument", "NBITS", "dtype", "none" (float data without a declared depth)
    signed: bool = False

    @property
    def low(self) -> int | None:
        if self.bit_depth is None:
            return None
        return -(1 << (self.bit_depth - 1)) if self.signed else 0

    @property
    def high(self) -> int | None:
        if self.bit_depth is None:
            return None
        return (1 << (self.bit_depth - 1)) - 1 if self.signed else (1 << self.bit_depth) - 1

    @property
    def levels(self) -> int | None:
        return None if self.bit_depth is None else 1 << self.bit_depth


def grey_range(
    dtype: np.dtype | str, *, declared: int | None = None, nbits: int | None = None
) -> GreyRange:
    """Bit depth from the caller, else the NBITS tag, else the dtype (floats: none)."""
    dt = np.dtype(dtype)
    signed = dt.kind == "i"
    container = 8 * dt.itemsize if dt.kind in "uib" else None
    for value, source in ((declared, "argument"), (nbits, "NBITS")):
        if value is not None:
            if value < 1 or (container is not None and value > container):
                raise MeasureError(f"bit depth {value} ({source}) does not fit a {dt} band")
            return GreyRange(int(value), source, signed)
    if container is None:
        return GreyRange(None, "none", False)
    return GreyRange(1 if dt.kind == "b" else container, "dtype", signed)


@dataclass(frozen=True)
class Histogram:
    """A histogram: either one bin per DN from ``offset`` or equal bins with ``edges``."""

    counts: tuple[int, ...]
    offset: int | None = None
    edges: tuple[float, ...] | None = None

    def to_dict(self) -> dict[str, Any]:
        if self.edges is not None:
            return {"kind": "binned", "edges": list(self.edges), "counts": list(self.counts)}
        return {"kind": "per_dn", "first_dn": self.offset, "counts": list(self.counts)}


@dataclass(frozen=True)
class BandStats:
    """Exact statistics and JRC §6.3 radiometric measures of one band (or the luminosity)."""

    band: str
    dtype: str
    pixels: int
    valid: int
    min: float | None
    max: float | None
    mean: float | None
    std: float | None
    histogram: Histogram | None
    bit_depth: int | None
    bit_depth_source: str
    range_low: int | None
    range_high: int | None
    used_bits: int | None
    above_range: int
    saturation_low_pct: float | None
    saturation_high_pct: float | None
    dark_margin_pct: float | None
    bright_margin_pct: float | None
    dark_margin_robust_pct: float | None
    bright_margin_robust_pct: float | None
    cv_percent: float | None
    noise_sigma_immerkaer: float | None = None
    noise_sigma_homogeneous: float | None = None
    nodata: float | None = None
    #: float bands: NaN / +/-Inf pixels that are not no-data, excluded from every statistic
    nonfinite: int | None = None

    @property
    def saturation_low_hidden(self) -> bool:
        """True when nodata is the lowest grey level: dark saturation is then invisible."""
        return (
            self.nodata is not None
            and self.range_low is not None
            and (self.nodata == self.range_low)
        )

    @property
    def nodata_fraction(self) -> float:
        return (self.pixels - self.valid) / self.pixels if self.pixels else 0.0

    def to_dict(self, *, histogram: bool = True) -> dict[str, Any]:
        out: dict[str, Any] = {
            "band": self.band,
            "dtype": self.dtype,
            "pixels": self.pixels,
            "valid": self.valid,
            "nodata_fraction": self.nodata_fraction,
            "min": self.min,
            "max": self.max,
            "mean": self.mean,
            "std": self.std,
            "bit_depth": self.bit_depth,
            "bit_depth_source": self.bit_depth_source,
            "range_low": self.range_low,
            "range_high": self.range_high,
            "used_bits": self.used_bits,
            "above_range": self.above_range,
            "saturation_low_pct": self.saturation_low_pct,
            "saturation_high_pct": self.saturation_high_pct,
            "dark_margin_pct": self.dark_margin_pct,
            "bright_margin_pct": self.bright_margin_pct,
            "dark_margin_robust_pct": self.dark_margin_robust_pct,
            "bright_margin_robust_pct": self.bright_margin_robust_pct,
            "cv_percent": self.cv_percent,
            "noise_std_global": self.std,
            "noise_sigma_immerkaer": self.noise_sigma_immerkaer,
            "noise_sigma_homogeneous": self.noise_sigma_homogeneous,
            "nodata": self.nodata,
            "saturation_low_hidden_by_nodata": self.saturation_low_hidden,
        }
        if self.nonfinite is not None:
            out["nonfinite_pixels"] = self.nonfinite
        if histogram:
            out["histogram"] = None if self.histogram is None else self.histogram.to_dict()
        return out


def _used_bits(vmax: float | None, signed: bool) -> int | None:
    if vmax is None or not np.isfinite(vmax):
        return None
    top = math.floor(vmax)
    return max(abs(top).bit_length() + (1 if signed else 0), 1)


def band_stats_from_histogram(
    band: str,
    dtype: str,
    acc: HistogramAccumulator,
    rng: GreyRange,
    *,
    noise: NoiseAccumulator | None = None,
    nodata: float | None = None,
) -> BandStats:
    """Exact statistics and §6.3 measures from a per-DN histogram (nodata already excluded)."""
    m = acc.moments()
    counts = acc.counts
    n = m.n
    hist = None
    if n:
        lo_i, hi_i = int(m.vmin) - acc.offset, int(m.vmax) - acc.offset
        hist = Histogram(counts=tuple(counts[lo_i : hi_i + 1].tolist()), offset=int(m.vmin))
    sat_lo = sat_hi = dm = bm = dmr = bmr = cv = None
    above = 0
    if n and rng.bit_depth is not None:
        low, high = rng.low, rng.high
        assert low is not None and high is not None
        span = float(high - low)

        def count_at(v: int) -> int:
            i = v - acc.offset
            return int(counts[i]) if 0 <= i < counts.size else 0

        sat_lo = 100.0 * count_at(low) / n
        sat_hi = 100.0 * count_at(high) / n
        above = int(counts[max(high + 1 - acc.offset, 0) :].sum()) + int(
            counts[: max(low - acc.offset, 0)].sum()
        )
        dm = 100.0 * (m.vmin - low) / span
        bm = 100.0 * (high - m.vmax) / span
        cum = np.cumsum(counts)
        k = max(math.ceil(ROBUST_TAIL * n), 1)
        p_lo = int(np.searchsorted(cum, k)) + acc.offset
        p_hi = int(np.searchsorted(cum, n - k + 1)) + acc.offset
        dmr = 100.0 * (p_lo - low) / span
        bmr = 100.0 * (high - p_hi) / span
        cv = 100.0 * m.std / float(rng.levels)  # type: ignore[arg-type]
    return BandStats(
        band=band,
        dtype=dtype,
        pixels=acc.total,
        valid=n,
        min=m.vmin if n else None,
        max=m.vmax if n else None,
        mean=m.mean if n else None,
        std=m.std if n else None,
        histogram=hist,
        bit_depth=rng.bit_depth,
        bit_depth_source=rng.source,
        range_low=rng.low,
        range_high=rng.high,
        used_bits=_used_bits(m.vmax if n else None, rng.signed),
        above_range=above,
        saturation_low_pct=sat_lo,
        saturation_high_pct=sat_hi,
        dark_margin_pct=dm,
        bright_margin_pct=bm,
        dark_margin_robust_pct=dmr,
        bright_margin_robust_pct=bmr,
        cv_percent=cv,
        noise_sigma_immerkaer=noise.immerkaer_sigma if noise else None,
        noise_sigma_homogeneous=noise.homogeneous_sigma if noise else None,
        nodata=nodata,
    )


def band_stats_from_moments(
    band: str,
    dtype: str,
    pixels: int,
    m: Moments,
    rng: GreyRange,
    *,
    histogram: BinnedHistogramAccumulator | None = None,
    noise: NoiseAccumulator | None = None,
    count_low: int = 0,
    count_high: int = 0,
    above_range: int = 0,
    nodata: float | None = None,
) -> BandStats:
    """Statistics of a float / 32-bit band; saturation only when a bit depth is known."""
    n = m.n
    hist = None
    if histogram is not None and n:
        hist = Histogram(
            counts=tuple(histogram.counts.tolist()), edges=tuple(float(e) for e in histogram.edges)
        )
    sat_lo = sat_hi = dm = bm = cv = None
    if n and rng.bit_depth is not None:
        low, high = rng.low, rng.high
        assert low is not None and high is not None
        span = float(high - low)
        sat_lo, sat_hi = 100.0 * count_low / n, 100.0 * count_high / n
        dm, bm = 100.0 * (m.vmin - low) / span, 100.0 * (high - m.vmax) / span
        cv = 100.0 * m.std / float(rng.levels)  # type: ignore[arg-type]
    return BandStats(
        band=band,
        dtype=dtype,
        pixels=pixels,
        valid=n,
        min=m.vmin if n else None,
        max=m.vmax if n else None,
        mean=m.mean if n else None,
        std=m.std if n else None,
        histogram=hist,
        bit_depth=rng.bit_depth,
        bit_depth_source=rng.source,
        range_low=rng.low,
        range_high=rng.high,
        used_bits=_used_bits(m.vmax if n else None, rng.signed),
        above_range=above_range,
        saturation_low_pct=sat_lo,
        saturation_high_pct=sat_hi,
        dark_margin_pct=dm,
        bright_margin_pct=bm,
        dark_margin_robust_pct=None,
        bright_margin_robust_pct=None,
        cv_percent=cv,
        noise_sigma_immerkaer=noise.immerkaer_sigma if noise else None,
        noise_sigma_homogeneous=noise.homogeneous_sigma if noise else None,
        nodata=nodata,
    )


# --------------------------------------------------------------------------- misregistration


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


@dataclass
class MaskShareAccumulator:
    """Share of flagged pixels (non-zero) among the valid pixels of a mask raster."""

    flagged: int = 0
    valid: int = 0

    def add(self, mask: np.ndarray, valid: np.ndarray | None = None) -> None:
        m = mask if valid is None else mask[valid]
        self.valid += int(m.size)
        self.flagged += int(np.count_nonzero(m))

    def merge(self, other: MaskShareAccumulator) -> MaskShareAccumulator:
        self.flagged += other.flagged
        self.valid += other.valid
        return self

    @property
    def percent(self) -> float | None:
        return 100.0 * self.flagged / self.valid if self.valid else None
