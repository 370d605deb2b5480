"""The edge chain's physical PSF model: closed forms, its lack-of-fit test, its choice
between Gaussian, Gaussian x box and core + halo, and measured (non-Gaussian) PSFs whose
truth comes from ``kernel_truth``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import fftconvolve
from scipy.special import ndtr

from orthospec.measures.edge import PSF_FITS, measure_edge
from orthospec.measures.psf import gauss_boxes_esf, gauss_boxes_lsf, gauss_pixel_mtf
from orthospec.measures.synthetic import edge_truth, kernel_truth, slanted_edge

S = 9  # render supersampling; kernels are sampled at 1/S px so they render exactly
_R = np.arange(-80, 81) / S
X, Y = np.meshgrid(_R, _R)


def _gauss(sig):
    g = np.exp(-0.5 * (X**2 + Y**2) / sig**2)
    return g / g.sum()


def _disk(radius):
    acc = np.zeros_like(X)
    for dy in (np.arange(5) + 0.5) / 5 - 0.5:  # area coverage, 5 x 5 per sample
        for dx in (np.arange(5) + 0.5) / 5 - 0.5:
            acc += (X + dx / S) ** 2 + (Y + dy / S) ** 2 <= radius**2
    return acc / acc.sum()


KERNELS = {
    "halo": lambda: 0.8 * _gauss(0.6) + 0.2 * _gauss(2.0),
    "defocus": lambda: fftconvolve(_disk(2.0), _gauss(0.5), mode="same"),
    "motion": lambda: fftconvolve(np.where((np.abs(X) <= 0.75) & (np.abs(Y) < 0.5 / S), 1.0, 0.0),
                                  _gauss(0.5), mode="same"),
}


def _render(kernel, angle, snr, seed=0):
    return slanted_edge((100, 100), angle_deg=angle, sigma_px=None, psf=kernel, psf_step_px=1 / S,
                        snr=snr, supersample=S, offset_px=0.137 * seed,
                        rng=np.random.default_rng(seed))


# ------------------------------------------------------------------ closed forms


def test_boxes_reduce_to_the_gaussian_and_integrate_to_one():
    x = np.linspace(-8, 8, 3201)
    assert np.allclose(gauss_boxes_esf(x, 0.7, ()), ndtr(x / 0.7), atol=1e-15)
    for widths in [(1.0,), (0.95, 0.3), (0.9, 0.4, 1.7), (1.0, 0.0, 2.0)]:
        esf = gauss_boxes_esf(x, 0.5, widths)
        lsf = gauss_boxes_lsf(x, 0.5, widths)
        assert esf[0] == pytest.approx(0.0, abs=1e-12) and esf[-1] == pytest.approx(1.0, abs=1e-12)
        assert np.trapezoid(lsf, x) == pytest.approx(1.0, abs=1e-9)
        assert np.allclose(np.gradient(esf, x), lsf, atol=2e-5)
        assert np.allclose(lsf, lsf[::-1], atol=1e-12)  # symmetric about 0
    # a box of width w adds w^2 / 12 to the variance
    lsf = gauss_boxes_lsf(x, 0.5, (0.9, 0.4, 1.7))
    assert np.trapezoid(x * x * lsf, x) == pytest.approx(0.25 + (0.81 + 0.16 + 2.89) / 12, rel=1e-6)


def test_kernel_truth_agrees_with_the_closed_form_for_a_gaussian_kernel():
    for sig, ang in [(0.4, 2.0), (0.8, 10.0), (1.5, 29.0)]:
        g = np.exp(-0.5 * (_R / sig) ** 2)
        kt = kernel_truth(np.outer(g, g), angle_deg=ang, psf_step_px=1 / S, supersample=S)
        et = edge_truth(sigma_px=sig, angle_deg=ang)
        # kernel_truth also holds the renderer's 1/S px coverage ramp: +w^2/12 variance
        assert kt.fwhm_px == pytest.approx(et.fwhm_px, rel=3e-3)
        assert kt.width25_px == pytest.approx(et.width25_px, rel=3e-3)
        assert kt.rer == pytest.approx(et.rer, abs=2e-3)
        assert kt.mtf_nyquist == pytest.approx(et.mtf_nyquist, abs=2e-3)
        assert kt.edge_slope_per_px == pytest.approx(et.edge_slope_per_px, rel=3e-3)
        assert kt.sigma_px is None


def test_model_mtf_is_the_closed_form():
    r = measure_edge(slanted_edge((100, 100), angle_deg=12.0, sigma_px=0.9, snr=300, supersample=9,
                                  rng=np.random.default_rng(2)))
    f = r.fits["gauss"]
    sig = f.params["sigma_px"][0]
    assert np.allclose(f.mtf, gauss_pixel_mtf(f.mtf_freq, sig, r.angle_deg), atol=1e-12)
    assert f.mtf_nyquist == pytest.approx(
        float(gauss_pixel_mtf(np.array([0.5]), sig, r.angle_deg)[0])
    )


# ------------------------------------------------------------------ the lack-of-fit test


def test_lack_of_fit_test_is_calibrated_on_gaussian_edges():
    """Under a true model the F statistic averages 1 and its p-values are not small."""
    stats_, pvals = [], []
    for seed in range(12):
        img = slanted_edge(
            (100, 100),
            angle_deg=4.0 + 2 * seed,
            sigma_px=0.5 + 0.08 * seed,
            snr=80,
            supersample=9,
            offset_px=0.137 * seed,
            rng=np.random.default_rng(seed),
        )
        r = measure_edge(img)
        m = (
            r.fits["gauss"]
            if "gauss" in r.fits
            else next(r.fits[f] for f in PSF_FITS if f in r.fits)
        )
        stats_.append(m.params["lack_of_fit_f"])
        pvals.append(m.params["p_value"])
        assert m.params["noise_dn"] == pytest.approx(300 / 80, rel=0.08)  # pure error = pixel noise
    assert np.mean(stats_) == pytest.approx(1.0, abs=0.12)
    assert sum(p < 0.01 for p in pvals) <= 1


def test_sharpened_edge_is_described_by_the_unsharp_mask_model():
    """A ringing (unsharp-masked) edge is no blur of a positive PSF, but it is the
    Gaussian edge times (1 + k) - k G(sigma_m): the gauss-usm model (issue 16) describes
    it and matches the exact truth of the discrete filter (noise sharpened too)."""
    from scipy import ndimage

    from orthospec.measures.synthetic import unsharp_truth

    img = slanted_edge(
        (100, 100),
        angle_deg=7.0,
        sigma_px=1.0,
        snr=400,
        supersample=9,
        rng=np.random.default_rng(0),
    )
    sharp = img + 1.5 * (img - ndimage.gaussian_filter(img, 1.5))  # unsharp mask
    t = unsharp_truth(sigma_px=1.0, angle_deg=7.0, amount=1.5, mask_sigma_px=1.5)
    r = measure_edge(sharp)
    assert r.valid, r.reasons
    assert r.primary_fit == "gauss-usm" and r.fits["gauss-usm"].params["adequate"]
    assert r.fwhm_px == pytest.approx(t.fwhm_px, rel=0.01)
    assert r.rer == pytest.approx(t.rer, abs=0.005)
    assert r.mtf_nyquist == pytest.approx(t.mtf_nyquist, abs=0.005)


def test_model_rejected_when_it_cannot_describe_the_edge():
    """A clipped bright side (a saturating response) is no PSF blur: the model fails its
    lack-of-fit test, the cross-validated error prefers the spline, and the spline is
    primary, so no model value is passed off as the measurement."""
    img = slanted_edge(
        (100, 100),
        angle_deg=7.0,
        sigma_px=1.0,
        snr=400,
        supersample=9,
        rng=np.random.default_rng(0),
    )
    clipped = np.minimum(img, 330.0)
    r = measure_edge(clipped)
    assert r.valid, r.reasons
    model = next(r.fits[f] for f in PSF_FITS if f in r.fits)
    assert not model.params["adequate"] and model.params["p_value"] < 1e-3
    assert model.params["cv_error_spline"] < model.params["cv_error_model"]
    assert r.primary_fit == "spline" and r.estimate("fwhm_px").fit == "spline"
    forced = measure_edge(clipped, primary="model")
    assert forced.primary_fit == model.fit


# ------------------------------------------------------------------ measured PSFs


@pytest.mark.parametrize(
    "name,expect", [("halo", "gauss2"), ("defocus", "gauss-disk"), ("motion", "gauss-box")]
)
def test_non_gaussian_psf_high_snr(name, expect):
    kernel = KERNELS[name]()
    for angle in (5.0, 20.0):
        t = kernel_truth(kernel, angle_deg=angle, psf_step_px=1 / S, supersample=S)
        r = measure_edge(_render(kernel, angle, 500))
        assert r.valid, r.reasons
        # a 1.5-px smear and a radius-0.9 disk, each under G(0.5), differ by < 0.1 % in
        # FWHM: at 5 deg the disk may fit the motion edge as well (both flat-topped)
        ok = (expect, "gauss-disk") if name == "motion" else (expect,)
        assert r.primary_fit in (*ok, "spline")
        assert any(k in r.fits for k in ok)  # the likelihood ratio asked for the richer PSF
        assert r.fwhm_px == pytest.approx(t.fwhm_px, rel=0.02)
        assert abs(r.mtf_nyquist - t.mtf_nyquist) < 0.02
        assert abs(r.rer - t.rer) < 0.02
        assert r.estimate("fwhm_px", "spline").value == pytest.approx(t.fwhm_px, rel=0.02)
        if name == "defocus":  # the disk model (issue 16) is the defocus PSF itself
            assert r.primary_fit == "gauss-disk"
            assert abs(r.mtf_nyquist - t.mtf_nyquist) < 0.005
            assert r.fits["gauss-disk"].params["disk_radius_px"] == pytest.approx(2.0, abs=0.15)


@pytest.mark.parametrize("name", list(KERNELS))
def test_non_gaussian_psf_low_snr_stays_near_truth(name):
    """At SNR 100 the data cannot always tell the PSF shape apart; the primary fit stays
    within 3 % of the true FWHM over these ROIs (measured worst: 2.95 %, docs/edge-method.md)."""
    kernel = KERNELS[name]()
    for angle, seed in [(5.0, 0), (20.0, 1)]:
        t = kernel_truth(kernel, angle_deg=angle, psf_step_px=1 / S, supersample=S)
        r = measure_edge(_render(kernel, angle, 100, seed))
        assert r.valid, r.reasons
        assert r.fwhm_px == pytest.approx(t.fwhm_px, rel=0.03)
        assert abs(r.mtf_nyquist - t.mtf_nyquist) < 0.02


# ---- issue 16: quantisation-aware model choice, sharpened edges ----------------------


def _u8(img):
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("angle", [5.0, 12.0])
def test_noise_free_8bit_halo_edge_keeps_the_model(angle):
    """Issue 16: a noise-free 8-bit halo edge has no plateau scatter; the lack-of-fit test
    must count the rounding (q^2/12 per bin mean) so the model is kept, not the spline that
    follows the quantisation steps (was MTF@Ny 0.0767 against truth 0.0919)."""
    k = 0.85 * _gauss(0.6) + 0.15 * _gauss(2.0)
    img = _u8(
        slanted_edge(
            (100, 100),
            angle_deg=angle,
            sigma_px=None,
            psf=k,
            psf_step_px=1 / S,
            dark=51,
            bright=204,
            supersample=S,
        )
    )
    t = kernel_truth(k, angle_deg=angle, psf_step_px=1 / S, supersample=S)
    r = measure_edge(img)
    assert r.valid and r.primary_fit in PSF_FITS
    assert r.fits[r.primary_fit].params["quantisation_dn"] == 1.0
    assert abs(r.mtf_nyquist - t.mtf_nyquist) <= 0.005
    assert abs(r.fwhm_px / t.fwhm_px - 1) <= 0.02
    # the SNR of a noise-free quantised edge is finite: at most dDN / (q / sqrt(12)), the
    # quantisation noise floor (the halo's tail adds some level variation)
    snr = r.check("snr")
    assert snr.passed and 50 < snr.value <= 153 * 12**0.5 + 1e-9


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sharpened_edge_at_snr_30_within_3_percent(seed):
    """Unsharp-masked (amount 1, sigma 1.5 px) Gaussian edge, noise after sharpening at
    SNR 30, truth from unsharp_truth (exact for the discrete filter)."""
    from orthospec.measures.synthetic import unsharp_mask, unsharp_truth

    t = unsharp_truth(sigma_px=0.8, angle_deg=12.0, amount=1.0, mask_sigma_px=1.5)
    base = slanted_edge(
        (100, 100),
        angle_deg=12.0,
        sigma_px=0.8,
        dark=51,
        bright=204,
        supersample=S,
        offset_px=0.137 * seed,
    )
    img = unsharp_mask(base, amount=1.0, sigma_px=1.5)
    img = _u8(img + np.random.default_rng(seed).normal(0, 153 / 30, img.shape))
    r = measure_edge(img, min_snr=25)
    assert r.valid
    assert abs(r.fwhm_px / t.fwhm_px - 1) <= 0.03
    assert abs(r.rer - t.rer) <= 0.02
    # the overshoot of a sharpened edge is seen (GIQE H > 1)
    assert r.estimate("overshoot_h").value > 1.0


def test_model_choice_by_cross_validation_is_recorded():
    """When the model fails its lack-of-fit test, the choice is the lower out-of-sample
    (5-fold over the ESF bins) error, and both errors are in the JSON."""
    k = 0.85 * _gauss(0.6) + 0.15 * _gauss(2.0)
    img = slanted_edge(
        (100, 100),
        angle_deg=7.0,
        sigma_px=None,
        psf=k,
        psf_step_px=1 / S,
        supersample=S,
        snr=2000,
        rng=np.random.default_rng(0),
    )
    d = measure_edge(img, min_snr=45).to_dict()
    if d["psf_model.adequate"]:
        assert d["psf_model.cv_error"] is None and d["primary_fit"] == d["psf_model"]
    else:
        cv_m, cv_s = d["psf_model.cv_error"], d["spline.cv_error"]
        assert d["primary_fit"] == (d["psf_model"] if cv_m <= cv_s else "spline")
