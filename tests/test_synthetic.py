"""Synthetic slanted edges and the analytic truth of Gaussian PSF * square pixel."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from orthospec.errors import MeasureError
from orthospec.measures.synthetic import (
    edge_truth,
    slanted_edge,
    truth_esf,
    truth_lsf,
    truth_mtf,
)


@pytest.mark.parametrize("angle", [0.0, 7.0, 30.0, 45.0])
@pytest.mark.parametrize("sigma", [0.3, 1.2])
def test_truth_functions_are_consistent(angle, sigma):
    d = np.linspace(-12, 12, 24001)
    step = d[1] - d[0]
    lsf = truth_lsf(d, sigma_px=sigma, angle_deg=angle)
    esf = truth_esf(d, sigma_px=sigma, angle_deg=angle)
    assert np.sum(lsf) * step == pytest.approx(1.0, abs=1e-6)
    assert np.max(np.abs(np.gradient(esf, d) - lsf)) < 1e-4
    assert esf[0] == pytest.approx(0.0, abs=1e-9) and esf[-1] == pytest.approx(1.0, abs=1e-9)
    # MTF truth = |FT(LSF truth)| (Fourier slice of the pixel-integrated PSF)
    n = 1 << 18
    freq = np.fft.rfftfreq(n, step)
    ft = np.abs(np.fft.rfft(lsf, n)) * step
    for f in (0.1, 0.25, 0.5, 0.8):
        assert np.interp(f, freq, ft) == pytest.approx(
            truth_mtf(np.array([f]), sigma_px=sigma, angle_deg=angle)[0], abs=1e-4)


def test_tilted_pixel_footprint_is_two_boxes():
    """At 45 deg the unit square projects to a triangle of base sqrt(2): MTF = sinc^2."""
    f = np.array([0.3, 0.5])
    c = np.cos(np.pi / 4)
    got = truth_mtf(f, sigma_px=1e-6, angle_deg=45.0)
    assert np.allclose(got, np.sinc(f * c) ** 2, atol=1e-9)
    # and at 0 deg the plain pixel: Gaussian * |sinc(f)|
    g = truth_mtf(f, sigma_px=0.5, angle_deg=0.0)
    assert np.allclose(g, np.exp(-2 * np.pi**2 * 0.25 * f**2) * np.abs(np.sinc(f)))


def test_edge_truth_values():
    t = edge_truth(sigma_px=0.5, angle_deg=0.0)
    # widths ordered, FWHM wider than the Gaussian's alone and than one pixel
    assert t.width80_px < t.fwhm_px < t.width25_px
    assert t.fwhm_px > 2.3548 * 0.5 and t.fwhm_px > 1.0
    esf = truth_esf(np.array([-0.5, 0.5]), sigma_px=0.5, angle_deg=0.0)
    assert t.rer == pytest.approx(esf[1] - esf[0])
    assert t.mtf_nyquist == pytest.approx(np.exp(-2 * np.pi**2 * 0.25 * 0.25) * np.sinc(0.5))


@settings(max_examples=25, deadline=None)
@given(sigma=st.floats(0.2, 3.0), angle=st.floats(0.0, 45.0))
def test_truth_properties(sigma, angle):
    t = edge_truth(sigma_px=sigma, angle_deg=angle)
    assert 0.0 < t.rer < 1.0
    assert 0.0 <= t.mtf_nyquist <= 2 / np.pi + 1e-12  # a pixel never beats sinc(0.5)
    blurrier = edge_truth(sigma_px=sigma * 1.2, angle_deg=angle)
    assert blurrier.fwhm_px > t.fwhm_px and blurrier.rer < t.rer


@pytest.mark.parametrize("angle,sigma", [(3.0, 0.4), (12.0, 0.9), (28.0, 1.5)])
def test_render_matches_analytic_esf(angle, sigma):
    """Supersampled render + box average equals dark + contrast * ESF(d) at every pixel."""
    img = slanted_edge((40, 40), angle_deg=angle, sigma_px=sigma, dark=100.0, bright=400.0,
                       supersample=21)
    y, x = np.mgrid[0:40, 0:40].astype(float)
    t = np.deg2rad(angle)
    d = (x - 19.5) * np.cos(t) - (y - 19.5) * np.sin(t)
    expect = 100.0 + 300.0 * truth_esf(d, sigma_px=sigma, angle_deg=angle)
    inner = np.ones_like(d, dtype=bool)  # the generator pads, so borders are exact too
    assert np.max(np.abs(img - expect)[inner]) < 0.005 * 300


def test_noise_follows_seed_snr_and_is_seedable():
    a = slanted_edge((80, 80), angle_deg=5, sigma_px=0.5, snr=40, dark=100, bright=300,
                     rng=np.random.default_rng(7))
    b = slanted_edge((80, 80), angle_deg=5, sigma_px=0.5, snr=40, dark=100, bright=300,
                     rng=np.random.default_rng(7))
    c = slanted_edge((80, 80), angle_deg=5, sigma_px=0.5, snr=40, dark=100, bright=300,
                     rng=np.random.default_rng(8))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    plateau = np.concatenate([a[:, :25].ravel(), a[:, -25:].ravel()])
    levels = np.concatenate([np.full(80 * 25, 100.0), np.full(80 * 25, 300.0)])
    assert np.std(plateau - levels) == pytest.approx(200 / 40, rel=0.05)


@pytest.mark.parametrize("bits,dtype", [(8, np.uint8), (11, np.uint16), (16, np.uint16)])
def test_quantisation(bits, dtype):
    img = slanted_edge((30, 30), angle_deg=4, sigma_px=0.6, snr=20, bit_depth=bits,
                       rng=np.random.default_rng(0))
    assert img.dtype == dtype
    assert img.max() <= 2**bits - 1
    assert img.min() >= 0
    hi = 0.8 * (2**bits - 1)
    assert abs(float(np.median(img[:, -5:])) - hi) <= 0.02 * hi


def test_measured_psf_kernel_matches_gaussian():
    sig = 0.8
    yy, xx = np.mgrid[-6:6.01:0.25, -6:6.01:0.25]
    kernel = np.exp(-(xx**2 + yy**2) / (2 * sig**2))
    a = slanted_edge((30, 30), angle_deg=6, psf=kernel, psf_step_px=0.25, supersample=12)
    b = slanted_edge((30, 30), angle_deg=6, sigma_px=sig, supersample=12)
    assert np.max(np.abs(a - b)[3:-3, 3:-3]) < 0.01 * (b.max() - b.min())


@pytest.mark.parametrize("kwargs", [
    {"shape": (1, 10)}, {"bit_depth": 20}, {"snr": -1.0}, {"supersample": 0},
    {"psf": np.ones(5)},
])
def test_bad_generator_input(kwargs):
    with pytest.raises(MeasureError):
        slanted_edge(**kwargs)


def test_bad_truth_sigma():
    with pytest.raises(MeasureError, match="sigma_px"):
        edge_truth(sigma_px=0.0, angle_deg=5)


def test_unsharp_truth_reduces_to_the_closed_form_and_uses_ndimage_kernel():
    """unsharp_truth (issue 16): amount 0 is the Gaussian edge's closed form; the MTF gain
    at Nyquist matches the transfer function of scipy.ndimage's own filter, obtained by
    filtering a delta image (independent of the taps unsharp_truth builds)."""
    from scipy import ndimage

    from orthospec.measures.synthetic import unsharp_truth

    base = edge_truth(sigma_px=0.8, angle_deg=12.0)
    zero = unsharp_truth(sigma_px=0.8, angle_deg=12.0, amount=0.0, mask_sigma_px=1.5)
    assert zero.fwhm_px == pytest.approx(base.fwhm_px, rel=1e-3)
    assert zero.rer == pytest.approx(base.rer, abs=1e-9)
    assert zero.mtf_nyquist == pytest.approx(base.mtf_nyquist, abs=1e-12)
    delta = np.zeros((41, 41))
    delta[20, 20] = 1.0
    kern = ndimage.gaussian_filter(delta, 1.5, mode="constant")
    yy, xx = np.mgrid[-20:21, -20:21]
    t = np.deg2rad(12.0)
    u = xx * np.cos(t) - yy * np.sin(t)
    gain = abs(1.0 + 1.0 - 1.0 * float(np.sum(kern * np.cos(2 * np.pi * 0.5 * u))))
    sharp = unsharp_truth(sigma_px=0.8, angle_deg=12.0, amount=1.0, mask_sigma_px=1.5)
    assert sharp.mtf_nyquist == pytest.approx(base.mtf_nyquist * gain, rel=1e-9)
    assert sharp.fwhm_px < base.fwhm_px and sharp.rer > base.rer
