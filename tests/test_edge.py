"""The CEOS 12-step edge chain on synthetic edges with analytic truth, invariances, bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from orthospec.errors import MeasureError
from orthospec.figures.edge import edge_figures
from orthospec.measures.edge import PSF_FITS, measure_edge, rer_two_directions
from orthospec.measures.synthetic import edge_truth, slanted_edge

TOL_FWHM = 0.02  # relative
TOL_MTF = 0.02
TOL_RER = 0.02
TOL_ANGLE = 0.1  # deg


def _edge(angle, sigma, snr, seed=0, shape=(100, 100), **kw):
    return slanted_edge(shape, angle_deg=angle, sigma_px=sigma, snr=snr, supersample=9,
                        offset_px=0.137 * seed, rng=np.random.default_rng(seed), **kw)


def _assert_close_to_truth(r, angle, sigma, *, fwhm=TOL_FWHM):
    t = edge_truth(sigma_px=sigma, angle_deg=angle)
    assert r.valid, r.reasons
    assert abs(r.angle_deg - angle) < TOL_ANGLE
    assert r.fwhm_px == pytest.approx(t.fwhm_px, rel=fwhm)
    assert abs(r.mtf_nyquist - t.mtf_nyquist) < TOL_MTF
    assert abs(r.rer - t.rer) < TOL_RER


# single ROIs at high SNR: every estimator within the tolerances
@pytest.mark.parametrize("angle,sigma,snr", [
    (2.0, 0.4, None), (5.0, 1.5, 500), (10.0, 0.8, 500), (20.0, 0.4, 500),
    (29.0, 1.2, 500), (15.0, 1.0, 300),
])
def test_accuracy_single_roi(angle, sigma, snr):
    r = measure_edge(_edge(angle, sigma, snr))
    _assert_close_to_truth(r, angle, sigma)
    assert r.direction == "across" and r.polarity == "dark_to_bright"
    t = edge_truth(sigma_px=sigma, angle_deg=angle)
    assert r.estimate("width25_px").value == pytest.approx(t.width25_px, rel=0.03)
    assert r.estimate("width80_px").value == pytest.approx(t.width80_px, rel=0.05)
    assert r.estimate("edge_slope_per_px").value == pytest.approx(t.edge_slope_per_px, rel=0.03)


# single ROIs over the grid, 100 x 100 px, down to SNR 50. At SNR 50 the seed's
# "SNR > 50" health check is at its boundary (the measured SNR scatters +-1 % about 50),
# so those ROIs run with the check at 45: the estimators are what is tested here.
GRID = [(a, s, snr, seed) for snr in (50, 100) for s in (0.4, 0.8, 1.5)
        for a in (2.0, 5.0, 10.0, 20.0, 29.0) for seed in (0, 1)]


@pytest.mark.parametrize("angle,sigma,snr,seed", GRID)
def test_accuracy_low_snr_single_roi(angle, sigma, snr, seed):
    r = measure_edge(_edge(angle, sigma, snr, seed=seed), min_snr=45, primary="model")
    _assert_close_to_truth(r, angle, sigma)
    assert r.check("snr").value == pytest.approx(snr, rel=0.05)
    assert r.primary_fit in PSF_FITS


def test_model_is_primary_on_gaussian_edges():
    """``primary="auto"`` uses the model only when its lack-of-fit test passes (p >= 0.001).
    Over the grid it passes on 59 of 60 ROIs; the one rejection (2 deg, sigma 1.5, SNR 50,
    seed 1, p = 0.0006: a chance event, the F statistic of the same noise pattern is low
    at every SNR) is reported with the spline, whose MTF@Nyquist is then 0.024 off."""
    picked = [measure_edge(_edge(a, s, snr, seed=seed), min_snr=45).primary_fit
              for a, s, snr, seed in GRID]
    assert sum(p in PSF_FITS for p in picked) >= 58
    assert set(picked) <= {*PSF_FITS, "spline"}


def test_spline_alone_is_the_weaker_estimator_at_low_snr():
    """Why the PSF model is primary: over the same ROIs the model-free spline scatters
    3-4x more (it is still reported, and `primary="spline"` selects it)."""
    model, spline = [], []
    for a, s, snr, seed in GRID[:30]:
        t = edge_truth(sigma_px=s, angle_deg=a)
        r = measure_edge(_edge(a, s, snr, seed=seed), min_snr=45, primary="spline")
        assert r.primary_fit == "spline" and r.fwhm_px == r.estimate("fwhm_px", "spline").value
        spline.append(r.fwhm_px / t.fwhm_px - 1)
        model.append(next(r.estimate("fwhm_px", f).value for f in PSF_FITS if f in r.fits)
                     / t.fwhm_px - 1)
    assert np.sqrt(np.mean(np.square(spline))) > 2.5 * np.sqrt(np.mean(np.square(model)))
    assert max(map(abs, spline)) > TOL_FWHM > max(map(abs, model))


def test_fits_are_reported_with_their_names():
    r = measure_edge(_edge(8.0, 0.7, 400))
    t = edge_truth(sigma_px=0.7, angle_deg=8.0)
    fits = {e.fit for e in r.estimates}
    assert fits == {"spline", "fermi3", "gauss"}
    assert r.primary_fit == "gauss" and r.estimate("fwhm_px").fit == "gauss"
    model = r.fits["gauss"].params
    assert model["adequate"] and model["p_value"] > 1e-3 and model["sigma_px"] == [
        pytest.approx(0.7, rel=0.02)]
    assert model["footprint_px"] == pytest.approx(
        [math.cos(math.radians(8)), math.sin(math.radians(8))], abs=1e-3
    )
    for fit in ("spline", "fermi3"):
        assert r.estimate("fwhm_px", fit).value == pytest.approx(t.fwhm_px, rel=0.03)
    d = r.to_dict()
    assert d["fwhm_px.fit"] == "gauss" and d["primary_fit"] == "gauss"
    assert "fwhm_px.fermi3" in d and "fwhm_px.spline" in d and d["fwhm_px.unit"] == "px"
    single = measure_edge(_edge(8.0, 0.7, 400), fermi_terms=1)
    assert {e.fit for e in single.estimates} == {"spline", "fermi", "gauss"}
    # a single Fermi-Dirac term is too heavy-tailed for a Gaussian system: narrower FWHM
    assert single.estimate("fwhm_px", "fermi").value < 0.95 * t.fwhm_px
    with pytest.raises(MeasureError, match="primary must be one of"):
        measure_edge(_edge(8.0, 0.7, 400), primary="fermi")


@pytest.mark.parametrize(
    "name,transform,direction,polarity",
    [
        ("mirror", lambda a: a[:, ::-1], "across", "bright_to_dark"),
        ("invert", lambda a: a.max() + a.min() - a, "across", "bright_to_dark"),
        ("transpose", lambda a: a.T, "along", "dark_to_bright"),
        ("rot90", np.rot90, "along", "bright_to_dark"),
        ("flipud", lambda a: a[::-1], "across", "dark_to_bright"),
    ],
)
def test_polarity_and_transpose_invariance(name, transform, direction, polarity):
    img = _edge(7.0, 0.7, 150, seed=3, shape=(90, 70))
    base = measure_edge(img)
    other = measure_edge(transform(img))
    assert other.valid and base.valid
    assert (other.direction, other.polarity) == (direction, polarity)
    assert other.angle_deg == pytest.approx(base.angle_deg, abs=1e-9)
    for e in base.estimates:
        o = other.estimate(e.name, e.fit)
        tol = 1e-8 if e.fit == "spline" else 1e-4
        assert o is not None and o.value == pytest.approx(e.value, rel=tol, abs=tol), e.name


def test_horizontal_edge_is_along():
    r = measure_edge(_edge(12.0, 0.9, 300).T)
    assert r.direction == "along" and r.transposed
    _assert_close_to_truth(r, 12.0, 0.9)


def test_effective_resolution_and_metres():
    """Seed 004: factor x GSD = effective resolution; here factor = FWHM / 1 px."""
    r = measure_edge(_edge(6.0, 0.6, 400), gsd=0.25)
    f = r.effective_resolution_factor
    assert f == pytest.approx(r.fwhm_px)
    assert r.estimate("effective_gsd_m").value == pytest.approx(f * 0.25)
    assert r.estimate("fwhm_m").value == pytest.approx(r.fwhm_px * 0.25)
    assert r.estimate("edge_slope_per_m").value == pytest.approx(
        r.estimate("edge_slope_per_px").value / 0.25
    )
    # an ideal sampler (no blur beyond the pixel) has factor ~1: "should not be below 1.0"
    sharp = measure_edge(_edge(6.0, 0.05, None))
    assert sharp.effective_resolution_factor == pytest.approx(1.0, abs=0.05)


def test_to_dict_is_flat_and_json_safe():
    r = measure_edge(_edge(6.0, 0.6, 400), gsd=0.5)
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    assert all(isinstance(v, (str, bool, int, float, type(None))) for v in d.values())
    assert d["valid"] is True and d["check.snr.passed"] is True
    assert d["rer"] == pytest.approx(r.rer) and d["fwhm_m"] == pytest.approx(r.fwhm_px * 0.5)


def test_nodata_pixels_are_ignored():
    img = _edge(6.0, 0.7, 300).astype(float)
    ref = measure_edge(img)
    img[:10, :15] = 0.0
    assert not measure_edge(img).valid  # zero fill in the dark area: saturation/fill check
    r = measure_edge(img, nodata=0.0)
    assert r.valid and r.fwhm_px == pytest.approx(ref.fwhm_px, rel=0.02)
    img[:10, :15] = np.nan
    assert measure_edge(img).valid


# ---------------------------------------------------------------------------- bad input


def _invalid(r, *failed):
    assert not r.valid
    assert r.estimates == () and r.rer is None and r.fwhm_px is None and r.mtf_nyquist is None
    names = {c.name for c in r.checks if not c.passed}
    for name in failed:
        assert name in names, (name, r.reasons)
        c = r.check(name)
        assert c.reason and name in " ".join(r.reasons)
    d = r.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["valid"] is False and d.get("fwhm_px") is None
    return names


def test_no_edge():
    rng = np.random.default_rng(0)
    r = measure_edge(rng.normal(100, 5, size=(60, 60)))
    _invalid(r, "contrast")
    assert len({c.name for c in r.checks if not c.passed}) >= 2


def test_two_edges():
    img = _edge(5.0, 0.6, 300)
    stripe = np.concatenate([img, img[:, ::-1]], axis=1)  # dark | bright | dark
    r = measure_edge(stripe)
    _invalid(r, "snr")
    assert r.check("snr").value < 10


def test_saturated_side():
    img = _edge(5.0, 0.6, 200, bit_depth=11, bright=2100.0, dark=400.0)
    assert img.max() == 2047
    r = measure_edge(img, bit_depth=11)
    _invalid(r, "saturation")
    assert r.check("saturation").value > 0.5


def test_too_few_lines():
    r = measure_edge(_edge(5.0, 0.6, 300, shape=(12, 60)))
    _invalid(r, "edge_length")
    assert r.check("edge_length").value == 12


def test_too_small_contrast():
    r = measure_edge(_edge(5.0, 0.6, 300, dark=100.0, bright=140.0))
    _invalid(r, "contrast")
    assert r.check("contrast").value == pytest.approx(40, rel=0.05)


def test_low_snr():
    r = measure_edge(_edge(5.0, 0.6, 20, shape=(200, 100)))
    _invalid(r, "snr")
    assert r.check("snr").value == pytest.approx(20, rel=0.15)


def test_angle_beyond_the_seed_range_is_measured_with_a_warning_and_zero_angle_refused():
    """Issue 31: an edge at 38 deg is measured (as accurately, against the closed form) with a
    warning, since the seed's step 3d permits 0-30 deg (TBR); at 0 deg every line samples the
    ESF at the same phases, 1 px apart (the geometry), and the sampling check refuses it."""
    r = measure_edge(_edge(38.0, 0.6, 300))
    _assert_close_to_truth(r, 38.0, 0.6)
    assert r.warnings and "0-30 deg of CEOS step 3d" in r.warnings[0]
    assert r.to_dict()["warnings"] == r.warnings[0]
    assert not measure_edge(_edge(20.0, 0.6, 300)).warnings
    r0 = measure_edge(_edge(0.0, 0.6, 300))
    _invalid(r0, "sampling")
    assert r0.check("sampling").value == pytest.approx(1.0, abs=0.02)


def test_narrow_plateau():
    _invalid(measure_edge(_edge(5.0, 0.6, 300, shape=(60, 9))), "dark_width")


def test_limits_are_parameters():
    img = _edge(5.0, 0.6, 40, shape=(150, 80))
    assert not measure_edge(img).valid
    assert measure_edge(img, min_snr=30).valid


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros(10),
        np.zeros((3, 20, 20)),
        np.zeros((4, 40)),
        np.full((20, 20), np.nan),
        np.array([["a"] * 6] * 6),
    ],
)
def test_malformed_input_raises(bad):
    with pytest.raises(MeasureError):
        measure_edge(bad)


def test_bad_gsd_raises():
    with pytest.raises(MeasureError, match="gsd"):
        measure_edge(_edge(5.0, 0.6, None), gsd=-1.0)


# ---------------------------------------------------------------------------- RER two directions


def test_rer_geometric_mean_against_usgs_table():
    """Seed 000 'Spatial Results': Easting, Northing and the reported 'Average'.

    The formula is the geometric mean; the table's Average column rounds the *arithmetic*
    mean to 0.1 in every row, and the geometric mean in 7 of 10 rows only (DAIS green,
    IKONOS pan and ADS40 green differ) - we implement the stated formula.
    """
    rows = [
        (0.89, 0.8, 0.8),
        (0.88, 0.63, 0.8),
        (0.49, 0.44, 0.5),
        (0.64, 0.83, 0.7),
        (0.85, 0.65, 0.8),
        (0.37, 0.41, 0.4),
        (0.53, 0.57, 0.6),
        (0.60, 0.48, 0.5),
        (0.58, 0.65, 0.6),
        (0.47, 0.51, 0.5),
    ]
    e, n, avg = (np.array(c) for c in zip(*rows, strict=True))
    geo = rer_two_directions(e, n)
    assert np.allclose(geo, np.sqrt(e * n))
    half_up = np.floor((e + n) / 2 * 10 + 0.5 + 1e-9) / 10
    assert np.allclose(half_up, avg)
    agree = np.isclose(np.floor(geo * 10 + 0.5) / 10, avg)
    assert agree.sum() == 7 and list(np.flatnonzero(~agree)) == [1, 4, 6]
    with pytest.raises(MeasureError):
        rer_two_directions(-0.1, 0.5)


def test_rer_two_directions_from_measurements():
    x = measure_edge(_edge(6.0, 0.6, 400))
    y = measure_edge(_edge(6.0, 1.0, 400).T)
    assert (x.direction, y.direction) == ("across", "along")
    assert float(rer_two_directions(x.rer, y.rer)) == pytest.approx(math.sqrt(x.rer * y.rer))


# ---------------------------------------------------------------------------- figures


def test_figures_are_deterministic_svg():
    img = _edge(6.0, 0.6, 200, shape=(50, 50))
    r = measure_edge(img, min_edge_length_px=10)
    a, b = edge_figures(img, r), edge_figures(img, r)
    assert set(a) == {"detection", "esf", "lsf", "mtf"}
    assert a == b
    for svg in a.values():
        assert svg.lstrip().startswith("<?xml") and "<svg" in svg and "<dc:date>" not in svg
    assert "Nyquist" in a["mtf"] and "spline" in a["esf"] and "fermi3" in a["lsf"]
    bad = measure_edge(np.random.default_rng(1).normal(100, 5, (30, 30)))
    assert "INVALID" in edge_figures(np.zeros((30, 30)), bad)["esf"]


def test_measured_psf_with_halo():
    """A measured-kernel PSF (Gaussian core + 20 % wider halo): truth is the same mixture of
    the analytic responses; the plateau-start tail rule keeps the halo's LSF tail."""
    from orthospec.measures.synthetic import truth_esf, truth_lsf, truth_mtf

    angle, w, core, halo = 4.0, 0.2, 0.5, 1.5
    yy, xx = np.mgrid[-8:8.01:0.125, -8:8.01:0.125]  # sampled at the render's sub-pixel
    kernel = (1 - w) * np.exp(-(xx**2 + yy**2) / (2 * core**2)) / core**2 + w * np.exp(
        -(xx**2 + yy**2) / (2 * halo**2)
    ) / halo**2
    img = slanted_edge(
        (100, 100),
        angle_deg=angle,
        psf=kernel,
        psf_step_px=0.125,
        supersample=8,
        snr=300,
        rng=np.random.default_rng(0),
    )
    r = measure_edge(img)
    assert r.valid, r.reasons

    def mix(fn, x):
        return (1 - w) * fn(x, sigma_px=core, angle_deg=angle) + w * fn(
            x, sigma_px=halo, angle_deg=angle
        )

    x = np.arange(0, 6, 0.001)
    lsf = mix(truth_lsf, x)
    fwhm = 2 * x[np.argmax(lsf < lsf[0] / 2)]
    esf = mix(truth_esf, np.array([-0.5, 0.5]))
    assert r.fwhm_px == pytest.approx(fwhm, rel=TOL_FWHM)
    assert abs(r.rer - (esf[1] - esf[0])) < TOL_RER
    assert abs(r.mtf_nyquist - mix(truth_mtf, np.array([0.5]))[0]) < TOL_MTF


# ---- issue 16: the JSON contract ------------------------------------------------------


def test_json_contract_every_estimator_key_present():
    from orthospec.measures.edge import ESTIMATORS

    good = measure_edge(_edge(17.0, 0.8, 300)).to_dict()
    bad = measure_edge(_edge(17.0, 0.8, 10)).to_dict()
    for name in ESTIMATORS:
        for d in (good, bad):
            assert name in d and f"{name}.reason" in d and f"{name}.unit" in d
        assert bad[name] is None and bad[f"{name}.reason"].startswith("invalid edge: snr")
    assert good["rer"] is not None and good["rer.reason"] is None
    assert good["fwhm_m"] is None and good["fwhm_m.reason"] == "no GSD given"
    # a check's value is never null while it passes
    for d in (good, bad):
        for key in d:
            if key.startswith("check.") and key.endswith(".passed") and d[key]:
                assert d[key[: -len(".passed")] + ".value"] is not None, key


def test_json_states_the_direction_and_row_equivalents():
    """Widths are normal to the edge; along a row they are width / cos(theta) (the
    MTF_Estimator image of docs/edge-method.md: FWHM_row = FWHM_perp / cos theta)."""
    angle = 17.0
    r = measure_edge(_edge(angle, 0.8, 300))
    d = r.to_dict()
    assert "normal" in d["direction_convention"]
    c = math.cos(math.radians(r.angle_deg))
    assert d["fwhm_px.along_row"] == pytest.approx(d["fwhm_px"] / c, rel=1e-9)
    assert d["fwhm_px.along_column"] == pytest.approx(
        d["fwhm_px"] / math.sin(math.radians(r.angle_deg))
    )
    # along the row the response is wider: lower RER and MTF than normal to the edge
    assert d["rer.along_row"] < d["rer"] and d["mtf_nyquist.along_row"] < d["mtf_nyquist"]
    t = r.transposed
    rt = measure_edge(_edge(angle, 0.8, 300).T).to_dict()
    assert not t and rt["fwhm_px.along_column"] == pytest.approx(rt["fwhm_px"] / c, rel=1e-3)


def test_noise_free_float_edge_has_a_finite_snr():
    from orthospec.measures.synthetic import slanted_edge as se

    d = measure_edge(se((100, 100), angle_deg=7.0, sigma_px=0.8)).to_dict()
    # the floor is 1e-6 of the contrast (SNR <= 1e6); the blur tail left in the uniform
    # areas is what remains here
    assert d["check.snr.passed"] is True and 1e3 < d["check.snr.value"] <= 1e6
