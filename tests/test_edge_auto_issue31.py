"""Issue 31: the automatic edge search gives one measurement per physical edge, and a float
band holding integer DNs keeps the quantisation floor of integer data."""

from __future__ import annotations

import numpy as np
import pytest

from orthospec.measures import edge_detect
from orthospec.measures.edge import PSF_FITS, measure_edge
from orthospec.measures.synthetic import PsfFamily, family_edge


@pytest.mark.parametrize("seed", [3, 5])
def test_one_measurement_per_physical_edge_at_snr_30(seed):
    """One straight edge, SNR 30: noise lines crossing it at the border were reported beside it
    (seeds 3 and 5: two edges for one); now exactly the one edge, valid."""
    img = family_edge(PsfFamily("gauss", sigma=0.8), (120, 120), angle_deg=8.0, dark=40, bright=200,
                      snr=30, bit_depth=8, rng=np.random.default_rng(seed))
    t = edge_detect.measure_target(img, min_snr=25)
    assert len(t.edges) == 1
    assert t.edges[0].result.valid and t.edges[0].result.angle_deg == pytest.approx(8.0, abs=0.3)


def test_collinear_duplicates_are_merged():
    """The same edge found as two overlapping segments (what noise does to Hough): one kept."""
    img = family_edge(PsfFamily("gauss", sigma=0.8), (120, 120), angle_deg=8.0, dark=40, bright=200,
                      snr=100, bit_depth=8, rng=np.random.default_rng(0))
    t = edge_detect.measure_target(img)
    (e,) = t.edges
    twin = edge_detect.FoundEdge(
        e.x0 + 0.5,
        e.y0 + 10,
        e.x1 + 0.5,
        e.y1 - 5,
        e.line_angle_deg + 0.5,
        e.axis,
        e.window,
        e.half_width_px,
        e.result,
        e.roi,
    )
    assert edge_detect._one_per_edge([twin, e]) == [e]  # the longer one stays
    other = edge_detect.FoundEdge(
        e.x0 + 20,
        e.y0,
        e.x1 + 20,
        e.y1,
        e.line_angle_deg,
        e.axis,
        e.window,
        e.half_width_px,
        e.result,
        e.roi,
    )
    assert len(edge_detect._one_per_edge([e, other])) == 2  # a parallel edge 20 px away stays


def test_float_band_with_integer_dns_keeps_the_quantisation_floor():
    """A noise-free 8-bit edge read as float (as the automatic search and masked reads pass it)
    has the SNR floor dDN / (1 / sqrt(12)) of integer data, as the uint8 array itself does."""
    img = family_edge(
        PsfFamily("gauss", sigma=0.7), (100, 100), angle_deg=7.0, dark=40, bright=200, bit_depth=8
    )
    as_int = measure_edge(img)
    as_float = measure_edge(img.astype(np.float32))
    assert as_float.check("snr").value == pytest.approx(as_int.check("snr").value, rel=1e-9)
    assert as_float.check("snr").value <= 160 * 12**0.5 + 1e-6
    model = next(f for n, f in as_float.fits.items() if n in PSF_FITS)
    assert model.params["quantisation_dn"] == 1.0
    # a genuinely continuous float band has no such floor
    cont = measure_edge(img.astype(float) + 0.25 * np.random.default_rng(0).random(img.shape))
    assert next(f for n, f in cont.fits.items() if n in PSF_FITS).params["quantisation_dn"] == 0.0
