"""Pure radiometry accumulators: exact moments, merges, §6.3 measures, noise, misregistration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy import ndimage

from orthospec.errors import MeasureError
from orthospec.measures import radiometry as rad


def _stats_u8(values: np.ndarray, bits: int = 8) -> rad.BandStats:
    acc = rad.HistogramAccumulator.for_dtype(values.dtype)
    acc.add(values)
    return rad.band_stats_from_histogram("1", str(values.dtype), acc,
                                         rad.grey_range(values.dtype, declared=bits))


@settings(max_examples=60, deadline=None)
@given(arrays(np.uint16, st.integers(1, 400), elements=st.integers(0, 65535)),
       st.integers(1, 5))
def test_histogram_moments_equal_numpy_population_stats_in_any_chunking(a, parts):
    acc = rad.HistogramAccumulator.for_dtype(a.dtype)
    for chunk in np.array_split(a, parts):
        part = rad.HistogramAccumulator.for_dtype(a.dtype)
        part.add(chunk)
        acc.merge(part)
    m = acc.moments()
    assert m.n == a.size
    assert m.vmin == a.min() and m.vmax == a.max()
    assert m.mean == pytest.approx(a.astype(np.float64).mean(), rel=1e-12)
    assert m.std == pytest.approx(a.astype(np.float64).std(ddof=0), rel=1e-9, abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.integers(1, 300),
              elements=st.floats(-1e6, 1e6, allow_nan=False)), st.integers(1, 6))
def test_chan_merge_equals_one_pass_numpy(a, parts):
    m = rad.Moments()
    for chunk in np.array_split(a, parts):
        m.add(chunk)
    assert m.n == a.size
    assert m.mean == pytest.approx(a.mean(), rel=1e-9, abs=1e-6)
    assert m.std == pytest.approx(a.std(), rel=1e-7, abs=1e-6)
    assert (m.vmin, m.vmax) == (a.min(), a.max())


def test_signed_int16_histogram_uses_offset_bins():
    a = np.array([-32768, -1, 0, 5, 32767, 5], dtype=np.int16)
    acc = rad.HistogramAccumulator.for_dtype(a.dtype)
    acc.add(a)
    m = acc.moments()
    assert (m.vmin, m.vmax) == (-32768.0, 32767.0)
    assert m.mean == pytest.approx(a.mean())
    assert acc.counts[5 + 32768] == 2


def test_nodata_bin_is_excluded_and_counted():
    a = np.array([0, 0, 0, 10, 20, 30], dtype=np.uint8)
    acc = rad.HistogramAccumulator.for_dtype(a.dtype)
    acc.add(a)
    assert acc.exclude_value(0.0) == 3
    m = acc.moments()
    assert (m.n, m.vmin, m.mean) == (3, 10.0, 20.0)
    s = rad.band_stats_from_histogram("1", "uint8", acc, rad.grey_range("uint8"))
    assert s.nodata_fraction == pytest.approx(0.5)


def test_saturation_margins_and_cv_by_hand():
    # 1000 pixels: 3 at 0, 7 at 255, the rest at 100 and 150 (495 each)
    a = np.concatenate([np.zeros(3), np.full(7, 255), np.full(495, 100), np.full(495, 150)])
    s = _stats_u8(a.astype(np.uint8))
    assert s.saturation_low_pct == pytest.approx(0.3)
    assert s.saturation_high_pct == pytest.approx(0.7)
    assert s.dark_margin_pct == 0.0 and s.bright_margin_pct == 0.0
    # robust margins ignore the 0.1 % tails at each side: 3 pixels at 0 > 1 pixel -> still 0
    assert s.dark_margin_robust_pct == 0.0
    assert s.cv_percent == pytest.approx(100 * a.std() / 256)
    assert s.used_bits == 8


def test_margins_in_percent_of_range_and_eleven_bit_depth():
    a = np.array([205, 1000, 1842], dtype=np.uint16)  # 11-bit range 0..2047
    s = _stats_u8(a, bits=11)
    assert (s.range_low, s.range_high, s.bit_depth) == (0, 2047, 11)
    assert s.dark_margin_pct == pytest.approx(100 * 205 / 2047)
    assert s.bright_margin_pct == pytest.approx(100 * (2047 - 1842) / 2047)
    assert s.cv_percent == pytest.approx(100 * a.std() / 2048)
    assert s.used_bits == 11
    assert s.saturation_high_pct == 0.0


def test_values_above_declared_range_are_reported():
    a = np.array([10, 2047, 4000], dtype=np.uint16)
    s = _stats_u8(a, bits=11)
    assert s.above_range == 1
    assert s.saturation_high_pct == pytest.approx(100 / 3)
    assert s.used_bits == 12


def test_grey_range_priority_and_errors():
    assert rad.grey_range("uint16", declared=12, nbits=11).source == "argument"
    assert rad.grey_range("uint16", nbits=11).bit_depth == 11
    assert rad.grey_range("uint16").bit_depth == 16
    assert rad.grey_range("float32").bit_depth is None
    with pytest.raises(MeasureError, match="does not fit"):
        rad.grey_range("uint8", declared=11)


def test_luminosity_rec601_rounded_half_up():
    r = np.array([255, 0, 0, 10], dtype=np.uint8)
    g = np.array([0, 255, 0, 20], dtype=np.uint8)
    b = np.array([0, 0, 255, 30], dtype=np.uint8)
    y = rad.luminosity(r, g, b, np.uint8)
    expected = np.floor(0.299 * r + 0.587 * g + 0.114 * b + 0.5).astype(np.uint8)
    assert np.array_equal(y, expected)
    assert y.tolist() == [76, 150, 29, 18]
    # an exact tie: 299*0 + 587*0 + 114*25 = 2850 -> 2.85 -> 3; 1000*x.5 ties round up
    tie = rad.luminosity(np.array([5], np.uint16), np.array([5], np.uint16),
                         np.array([5], np.uint16), np.uint16)
    assert tie.tolist() == [5]
    r16 = np.array([1000, 2047, 3], np.uint16)
    y16 = rad.luminosity(r16, r16[::-1].copy(), r16, np.uint16)
    ri = r16.astype(np.int64)
    assert np.array_equal(y16, (299 * ri + 587 * ri[::-1] + 114 * ri + 500) // 1000)


@settings(max_examples=50, deadline=None)
@given(arrays(np.uint8, st.integers(0, 3000)))
def test_fast_bincount_equals_numpy(a):
    assert np.array_equal(rad.fast_bincount(a, 256), np.bincount(a, minlength=256))


@pytest.mark.parametrize("sigma", [2.0, 5.0, 12.0])
def test_noise_estimators_recover_known_gaussian_sigma(sigma):
    rng = np.random.default_rng(42)
    yy, xx = np.mgrid[0:512, 0:512]
    signal = 300 + 0.2 * xx + 0.1 * yy  # a smooth ramp: both estimators must ignore it
    img = signal + rng.normal(0, sigma, signal.shape)
    acc = rad.NoiseAccumulator()
    for rows in np.array_split(np.arange(512), 4):  # streamed in 4 chunks and merged
        part = rad.NoiseAccumulator()
        part.add(img[rows])
        acc.merge(part)
    assert acc.immerkaer_sigma == pytest.approx(sigma, rel=0.03)
    assert acc.homogeneous_sigma == pytest.approx(sigma, rel=0.06)


def test_homogeneous_noise_ignores_textured_half():
    rng = np.random.default_rng(1)
    img = rng.normal(100, 3.0, (256, 256))
    img[:, 128:] += rng.normal(0, 40, (256, 128))  # strong texture on half the image
    acc = rad.NoiseAccumulator()
    acc.add(img)
    assert acc.homogeneous_sigma == pytest.approx(3.0, rel=0.08)
    assert acc.immerkaer_sigma > 10  # the global estimator is fooled, as documented


def test_noise_respects_validity_mask():
    rng = np.random.default_rng(2)
    img = rng.normal(50, 4.0, (128, 128))
    img[:, :40] = 0  # nodata stripe with a sharp edge
    valid = np.ones(img.shape, bool)
    valid[:, :40] = False
    acc = rad.NoiseAccumulator()
    acc.add(img, valid)
    assert acc.immerkaer_sigma == pytest.approx(4.0, rel=0.05)


@pytest.mark.parametrize("shift", [(0.0, 0.0), (1.3, -0.4), (-2.75, 3.5), (0.2, 0.6)])
def test_phase_correlation_recovers_subpixel_shift(shift):
    rng = np.random.default_rng(7)
    ref = ndimage.gaussian_filter(rng.normal(size=(256, 256)), 2.0) * 100
    moved = np.fft.ifft2(ndimage.fourier_shift(np.fft.fft2(ref), shift)).real
    s = rad.phase_correlation(ref, moved, upsample=50)
    assert s.dy == pytest.approx(shift[0], abs=0.05)
    assert s.dx == pytest.approx(shift[1], abs=0.05)
    assert s.magnitude == pytest.approx(math.hypot(*shift), abs=0.07)


def test_phase_correlation_rejects_bad_shapes():
    with pytest.raises(MeasureError, match="equal 2-D arrays"):
        rad.phase_correlation(np.zeros((10, 10)), np.zeros((10, 12)))


def test_mask_share_accumulates_over_blocks():
    m1 = np.array([[0, 1], [1, 1]], dtype=np.uint8)
    m2 = np.array([[0, 0], [255, 0]], dtype=np.uint8)
    acc = rad.MaskShareAccumulator()
    acc.add(m1)
    part = rad.MaskShareAccumulator()
    part.add(m2, np.array([[True, True], [True, False]]))
    acc.merge(part)
    assert (acc.flagged, acc.valid) == (4, 7)
    assert acc.percent == pytest.approx(400 / 7)


def test_chi_factor_constant_matches_scipy():
    from scipy.stats import chi2

    expected = math.sqrt(chi2.ppf(0.1, 63) / 63)
    assert abs(rad._CHI_FACTOR_8X8_P10 - expected) <= 1e-15 * expected


@pytest.mark.parametrize(("dtype", "size"), [("uint8", rad.PARALLEL_BINCOUNT_MIN * 3 + 1),
                                             ("uint16", rad.PARALLEL_BINCOUNT_MIN * 2 + 7),
                                             ("uint8", rad.PARALLEL_BINCOUNT_MIN - 1)])
def test_fast_bincount_split_over_threads_equals_numpy(dtype, size):
    """Big arrays are counted in two halves (one in a helper thread): the counts are numpy's,
    through Pillow (bytes) and through numpy alone (the path without Pillow, 16-bit values)."""
    a = np.random.default_rng(size).integers(0, np.iinfo(dtype).max, size, endpoint=True,
                                             dtype=dtype)
    bins = np.iinfo(dtype).max + 1
    want = np.bincount(a, minlength=bins)
    assert np.array_equal(rad.fast_bincount(a, bins), want)
    assert np.array_equal(rad.numpy_bincount(a, bins), want)


@settings(max_examples=60, deadline=None)
@given(arrays(np.uint8, st.integers(1, 5000)), st.floats(0.0, 1.0), st.integers(0, 2**32 - 1))
def test_pillow_byte_counts_equal_numpy_with_and_without_mask(a, invalid_share, seed):
    """Pillow's C histogram of a zero-copy view counts exactly what np.bincount counts, and
    under a mask exactly the selected pixels."""
    pytest.importorskip("PIL")
    mask = np.random.default_rng(seed).random(a.size) >= invalid_share
    assert np.array_equal(rad._pillow_counts(a), np.bincount(a, minlength=256))
    assert np.array_equal(rad._pillow_counts(a, mask), np.bincount(a[mask], minlength=256))


def _random_of(rng: np.random.Generator, dtype: str, shape: tuple[int, int], *, true_share: float) -> np.ndarray:
    """Uniform values over the dtype's whole range (bool: True with probability ``true_share``)."""
    if dtype == "bool":
        return rng.random(shape) >= 1.0 - true_share
    info = np.iinfo(dtype)
    return rng.integers(info.min, info.max, shape, endpoint=True, dtype=dtype)


@pytest.mark.parametrize("dtype", ["uint8", "int8", "bool", "uint16"])
@pytest.mark.parametrize("invalid_share", [0.0, 0.1, 0.6])
def test_histogram_accumulator_of_every_small_dtype_with_mask_equals_numpy(dtype, invalid_share):
    """Every per-DN path (Pillow for bytes, signed via offset binary, numpy for 16 bits) counts
    the valid pixels of a 2-D block (non-contiguous too) exactly as numpy does."""
    rng = np.random.default_rng(5)
    data = _random_of(rng, dtype, (90, 140), true_share=0.7)
    data = data[:, 10:130]  # a strided view, as a band sliced out of a chunk can be
    valid = rng.random(data.shape) >= invalid_share
    acc = rad.HistogramAccumulator.for_dtype(dtype)
    acc.add(data, valid)
    offset, bins = rad.histogram_layout(dtype)
    want = np.bincount(data[valid].astype(np.int64) - offset, minlength=bins)
    assert np.array_equal(acc.counts, want)
    assert acc.total == data.size
    # a uint8 selector (non-zero = count), as the luminosity passes its darkest colour value
    selector = np.where(valid, rng.integers(1, 256, valid.shape), 0).astype(np.uint8)
    by_selector = rad.HistogramAccumulator.for_dtype(dtype)
    by_selector.add_where(data, selector)
    assert np.array_equal(by_selector.counts, want) and by_selector.total == data.size


@pytest.mark.parametrize("dtype", ["uint8", "bool", "int8", "uint16", "int16"])
def test_noise_of_integers_equals_the_float_path(dtype):
    """The integer Immerkaer sums and byte window stds give the same sigmas, to the last bit,
    as the float32 / float64 arithmetic of the same values (exact integers either way)."""
    rng = np.random.default_rng(9)
    data = _random_of(rng, dtype, (200, 333), true_share=0.5)
    valid = np.ones(data.shape, bool)
    valid[50:70, 100:140] = False
    for v in (None, valid):
        ints, floats = rad.NoiseAccumulator(), rad.NoiseAccumulator()
        ints.add(data, v)
        floats.add(data.astype(np.float32), v)  # float32 holds every 16-bit integer exactly
        assert (ints.sum_abs, ints.n_lap) == (floats.sum_abs, floats.n_lap)
        assert ints.immerkaer_sigma == floats.immerkaer_sigma
    k = rad.NOISE_WINDOW
    if data.dtype.itemsize == 1 and dtype != "int8":  # the byte path vs the float64 path
        wide = data[:192, :328].astype(np.uint16)
        assert np.array_equal(
            rad._window_std_exact(data[:192, :328], k), rad._window_std_exact(wide, k)
        )


def _noise_by_definition(img: np.ndarray, valid: np.ndarray) -> tuple[int, int, np.ndarray]:
    """Immerkaer's sum |I * N| and count over fully valid 3x3 neighbourhoods, and the sample
    stds of the fully valid 8x8 windows, straight from the definitions (scipy, numpy)."""
    a = img.astype(np.int64)
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]])
    lap = ndimage.correlate(a, kernel, mode="constant")[1:-1, 1:-1]
    ok = ndimage.minimum_filter(valid.astype(np.uint8), size=3, mode="constant")[1:-1, 1:-1] == 1
    k = rad.NOISE_WINDOW
    h, w = (img.shape[0] // k) * k, (img.shape[1] // k) * k
    tiles = a[:h, :w].reshape(h // k, k, w // k, k).transpose(0, 2, 1, 3).reshape(-1, k * k)
    vt = valid[:h, :w].reshape(h // k, k, w // k, k).all(axis=(1, 3)).ravel()
    return int(np.abs(lap[ok]).sum()), int(ok.sum()), tiles[vt].std(axis=1, ddof=1)


@pytest.mark.parametrize("dtype", ["uint8", "uint16", "int16", "bool"])
@pytest.mark.parametrize("where", ["scattered", "edges", "none", "dense"])
def test_noise_with_few_invalid_pixels_equals_the_definition(dtype, where):
    """Integer blocks with a few invalid pixels (scattered nodata DNs) are added whole and the
    neighbourhoods and windows touching them taken out afterwards: the same sums, counts and
    local-std histogram as masking, also for invalid pixels on the block's edges and corners."""
    rng = np.random.default_rng(11)
    data = _random_of(rng, dtype, (203, 333), true_share=0.5)
    valid = np.ones(data.shape, bool)
    if where == "scattered":
        valid[rng.integers(0, 203, 40), rng.integers(0, 333, 40)] = False
    elif where == "edges":
        valid[[0, 0, 202, 202, 0, 100, 202, 5], [0, 332, 0, 332, 150, 0, 200, 332]] = False
        valid[200:203, 320:333] = False  # rows and columns that no whole 8x8 window covers
    elif where == "dense":  # above 1 in SPARSE_INVALID: the masked path
        valid[rng.random(data.shape) < 0.05] = False
    got = rad.NoiseAccumulator()
    got.add(data, valid)
    sum_abs, n_lap, stds = _noise_by_definition(data, valid)
    assert (got.sum_abs, got.n_lap) == (float(sum_abs), n_lap)
    want = rad.NoiseAccumulator()
    want._bin_local_stds(stds)
    assert np.array_equal(got.local_counts, want.local_counts) and got.n_flat == want.n_flat
    assert got.homogeneous_sigma == want.homogeneous_sigma


@pytest.mark.parametrize("invalid_share", [0.0, 1e-4, 0.2, 0.7, 1.0])
def test_histogram_with_validity_mask_equals_numpy_of_the_valid_pixels(invalid_share):
    """Mostly valid blocks are counted whole minus the invalid pixels: same counts as selecting."""
    rng = np.random.default_rng(3)
    data = rng.integers(0, 256, (300, 700), dtype=np.uint8)
    valid = rng.random(data.shape) >= invalid_share
    acc = rad.HistogramAccumulator.for_dtype("uint8")
    acc.add(data, valid)
    assert np.array_equal(acc.counts, np.bincount(data[valid], minlength=256))
    assert acc.total == data.size


@pytest.mark.parametrize("dtype", ["uint8", "uint16", "int16", "bool"])
def test_window_std_of_integers_equals_numpy_float64(dtype):
    """The exact integer-sum window std (noise estimator) equals numpy's float64 std, ddof=1."""
    rng = np.random.default_rng(11)
    if dtype == "bool":
        data = rng.random((48, 72)) > 0.5
        data[:8, :8] = True  # a flat window: std exactly 0
    else:
        info = np.iinfo(dtype)
        data = rng.integers(info.min, info.max, (48, 72), endpoint=True, dtype=dtype)
        data[:8, :8] = info.max  # a flat window: std exactly 0
    k = rad.NOISE_WINDOW
    want = data.astype(np.float64).reshape(48 // k, k, 72 // k, k).std(axis=(1, 3), ddof=1)
    got = rad._window_std_exact(data, k)
    assert got[0, 0] == 0.0
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 65535), st.integers(1, 2**40)), min_size=1, max_size=40))
def test_histogram_variance_is_the_exact_rational_rounded_once(bins):
    """Population variance from the histogram: (n * S2 - S1^2) / n^2 in exact integers,
    rounded once (independent check: fractions.Fraction), so no BLAS summation order or
    thread count can change a bit."""
    from fractions import Fraction

    acc = rad.HistogramAccumulator.for_dtype("uint16")
    for dn, count in bins:
        acc.counts[dn] += count
    n = sum(int(c) for c in acc.counts)
    s1 = sum(int(c) * v for v, c in enumerate(acc.counts.tolist()))
    s2 = sum(int(c) * v * v for v, c in enumerate(acc.counts.tolist()))
    var = float(Fraction(n * s2 - s1 * s1, n * n))
    m = acc.moments()
    assert m.mean == float(Fraction(s1, n))
    assert m.m2 == var * n
    assert m.std == math.sqrt(var * n / n)


@pytest.mark.parametrize("big", [3, 2**50])
def test_histogram_mean_is_the_exact_integer_mean(big):
    """The mean from the histogram is sum(count * DN) / n done in exact integers, also when the
    products would overflow int64 (Python ints then)."""
    from fractions import Fraction

    acc = rad.HistogramAccumulator.for_dtype("uint16")
    acc.counts[[0, 1, 40000, 65535]] = [5, 7, big, big + 1]
    m = acc.moments()
    total = 7 * 1 + big * 40000 + (big + 1) * 65535
    n = 5 + 7 + big + big + 1
    assert m.n == n and (m.vmin, m.vmax) == (0.0, 65535.0)
    assert m.mean == float(Fraction(total, n))
