"""Radiometric measures of orthoimages (JRC EUR 23638 EN §3.2, §6.3): the names of the modules
they live in, under their former address.

Pure numeric layer, computed block by block: the accumulators take numpy blocks of pixels plus
validity masks and merge, so a reader can stream a file of any size through them with bounded
memory and several workers can merge partial results. Nothing here opens a file.

* counting.py: the one-bin-per-DN layout, fast bincount (Pillow, a reused intp buffer), the
  per-thread work arrays;
* histogram.py: exact histograms and moments (GDAL's conventions), grey ranges and the
  statistics and §6.3 measures of a band (:class:`BandStats`);
* noise.py: the two noise estimators (Immerkaer, homogeneous areas);
* luminosity.py: Rec. 601 luma;
* registration.py: band-to-band shift by phase correlation (geometry, kept apart).

Validity (which pixels count) is decided by the reader (raster/scan.py), as GDAL's
``ComputeStatistics`` does: a band's nodata value (plus NaN for floats), else a per-dataset mask
or alpha band, else every pixel.
"""

from __future__ import annotations

from .counting import (
    PARALLEL_BINCOUNT_MIN,
    SLAB_PIXELS,
    _pillow_counts,
    counting_helper,
    fast_bincount,
    histogram_layout,
    numpy_bincount,
    scratch,
)
from .histogram import (
    FLOAT_HISTOGRAM_BINS,
    ROBUST_TAIL,
    BandStats,
    BinnedHistogramAccumulator,
    GreyRange,
    Histogram,
    HistogramAccumulator,
    MaskShareAccumulator,
    Moments,
    band_stats_from_histogram,
    band_stats_from_moments,
    grey_range,
)
from .luminosity import LUMA_WEIGHTS, luminosity, luminosity_block
from .noise import (
    _CHI_FACTOR_8X8_P10,
    NOISE_PERCENTILE,
    NOISE_WINDOW,
    SPARSE_INVALID,
    NoiseAccumulator,
    _window_std_exact,
)
from .registration import (
    Shift,
    _upsampled_dft,
    phase_correlation,
    phase_correlation_spectra,
    tapered_spectrum,
)

__all__ = [
    "FLOAT_HISTOGRAM_BINS",
    "LUMA_WEIGHTS",
    "NOISE_PERCENTILE",
    "NOISE_WINDOW",
    "PARALLEL_BINCOUNT_MIN",
    "ROBUST_TAIL",
    "SLAB_PIXELS",
    "SPARSE_INVALID",
    "_CHI_FACTOR_8X8_P10",
    "BandStats",
    "BinnedHistogramAccumulator",
    "GreyRange",
    "Histogram",
    "HistogramAccumulator",
    "MaskShareAccumulator",
    "Moments",
    "NoiseAccumulator",
    "Shift",
    "_pillow_counts",
    "_upsampled_dft",
    "_window_std_exact",
    "band_stats_from_histogram",
    "band_stats_from_moments",
    "counting_helper",
    "fast_bincount",
    "grey_range",
    "histogram_layout",
    "luminosity",
    "luminosity_block",
    "numpy_bincount",
    "phase_correlation",
    "phase_correlation_spectra",
    "scratch",
    "tapered_spectrum",
]
