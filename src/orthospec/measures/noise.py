"""Noise of an orthoimage band (JRC EUR 23638 EN §6.3), two estimators streamed block by block.

Pure numeric layer: :class:`NoiseAccumulator` takes numpy blocks plus validity masks and merges,
so a reader can stream a file of any size through it and several workers can merge partial
results.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import MeasureError
from .counting import SLAB_PIXELS

#: Side of the square windows of the local-standard-deviation noise estimator.
NOISE_WINDOW = 8

#: Percentile of the local standard deviations taken as the noise of homogeneous areas.
NOISE_PERCENTILE = 10.0

#: A noise block of integers whose invalid pixels are at most 1 in this many is added whole and
#: the few neighbourhoods and windows touching them are taken out afterwards (same sums).
SPARSE_INVALID = 64

#: (dy, dx, weight) of Immerkaer's 3x3 difference-of-Laplacians kernel
#: [[1,-2,1],[-2,4,-2],[1,-2,1]].
_LAPLACIAN_TAPS = tuple(
    (dy, dx, (1 if dy and dx else -2 if dy or dx else 4)) for dy in (-1, 0, 1) for dx in (-1, 0, 1)
)

# log-spaced bins for the histogram of local standard deviations (0.5 % relative resolution)
_LOCAL_STD_EDGES = np.geomspace(1e-3, 1e6, 4201)
_LOG_STEP = math.log(1e6 / 1e-3) / 4200


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
        a: np.ndarray[Any, np.dtype[Any]]  # int16/int32 or float32, decided below
        d: np.ndarray[Any, np.dtype[Any]]
        lap: np.ndarray[Any, np.dtype[Any]]
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
