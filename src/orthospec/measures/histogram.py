"""Exact band statistics from histograms and moments (JRC EUR 23638 EN §3.2, §6.3).

Conventions (they match GDAL's exact statistics, ``gdalinfo -stats`` / ``ComputeStatistics``
with ``approx_ok = FALSE``):

* statistics are *exact* (every pixel, never overviews) and the standard deviation is the
  *population* one (divide by N);
* integer bands of at most 16 bits are accumulated as a full histogram, one bin per DN, from
  which min, max, mean and std follow exactly (no rounding drift, any merge order);
* other bands (32-bit integers, floats) use Chan et al.'s pairwise merge of (n, mean, M2) in
  float64, and their histogram is a second pass with ``FLOAT_HISTOGRAM_BINS`` equal bins from
  the exact min to the exact max.

The saturation, DRA margins and coefficient of variation of a band (:class:`BandStats`) follow
from its histogram and its grey range (:class:`GreyRange`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import MeasureError
from .counting import _as_bin_index, _pillow_counts, fast_bincount, histogram_layout

if TYPE_CHECKING:
    from .noise import NoiseAccumulator

#: Number of equal bins of the histogram of floating-point (and 32-bit integer) bands.
FLOAT_HISTOGRAM_BINS = 256

#: Tail share used for the robust DRA margins (0.1 % of the valid pixels at each side).
ROBUST_TAIL = 0.001


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
