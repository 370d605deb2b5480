"""GIQE 4 and 5 against the published coefficients and hand-computed cases.

Sources:
* GIQE 4: Leachtenauer, Malila, Irvine, Colburn & Salvaggio, "General Image-Quality
  Equation: GIQE", Applied Optics 36(32):8322-8328 (1997), eq. 1:
  NIIRS = 10.251 - a log10 GSD + b log10 RER - 0.656 H - 0.344 G/SNR,
  a = 3.32, b = 1.559 for RER >= 0.9, else a = 3.16, b = 2.817 (GSD in inches).
* GIQE 5: NGA, "The General Image Quality Equation version 5.0" (16 Sep 2015, public
  release), as implemented in pyBSM (Kitware/AFRL) ``metrics.functional.giqe5``:
  NIIRS = 9.57 - 3.32 log10 GSD + 3.32 (1 - exp(-1.9/SNR)) log10 RER - 2 (log10 RER)^4
  - 1.8/SNR, RER = (max * min^2)^(1/3); NGA's Figure-1 case RER 0.35, GSD 20.8 in,
  SNR 50 is NIIRS 5.
* Overshoot H: Leachtenauer et al. 1997 (quoted in pyBSM ``edge_height_overshoot``):
  max over 1.0-3.0 px in 0.25-px steps; the value at 1.25 px for a monotone edge.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from orthospec.errors import MeasureError
from orthospec.measures.giqe import GIQE4, GIQE5, edge_overshoot, giqe4, giqe5


def test_published_coefficients():
    assert GIQE4 == {"c0": 10.251, "a_rer_ge_0.9": 3.32, "b_rer_ge_0.9": 1.559,
                     "a_rer_lt_0.9": 3.16, "b_rer_lt_0.9": 2.817, "h": 0.656,
                     "g_over_snr": 0.344}
    assert GIQE5 == {"a0": 9.57, "a1": -3.32, "a2": 3.32, "a3": -1.9, "a4": -2.0, "a5": -1.8}


def test_giqe4_hand_computed_below_the_rer_switch():
    # GSD 1 m = 39.3701 in: log10 = 1.595166; 3.16 x 1.595166 = 5.040725
    # RER 0.5: log10 = -0.301030; 2.817 x -0.301030 = -0.848001
    # H 1.0: 0.656; G/SNR = 1/50: 0.344 x 0.02 = 0.00688
    # 10.251 - 5.040725 - 0.848001 - 0.656 - 0.00688 = 3.699394
    r = giqe4(gsd_m=1.0, rer=0.5, overshoot=1.0, noise_gain=1.0, snr=50.0)
    assert r.niirs == pytest.approx(3.699394, abs=2e-6)
    assert r.inputs["gsd_in"] == pytest.approx(39.370079, abs=1e-6)
    assert (r.coefficients["a"], r.coefficients["b"]) == (3.16, 2.817)


def test_giqe4_hand_computed_above_the_rer_switch():
    # GSD 0.1 m = 3.937008 in: log10 = 0.595166; 3.32 x = 1.975952
    # RER 0.95: log10 = -0.022276; 1.559 x = -0.034729
    # H 1.1: 0.7216; G 2, SNR 100: 0.344 x 0.02 = 0.00688
    # 10.251 - 1.975952 - 0.034729 - 0.7216 - 0.00688 = 7.511839
    r = giqe4(gsd_m=0.1, rer=0.95, overshoot=1.1, noise_gain=2.0, snr=100.0)
    assert r.niirs == pytest.approx(7.511839, abs=2e-6)
    assert (r.coefficients["a"], r.coefficients["b"]) == (3.32, 1.559)
    assert r.to_dict()["giqe.input.rer"] == 0.95


def test_giqe5_nga_figure_1_case_is_niirs_5():
    r = giqe5(gsd_m=20.8 * 0.0254, rer_x=0.35, rer_y=0.35, snr=50.0)
    # 9.57 - 3.32 x 1.318063 + 3.32 x (1 - e^-0.038) x -0.455932 - 2 x 0.043211 - 0.036
    # = 9.57 - 4.375970 - 0.056448 - 0.086422 - 0.036 = 5.015160
    assert r.niirs == pytest.approx(5.015160, abs=2e-5)
    assert round(r.niirs, 1) == 5.0


def test_giqe5_two_direction_rer_weights_the_smaller_twice():
    r = giqe5(gsd_m=0.5, rer_x=0.6, rer_y=0.3, snr=math.inf)
    assert r.inputs["rer"] == pytest.approx((0.6 * 0.3**2) ** (1 / 3))
    lr = math.log10(r.inputs["rer"])
    assert r.niirs == pytest.approx(9.57 - 3.32 * math.log10(0.5 / 0.0254) - 2 * lr**4)


def test_bad_inputs_raise():
    with pytest.raises(MeasureError, match="rer"):
        giqe4(gsd_m=1.0, rer=0.0)
    with pytest.raises(MeasureError, match="gsd"):
        giqe5(gsd_m=-1.0, rer_x=0.5)


def test_overshoot_monotone_edge_is_the_value_at_1_25_px():
    sig = 0.7

    def esf(x):
        return ndtr(np.asarray(x) / sig)

    assert edge_overshoot(esf, 0.0) == pytest.approx(float(ndtr(1.25 / sig)))


def test_overshoot_ringing_edge_is_the_peak_in_1_to_3_px():
    def esf(x):
        x = np.asarray(x, dtype=float)
        return ndtr(x / 0.5) + 0.1 * np.exp(-0.5 * ((x - 1.5) / 0.3) ** 2)

    assert edge_overshoot(esf, 0.0) == pytest.approx(float(esf(np.array([1.5]))[0]), abs=1e-9)
