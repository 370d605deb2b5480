"""Issue 31, last items: the normal CDF without scipy.special, the 3-tap MTFC model on the pixel
grid, the rounding bound of flat bins, and one BLAS thread in the library call.

Truths are independent of the chain: ``math.erfc`` for the CDF, and for the edges
``synthetic.family_truth`` (numerical inverse of the 2-D OTF, validated in
test_edge_families.py against the 3-tap filter applied on the pixel grid)."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from orthospec.measures import psf
from orthospec.measures.edge import measure_edge
from orthospec.measures.edge.chain import one_blas_thread
from orthospec.measures.edge.model import _rounding_variance
from orthospec.measures.synthetic import PsfFamily, family_edge, family_truth


def test_normal_cdf_equals_the_standard_librarys_erfc():
    z = np.concatenate([np.linspace(-12.0, 12.0, 48_001), [-9.0, 9.0, 0.0, -1e-300, 37.5]])
    ref = np.array([0.5 * math.erfc(-float(t) / math.sqrt(2.0)) for t in z])
    assert np.max(np.abs(psf.ndtr(z) - ref)) < 2e-15
    out = psf.ndtr(np.array([np.nan, -np.inf, np.inf]))
    assert np.isnan(out[0]) and out[1] < 1e-18 and out[2] == 1.0
    assert psf.ndtr(np.zeros((3, 4))).shape == (3, 4)


def test_the_edge_chain_does_not_import_scipy():
    """scipy.special alone cost ~0.2 s of CPU at start-up, more than the measurement."""
    code = (
        "import sys, orthospec.measures.edge, orthospec.measures.psf; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_box_convolutions_in_one_call_equal_the_corner_sum():
    """The 2^n corners of the central differences, summed one by one (the definition)."""
    x = np.linspace(-6.0, 6.0, 241)
    s, ws = 0.6, (0.9, 0.3, 1.2)
    for order, n_psi in ((0, 3), (-1, 2)):
        ref = np.zeros_like(x)
        for corner in range(8):
            shift = sum(w / 2 if corner >> k & 1 else -w / 2 for k, w in enumerate(ws))
            sign = (-1) ** sum(1 for k in range(3) if not corner >> k & 1)
            ref += sign * psf._psi(n_psi, x + shift, s)
        assert np.allclose(psf._boxed(x, s, ws, order), ref / math.prod(ws), atol=1e-12)


def _edge(fam: PsfFamily, angle: float, shape: tuple[int, int], bits: int) -> tuple:
    truth = family_truth(fam, angle_deg=angle)
    dark, bright = (40.0, 200.0) if bits == 8 else (600.0, 3000.0)
    img = family_edge(
        fam, shape, angle_deg=angle, dark=dark, bright=bright, bit_depth=bits, truth=truth
    )
    return measure_edge(img, min_snr=25), truth


@pytest.mark.parametrize("angle", [26.565, 33.0, 40.0])
def test_a_3_tap_mtfc_edge_is_measured_by_its_model_and_its_uncertainty_covers(angle):
    """Noise-free 12-bit edges sharpened by the 3-tap kernel on rows and columns. Before, the
    continuous unsharp mask was the nearest model: at 26.6 deg MTF@Ny +0.0029 with u 0.0008,
    and at 33 and 40 deg the spline was kept (the model missed by 1.6-2 DN)."""
    fam = PsfFamily("mtfc", sigma=0.8, amount=0.25)
    r, t = _edge(fam, angle, (100, 100), 12)
    assert r.valid and r.primary_fit == "gauss-mtfc"
    for name, truth in (("mtf_nyquist", t.mtf_nyquist), ("rer", t.rer), ("fwhm_px", t.fwhm_px)):
        e = r.estimate(name)
        assert abs(e.value - truth) <= 2 * e.u, (name, e.value - truth, e.u)
    assert abs(r.mtf_nyquist - t.mtf_nyquist) < 0.002
    assert r.fits["gauss-mtfc"].params["mtfc_amount"] == pytest.approx(0.25, abs=0.02)


@pytest.mark.parametrize("angle,shape", [(2.5, (60, 60)), (9.0, (200, 120))])
def test_a_noise_free_8_bit_diffraction_edge_keeps_its_model(angle, shape):
    """Before: the lack-of-fit test rejected the right (diffraction) model on the rounding
    staircase of the far tails, and the spline, which follows the staircase, was reported:
    MTF@Ny -0.011 and -0.012 (MTF Mapper: +0.006, +0.002)."""
    fam = PsfFamily("diffraction", cutoff=1.0, sigma=0.25, length=0.8)
    r, t = _edge(fam, angle, shape, 8)
    assert r.valid and r.primary_fit == "airy"
    assert abs(r.mtf_nyquist - t.mtf_nyquist) < 0.005


def test_rounding_variance_is_the_bound_only_in_bins_of_one_dn():
    v = np.array([40.0, 40.0, 40.0, 41.0, 42.0, 42.0, 7.0])
    idx = np.array([0, 0, 0, 1, 1, 2, 3])  # bin 2 holds one pixel: no evidence of a tread
    assert _rounding_variance(v, idx, 4, 1.0).tolist() == [0.25, 1 / 12, 1 / 12, 1 / 12]
    assert _rounding_variance(v, idx, 4, 0.0).tolist() == [0.0] * 4
    gap = np.array([0, 0, 3, 3])  # an empty bin between: numbered as bins() numbers them
    assert _rounding_variance(np.array([1.0, 1.0, 2.0, 3.0]), gap, 2, 2.0).tolist() == [1.0, 1 / 3]


def test_library_call_runs_on_one_blas_thread_and_restores_it(monkeypatch):
    threadpoolctl = pytest.importorskip("threadpoolctl")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)

    def blas_threads() -> list[int]:
        return [
            m["num_threads"] for m in threadpoolctl.threadpool_info() if m["user_api"] == "blas"
        ]

    before = blas_threads()
    with one_blas_thread():
        assert all(n == 1 for n in blas_threads())
    assert blas_threads() == before
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")  # the CLI's processes: nothing to do
    with one_blas_thread():
        assert blas_threads() == before
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
