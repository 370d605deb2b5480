"""Subpixel chip matching (measures/matching.py): positions against shifts whose truth is the
Fourier shift theorem applied to a real Landsat chip, and the decisions that send a point to the
checker (issue 29)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from scipy import ndimage

from orthospec.measures.matching import MatchSettings, match_chip, noise_sigma, texture_ratio

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
ROOT = Path(__file__).resolve().parents[1]
T, S = 64, 16  # template, search range
M = S + 1


@pytest.fixture(scope="module")
def scene() -> np.ndarray:
    with rasterio.open(REAL / "RGB.byte.tif") as ds:
        lum = ds.read().astype(np.float64).mean(axis=0)
    return ndimage.gaussian_filter(lum, 0.5)


def _pair(
    scene: np.ndarray, r0: int, c0: int, dy: float, dx: float
) -> tuple[np.ndarray, np.ndarray]:
    """Template at (r0, c0) and a search window whose content is moved by (dy, dx): an exact,
    band-limited shift (Fourier shift theorem) of a larger window, cropped."""
    big = scene[r0 - M - 32 : r0 + T + M + 32, c0 - M - 32 : c0 + T + M + 32]
    moved = np.fft.ifft2(ndimage.fourier_shift(np.fft.fft2(big), (dy, dx))).real
    return scene[r0 : r0 + T, c0 : c0 + T], moved[32:-32, 32:-32]


CENTRES = [(250, 300), (320, 420), (400, 350), (200, 500), (450, 250)]


@pytest.mark.parametrize(
    ("dy", "dx"), [(0.0, 0.0), (0.25, -0.5), (-1.37, 2.81), (4.6, -3.05), (0.5, 0.5)]
)
@pytest.mark.parametrize("method", ["phase", "ncc"])
def test_known_subpixel_shift(scene: np.ndarray, dy: float, dx: float, method: str) -> None:
    errs = []
    for r0, c0 in CENTRES:
        t, s = _pair(scene, r0, c0, dy, dx)
        m = match_chip(t, s, settings=MatchSettings(method=method))  # type: ignore[arg-type]
        assert m.accepted, (r0, c0, m.reason)
        errs.append(math.hypot(m.dx_px - dx, m.dy_px - dy))
        assert m.score > 0.95
    # the default (phase) is exact to its 1/100 px DFT grid; the Gaussian peak fit is looser
    assert max(errs) <= (0.015 if method == "phase" else 0.2), errs


def test_phase_is_more_accurate_than_the_peak_fit(scene: np.ndarray) -> None:
    """Why ``phase`` is the default: over fractional shifts its error is a fraction of the fit's."""
    rng = np.random.default_rng(3)
    e = {"phase": [], "ncc": []}
    for r0, c0 in CENTRES:
        dy, dx = rng.uniform(-3, 3, 2)
        t, s = _pair(scene, r0, c0, dy, dx)
        m = match_chip(t, s)
        e["phase"].append(math.hypot(m.dx_px - dx, m.dy_px - dy))
        e["ncc"].append(math.hypot(m.other_dx_px - dx, m.other_dy_px - dy))
    assert np.median(e["phase"]) < 0.5 * np.median(e["ncc"])


def test_flat_chip_goes_to_the_checker() -> None:
    rng = np.random.default_rng(1)
    field = 80 + ndimage.gaussian_filter(rng.standard_normal((T + 2 * M, T + 2 * M)), 12) * 36
    s = field + rng.normal(0, 1.5, field.shape)
    t = field[M : M + T, M : M + T] + rng.normal(0, 1.5, (T, T))
    m = match_chip(t, s)
    assert m.decision == "by_hand"
    assert m.reason_code in ("low_texture", "ambiguous")
    assert texture_ratio(t) < 1.5  # pure noise gives 1
    assert noise_sigma(t) == pytest.approx(1.5, rel=0.15)


def test_cloud_goes_to_the_checker(scene: np.ndarray) -> None:
    t, s = _pair(scene, 320, 420, 1.3, -0.7)
    cloudy = s.copy()
    cloudy[10:80, 5:90] = 235.0 + np.random.default_rng(2).normal(0, 1, (70, 85))
    m = match_chip(t, cloudy)
    assert m.decision == "by_hand"
    assert m.reason_code == "cloud"
    assert match_chip(t, s).accepted  # the same pair without the cloud


def test_no_data_in_the_window_is_an_edge(scene: np.ndarray) -> None:
    t, s = _pair(scene, 320, 420, 0.3, 0.3)
    valid = np.ones_like(s, dtype=bool)
    valid[:, :5] = False
    m = match_chip(t, s, search_valid=valid)
    assert (m.decision, m.reason_code) == ("by_hand", "edge")
    assert math.isnan(m.dx_px)


def test_shift_at_and_beyond_the_search_range(scene: np.ndarray) -> None:
    t, s = _pair(scene, 320, 420, 0.0, 15.6)  # within +-16 px: found
    m = match_chip(t, s)
    assert m.accepted and abs(m.dx_px - 15.6) < 0.02
    t, s = _pair(scene, 320, 420, 0.0, 19.5)  # beyond: never a wrong position accepted
    m = match_chip(t, s)
    assert m.decision == "by_hand"
    assert m.reason_code in ("search_limit", "ambiguous", "change")


def test_changed_content_is_not_accepted(scene: np.ndarray) -> None:
    """The template from one place, the image from another: never a silent match."""
    t, _ = _pair(scene, 320, 420, 0, 0)
    _, s = _pair(scene, 200, 500, 0, 0)
    m = match_chip(t, s)
    assert m.decision == "by_hand"


def test_bad_shapes_and_settings() -> None:
    with pytest.raises(ValueError, match="square"):
        match_chip(np.zeros((10, 12)), np.zeros((30, 30)))
    with pytest.raises(ValueError, match="even margin"):
        match_chip(np.zeros((20, 20)), np.zeros((21, 21)))
    with pytest.raises(ValueError, match="unknown matching method"):
        MatchSettings(method="sift")  # type: ignore[arg-type]


def _bench():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(
        "bench_matching", ROOT / "benchmarks" / "matching.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up by name
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.slow
def test_accuracy_targets_on_a_fixed_synthetic_set(tmp_path: Path) -> None:
    """Issue 29's targets on a small fixed set of the benchmark's families (the full grid is in
    benchmarks/matching.py): median <= 0.1 px, 95th percentile <= 0.3 px on accepted points, no
    accepted match off by more than 1 px, >= 95 % of the textured points accepted (here: all but
    one), every no-texture and cloud chip on the hand list. Truth: the benchmark's band-limited
    rendering of a known displacement, independent of the matcher."""
    b = _bench()
    pairs = b.make_pairs(tmp_path, 4, seed=2029)
    res = b.run_orthospec(pairs)
    e = b.errors(pairs, res)
    textured = np.array([p.kind == "textured" for p in pairs])
    accepted = ~np.isnan(e)
    assert not accepted[~textured].any(), [
        p.family for p, a in zip(pairs, accepted, strict=True) if a and p.kind != "textured"
    ]
    assert accepted[textured].sum() >= textured.sum() - 1
    assert np.median(e[accepted]) <= 0.1
    assert np.percentile(e[accepted], 95) <= 0.3
    assert (e[accepted] <= 1.0).all()


def test_a_diverging_refinement_goes_to_the_checker() -> None:
    """A template and search window from the benchmark (a repetitive texture under a strong gamma and
    gain change) on which the iterated phase refinement walks off the correlation peak and out of the
    window: it goes to the hand list as unstable, for either estimator. Before the fix the next patch
    was empty and the FFT raised ValueError (a traceback from `measure checkpoints`)."""
    data = np.load(ROOT / "tests" / "data" / "matching" / "diverging-refinement.npz")
    template, search = data["template"].astype(np.float64), data["search"].astype(np.float64)
    for method in ("phase", "ncc"):
        m = match_chip(template, search, settings=MatchSettings(method=method))  # type: ignore[arg-type]
        assert m.decision == "by_hand" and m.reason_code == "unstable", (method, m)
        assert math.isnan(m.dx_px) and math.isnan(m.dy_px)


def test_a_third_of_the_chip_under_cloud_goes_to_the_checker() -> None:
    """A benchmark cloud pair (a third of the template's area under a bright cloud, the point's
    surroundings partly visible): its obscured share (0.145) was under the former 0.15 limit and the
    match was accepted; the limit is 0.08 (no accepted textured pair of the benchmark above 0.03)."""
    data = np.load(ROOT / "tests" / "data" / "matching" / "partial-cloud.npz")
    m = match_chip(data["template"].astype(np.float64), data["search"].astype(np.float64))
    assert m.decision == "by_hand" and m.reason_code in ("cloud", "change"), m
    assert 0.08 < m.obscured < 0.15
