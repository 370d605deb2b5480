"""Issue 31: the PSF-family generator (truth by the 2-D OTF) against independent paths, and the
edge chain on the families the issue names: tails, the diffraction model, motion, uncertainty."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from orthospec.measures.edge import measure_edge
from orthospec.measures.synthetic import (
    PsfFamily,
    edge_truth,
    family_edge,
    family_truth,
    slanted_edge,
)

# ------------------------------------------------------------------ the generator


@pytest.mark.parametrize("sigma,angle", [(0.45, 3.0), (0.8, 26.565), (1.2, 40.0)])
def test_gaussian_family_is_the_closed_form(sigma, angle):
    """Numerical inversion of the OTF against the closed forms of measures.psf (edge_truth), and
    the ESF(d) rendering against the supersampled renderer slanted_edge (a different path)."""
    fam = PsfFamily("gauss", sigma=sigma)
    t = family_truth(fam, angle_deg=angle)
    ref = edge_truth(sigma_px=sigma, angle_deg=angle)
    assert t.fwhm_px == pytest.approx(ref.fwhm_px, rel=1e-4)
    assert t.rer == pytest.approx(ref.rer, abs=1e-4)
    assert t.mtf_nyquist == pytest.approx(ref.mtf_nyquist, abs=1e-9)
    img = family_edge(fam, (40, 60), angle_deg=angle, dark=100.0, bright=400.0, truth=t)
    other = slanted_edge((40, 60), angle_deg=angle, sigma_px=sigma, dark=100.0, bright=400.0,
                         supersample=15)
    assert np.abs(img - other).max() < 1e-3 * 300  # the 1/15-px coverage ramp of the renderer


def test_mtfc_family_is_the_3_tap_filter_on_the_pixel_grid():
    """The sharpened family's truth (OTF x (1 + 2a - 2a cos 2 pi f) per axis) equals the 3-tap
    filter [-a, 1 + 2a, -a] applied along x and y to the rendered unsharpened edge."""
    a, sigma, angle = 0.25, 0.8, 12.0
    base = family_edge(
        PsfFamily("gauss", sigma=sigma), (60, 60), angle_deg=angle, dark=0.0, bright=1.0
    )
    taps = np.array([-a, 1 + 2 * a, -a])
    filt = ndimage.convolve1d(ndimage.convolve1d(base, taps, axis=1), taps, axis=0)
    sharp = family_edge(
        PsfFamily("mtfc", sigma=sigma, amount=a), (60, 60), angle_deg=angle, dark=0.0, bright=1.0
    )
    assert np.abs(filt[2:-2, 2:-2] - sharp[2:-2, 2:-2]).max() < 1e-4
    assert sharp.max() > 1.0 and sharp.min() < 0.0  # it rings


def test_family_truth_is_a_normalised_system():
    """Every family: LSF area 1, ESF from 0 to 1, MTF(0) = 1, MTF@Ny = |T(0.5)|."""
    for fam in (
        PsfFamily("halo", sigma=0.5, sigma2=4.0, weight=0.1),
        PsfFamily("defocus", radius=2.0, sigma=0.5),
        PsfFamily("motion_x", length=2.5, sigma=0.4),
        PsfFamily("motion_y", length=3.0, sigma=0.4),
        PsfFamily("diffraction", cutoff=0.8, sigma=0.3, length=1.0),
    ):
        t = family_truth(fam, angle_deg=9.0)
        step = t.x[1] - t.x[0]
        assert np.sum(t.lsf) * step == pytest.approx(1.0, abs=2e-3)
        assert t.esf[0] == pytest.approx(0.0, abs=3e-3) and t.esf[-1] == pytest.approx(
            1.0, abs=3e-3
        )
        assert t.mtf(np.array([0.0]))[0] == pytest.approx(1.0)
        assert t.mtf(np.array([0.5]))[0] == pytest.approx(t.mtf_nyquist)
    # a box along x of length L projects to L cos(theta) on the normal; along y to L sin(theta)
    tx = family_truth(PsfFamily("motion_x", length=2.0, sigma=0.3), angle_deg=20.0)
    ty = family_truth(PsfFamily("motion_y", length=2.0, sigma=0.3), angle_deg=20.0)
    c, s = math.cos(math.radians(20)), math.sin(math.radians(20))
    gauss = math.exp(-2 * math.pi**2 * 0.09 * 0.25) * abs(np.sinc(0.5 * c) * np.sinc(0.5 * s))
    assert tx.mtf_nyquist == pytest.approx(gauss * abs(np.sinc(0.5 * 2.0 * c)), rel=1e-9)
    assert ty.mtf_nyquist == pytest.approx(gauss * abs(np.sinc(0.5 * 2.0 * s)), rel=1e-9)


# ------------------------------------------------------------------ the chain on the families


def _measure(fam, angle, snr, seed=0, shape=(100, 100), bits=8):
    t = family_truth(fam, angle_deg=angle)
    dark, bright = (40.0, 200.0) if bits == 8 else (600.0, 3000.0)
    img = family_edge(
        fam,
        shape,
        angle_deg=angle,
        dark=dark,
        bright=bright,
        snr=snr,
        bit_depth=bits,
        offset_px=0.137 * seed,
        rng=np.random.default_rng(seed),
        truth=t,
    )
    return measure_edge(img, min_snr=25), t


@pytest.mark.parametrize("angle", [5.0, 18.435])
def test_wide_halo_tail_is_inside_the_window(angle):
    """A 10 % halo of sigma 4 px: its LSF is below 2 % of the peak beyond 1 px, yet 1 % of the
    step lies beyond 5 px. With the window ending 3-4 px from the edge RER read +0.024 and
    MTF@Ny +0.009 high (measured before issue 31); the window now reaches where the ESF settles."""
    r, t = _measure(
        PsfFamily("halo", sigma=0.55, sigma2=4.0, weight=0.1),
        angle,
        None,
        bits=12,
        shape=(100, 100),
    )
    assert r.valid, r.reasons
    assert r.window_px[0] <= -10.0 and r.window_px[1] >= 10.0
    assert abs(r.rer - t.rer) <= 0.01
    assert abs(r.mtf_nyquist - t.mtf_nyquist) <= 0.005
    assert abs(r.fwhm_px / t.fwhm_px - 1) <= 0.02


@pytest.mark.parametrize("snr,seed", [(100.0, 1), (50.0, 2)])
def test_diffraction_limited_edge_uses_the_pupil_model(snr, seed):
    """Diffraction (cut-off 1 cycle/px) x jitter 0.25 px x smear 0.8 px along track: the pupil
    model describes it (core and 1/x^2 tail); a sum of Gaussians read FWHM +2.5-4.5 % and
    MTF@Ny -0.015 off with the wide window (measured while developing issue 31)."""
    r, t = _measure(PsfFamily("diffraction", cutoff=1.0, sigma=0.25, length=0.8), 9.0, snr, seed)
    assert r.valid, r.reasons
    assert r.primary_fit == "airy"
    assert abs(r.fwhm_px / t.fwhm_px - 1) <= 0.02
    assert abs(r.rer - t.rer) <= 0.02
    assert abs(r.mtf_nyquist - t.mtf_nyquist) <= 0.01


def test_motion_across_the_edge_is_not_read_as_a_gaussian_at_snr_100():
    """A 1.5-px smear across the edge: the flat-topped LSF is chosen by its out-of-sample error.
    Before issue 31 (likelihood ratio at p < 0.001, then AIC) the 22-deg ROI kept the Gaussian
    (FWHM -2.9 %) and the 9-deg one the unsharp-masked Gaussian (run on commit 95a2ffd)."""
    for seed, angle in ((0, 5.0), (1, 9.0), (2, 22.0)):
        r, t = _measure(PsfFamily("motion_x", length=1.5, sigma=0.45), angle, 100.0, seed)
        assert r.valid, r.reasons
        assert r.primary_fit in ("gauss-box", "gauss-disk"), r.primary_fit
        assert abs(r.fwhm_px / t.fwhm_px - 1) <= 0.02


def test_noise_free_8bit_diffraction_edge_is_within_its_uncertainty():
    """Noise-free 8-bit: the stated uncertainty covers the error. (Until the rounding bound of
    one-DN bins, the pupil model failed its lack-of-fit test here and the spline, 0.012 off in
    MTF@Ny, was primary; test_edge_discrete.py now asserts the model.)"""
    r, t = _measure(PsfFamily("diffraction", cutoff=1.0, sigma=0.25, length=0.8), 9.0, None, 0)
    assert r.valid, r.reasons
    for name, truth in (("rer", t.rer), ("fwhm_px", t.fwhm_px), ("mtf_nyquist", t.mtf_nyquist)):
        e = r.estimate(name)
        assert abs(e.value - truth) <= 2 * e.u, name


# ------------------------------------------------------------------ uncertainty


def test_every_figure_has_a_standard_uncertainty_that_covers_the_error():
    """RER, FWHM and MTF@Ny carry u (JSON: *.u); over these ROIs of four families at SNR 50 the
    error is within 2u for at least 90 % of the figures (nominal 95 %), and u shrinks with noise."""
    fams = [
        PsfFamily("gauss", sigma=0.6),
        PsfFamily("defocus", radius=1.5, sigma=0.4),
        PsfFamily("mtfc", sigma=0.8, amount=0.25),
        PsfFamily("motion_y", length=1.5, sigma=0.45),
    ]
    inside, total = 0, 0
    for k, fam in enumerate(fams):
        for seed, angle in ((k, 7.0), (k + 10, 22.0)):
            r, t = _measure(fam, angle, 50.0, seed)
            assert r.valid, r.reasons
            d = r.to_dict()
            for name, truth in (
                ("rer", t.rer),
                ("fwhm_px", t.fwhm_px),
                ("mtf_nyquist", t.mtf_nyquist),
            ):
                u = d[f"{name}.u"]
                assert u is not None and u > 0
                inside += abs(d[name] - truth) <= 2 * u
                total += 1
    assert inside >= 0.9 * total
    quiet, _ = _measure(PsfFamily("gauss", sigma=0.6), 7.0, 400.0, 3)
    noisy, _ = _measure(PsfFamily("gauss", sigma=0.6), 7.0, 40.0, 3)
    assert quiet.estimate("fwhm_px").u < 0.3 * noisy.estimate("fwhm_px").u
    bad = measure_edge(np.random.default_rng(0).normal(100, 5, (60, 60))).to_dict()
    assert bad["fwhm_px.u"] is None and bad["rer.u"] is None
