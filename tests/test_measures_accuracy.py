"""Accuracy statistics against the USGS worked table, hand-computed cases and properties."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from orthospec.errors import MeasureError
from orthospec.measures.accuracy import (
    CANDIDATE_KEPT,
    ERROR_NO_JUSTIFICATION,
    ERROR_WITHIN_TOLERANCE,
    EXCLUDED,
    KEPT,
    accuracy_stats,
    ce90_formula,
    ce95_formula,
    deltas_from_coordinates,
    detect_blunders,
    empirical_percentile,
    nssda_horizontal,
    rmse_net,
)

USGS = json.loads((Path(__file__).parent / "data" / "usgs_geometric_results.json").read_text())
ROWS = USGS["rows"]


def _decimals(value: float) -> int:
    text = repr(value)
    return len(text.split(".")[1]) if "." in text else 0


def _matches_printed(computed: float, printed: float) -> bool:
    """True when ``computed`` rounds to the printed value at the printed precision."""
    half = 0.5 * 10 ** -_decimals(printed)
    return abs(computed - printed) <= half + 1e-12


FORMULAS = {
    "rmse_net": lambda r: float(rmse_net(r["rmse_x"], r["rmse_y"])),
    "ce90": lambda r: float(ce90_formula(r["rmse_x"], r["rmse_y"])),
    "ce95": lambda r: float(ce95_formula(r["rmse_x"], r["rmse_y"])),
}


@pytest.mark.parametrize(
    ("row", "quantity"),
    [(r, q) for r in ROWS for q in FORMULAS],
    ids=[f"{r['sensor']}-{q}" for r in ROWS for q in FORMULAS],
)
def test_usgs_table_reproduces_exactly_where_the_formula_applies(row, quantity):
    # Rows that do NOT reproduce, and why (also in the JSON "notes"):
    # - DAIS rmse_net: printed 0.048 is OCR damage of 0.48 (formula 0.481).
    # - ADS40: printed RMSE_y 0.02 gives RMSE_net 0.201 and CE90 0.236; mu_H/sigma_c = 1.36
    #   > 0.1, so its CE values are empirical percentiles anyway.
    # - IKONOS CE90/CE95: mu_H/sigma_c = 2.60 > 0.1, the printed CE values (2.28/2.53) are
    #   empirical percentiles of delta R; the formula gives 2.500/2.852.
    computed = FORMULAS[quantity](row)
    assert _matches_printed(computed, row[quantity]) is row["reproduces"][quantity]


def test_dais_rmse_net_is_the_printed_value_times_ten():
    dais = next(r for r in ROWS if r["sensor"] == "DAIS")
    assert _matches_printed(float(rmse_net(dais["rmse_x"], dais["rmse_y"])), 0.48)


def test_usgs_bias_ratios_in_the_table_all_exceed_the_limit():
    # The table's CE for DSS 300 and DAIS match the formula although their ratio exceeds 0.1:
    # the seed's own table does not apply its 0.1 rule strictly. We record, not hide, that.
    assert all(r["mu_h_over_sigma_c"] > 0.1 for r in ROWS)


def test_accuracy_stats_reproduce_dss300_from_deltas():
    row = ROWS[0]
    sign = np.tile([1.0, -1.0], 10)  # 20 points, zero mean, RMSE = the amplitude
    s = accuracy_stats(sign * row["rmse_x"], -sign * row["rmse_y"])
    assert s.rmse_x == pytest.approx(row["rmse_x"])
    assert s.rmse_y == pytest.approx(row["rmse_y"])
    for q in ("ce90", "ce95"):
        assert _matches_printed(getattr(s, q), row[q])
    assert _matches_printed(s.rmse_r, row["rmse_net"])
    assert s.bias_negligible and s.ce_method == "formula"
    assert s.ce90_selected == s.ce90


def test_hand_computed_case():
    dx = np.array([1.0, 2.0, 3.0, 4.0])
    dy = np.array([0.0, 0.0, 0.0, 2.0])
    dz = np.array([-1.0, 1.0, -1.0, 1.0])
    s = accuracy_stats(dx, dy, dz, ids=["a", "b", "c", "d"], gsd=0.5)
    assert s.n == 4
    assert s.mean_x == pytest.approx(2.5)
    assert s.std_x == pytest.approx(math.sqrt(5 / 3))  # Σ(d-μ)² = 5, n-1 = 3
    assert s.rmse_x == pytest.approx(math.sqrt(30 / 4))
    assert s.rmse_y == pytest.approx(1.0)
    assert s.rmse_z == pytest.approx(1.0)
    assert s.mean_z == pytest.approx(0.0)
    assert s.rmse_r == pytest.approx(math.sqrt(7.5 + 1.0))
    assert s.nssda_vertical_95 == pytest.approx(1.96)
    assert s.max_abs_dx == 4.0 and s.max_abs_dy == 2.0 and s.max_abs_dz == 1.0
    assert s.max_dr == pytest.approx(math.sqrt(20.0))
    assert s.sigma_c == pytest.approx((math.sqrt(5 / 3) + 1.0) / 2)  # std_y = sqrt(0.75*4/3)=1
    assert s.mu_h == pytest.approx(math.hypot(2.5, 0.5))
    g = s.in_gsd()
    assert g.unit == "px" and g.rmse_y == pytest.approx(2.0) and g.max_dr == pytest.approx(
        math.sqrt(20.0) / 0.5)
    assert g.n == 4 and g.bias_ratio == s.bias_ratio  # ratios are not lengths


def test_deltas_are_image_minus_reference():
    dx, dy, dz = deltas_from_coordinates([10.0], [20.0], [9.5], [21.0], [5.0], [4.0])
    assert dx[0] == 0.5 and dy[0] == -1.0 and dz is not None and dz[0] == 1.0
    with pytest.raises(MeasureError, match="together"):
        deltas_from_coordinates([1.0], [1.0], [1.0], [1.0], z=[1.0])


@pytest.mark.parametrize(
    ("rx", "ry", "expected", "holds", "method"),
    [
        (1.0, 1.0, 1.7308 * math.sqrt(2.0), True, "equal"),
        (0.7, 1.0, 2.4477 * 0.5 * 1.7, True, "approximation"),
        (0.6, 1.0, 2.4477 * 0.5 * 1.6, True, "approximation"),
        # below 0.6 the closed form does not hold: the 95 % radius of the elliptical normal error
        # (issue 26), checked against the polar-form quadrature of tests/test_consequences.py
        (0.5, 1.0, None, False, "elliptical"),
        (0.0, 0.0, 0.0, True, "equal"),
    ],
)
def test_nssda_horizontal(rx, ry, expected, holds, method):
    acc, ratio, ok, how = nssda_horizontal(rx, ry)
    if expected is None:
        from tests.test_consequences import _ellipse_95_polar

        expected = _ellipse_95_polar(max(rx, ry), min(rx, ry))
        assert acc > 2.4477 * 0.5 * (rx + ry)  # the closed form would understate it
    assert acc == pytest.approx(expected)
    assert ok is holds and how == method
    assert ratio == pytest.approx(1.0 if ry == rx else rx / ry)


def test_nssda_flag_in_stats_when_ratio_below_06():
    s = accuracy_stats([1.0, -1.0], [0.1, -0.1])
    assert s.nssda_ratio == pytest.approx(0.1)
    assert s.nssda_approximation_holds is False
    assert math.isfinite(s.nssda_horizontal_95)


def test_bias_decision_uses_mu_h_not_mu_x():
    # Pure northing bias: mu_x = 0, so the literal "mu_x/sigma_c > 0.1" would call it
    # negligible; mu_H/sigma_c (the tabulated ratio) does not.
    dx = np.array([0.1, -0.1, 0.1, -0.1])
    dy = np.array([1.1, 0.9, 1.1, 0.9])
    s = accuracy_stats(dx, dy)
    assert s.bias_ratio_x == pytest.approx(0.0)
    assert s.bias_ratio > 0.1
    assert s.bias_negligible is False
    assert s.ce_method == "empirical" and s.ce90_selected == s.ce90_empirical


def test_pure_shift_has_infinite_bias_ratio():
    s = accuracy_stats([1.0, 1.0, 1.0], [0.0, 0.0, 0.0])
    assert s.sigma_c == 0.0 and math.isinf(s.bias_ratio) and not s.bias_negligible


def test_empirical_percentiles_hand_computed():
    dr = np.arange(1.0, 11.0)  # sorted v0..v9 = 1..10
    # linear (Hyndman-Fan 7): h = (n-1)q = 8.1 -> v8 + 0.1(v9 - v8) = 9.1; q=.95 -> 9.55
    assert empirical_percentile(dr, 90) == pytest.approx(9.1)
    assert empirical_percentile(dr, 95) == pytest.approx(9.55)
    # nearest rank: v[ceil(q n) - 1] -> v8 = 9 and v9 = 10
    assert empirical_percentile(dr, 90, method="nearest-rank") == 9.0
    assert empirical_percentile(dr, 95, method="nearest-rank") == 10.0
    s = accuracy_stats(dr[::-1], np.zeros(10), percentile_method="nearest-rank")
    assert s.ce90_empirical == 9.0 and s.percentile_method == "nearest-rank"
    with pytest.raises(MeasureError, match="percentile method"):
        empirical_percentile(dr, 90, method="type9")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dx": [1.0], "dy": [1.0]}, "at least 2"),
        ({"dx": [1.0, np.nan, 2.0], "dy": [1.0, 1.0, 2.0], "ids": ["A", "B", "C"]}, "dx.*B"),
        ({"dx": [1.0, 2.0], "dy": [1.0, np.inf], "ids": ["A", "B"]}, "dy.*B"),
        ({"dx": [1.0, 2.0, 3.0], "dy": [1, 2, 3], "ids": ["P1", "P2", "P1"]}, "duplicate.*P1"),
        ({"dx": [1.0, 2.0], "dy": [1.0, 2.0, 3.0]}, "shape"),
        ({"dx": [1.0, 2.0], "dy": [1.0, 2.0], "dz": [1.0, np.nan], "ids": ["a", "z9"]}, "dz.*z9"),
        ({"dx": [1.0, 2.0], "dy": [1.0, 2.0], "gsd": 0.0}, "GSD"),
    ],
)
def test_bad_input_raises_with_offending_ids(kwargs, match):
    kw = dict(kwargs)
    dx, dy = kw.pop("dx"), kw.pop("dy")
    with pytest.raises(MeasureError, match=match):
        accuracy_stats(dx, dy, **kw)


def test_in_gsd_without_gsd_raises():
    with pytest.raises(MeasureError, match="GSD"):
        accuracy_stats([1.0, 2.0], [1.0, 2.0]).in_gsd()


# --------------------------------------------------------------------------- properties

finite = st.floats(-100, 100, allow_nan=False, allow_infinity=False)


@st.composite
def deltas(draw):
    n = draw(st.integers(2, 40))
    dx = draw(arrays(float, n, elements=finite))
    dy = draw(arrays(float, n, elements=finite))
    dz = draw(arrays(float, n, elements=finite))
    return dx, dy, dz


@settings(max_examples=60, deadline=None)
@given(deltas())
def test_rmse_squared_is_mean_squared_plus_scaled_variance(d):
    dx, dy, dz = d
    s = accuracy_stats(dx, dy, dz)
    n = s.n
    for ax in "xyz":
        rmse, mean, std = (getattr(s, f"{k}_{ax}") for k in ("rmse", "mean", "std"))
        assert rmse**2 == pytest.approx(mean**2 + (n - 1) / n * std**2, rel=1e-9, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(deltas(), st.floats(0, 2 * math.pi))
def test_rotation_leaves_rmse_r_unchanged(d, theta):
    dx, dy, _ = d
    c, s_ = math.cos(theta), math.sin(theta)
    a = accuracy_stats(dx, dy)
    b = accuracy_stats(c * dx - s_ * dy, s_ * dx + c * dy)
    assert b.rmse_r == pytest.approx(a.rmse_r, rel=1e-9, abs=1e-9)
    assert b.max_dr == pytest.approx(a.max_dr, rel=1e-9, abs=1e-9)
    assert b.mu_h == pytest.approx(a.mu_h, rel=1e-9, abs=1e-9)


LENGTHS = ("mean_x", "mean_y", "mean_z", "std_x", "std_y", "std_z", "rmse_x", "rmse_y",
           "rmse_z", "rmse_r", "nssda_horizontal_95", "nssda_vertical_95", "ce90", "ce95",
           "ce90_empirical", "ce95_empirical", "max_abs_dx", "max_abs_dy", "max_abs_dz",
           "max_dr", "sigma_c", "mu_h")


@settings(max_examples=60, deadline=None)
@given(deltas(), st.floats(0.01, 100))
def test_scaling_scales_every_length(d, k):
    dx, dy, dz = d
    a = accuracy_stats(dx, dy, dz)
    b = accuracy_stats(k * dx, k * dy, k * dz)
    for name in LENGTHS:
        assert getattr(b, name) == pytest.approx(k * getattr(a, name), rel=1e-9, abs=1e-9), name
    assert b.nssda_ratio == pytest.approx(a.nssda_ratio, rel=1e-9, abs=1e-9)


# --------------------------------------------------------------------------- blunders


def _twenty(big_dx: float = 5.0):
    rng = np.random.default_rng(1)
    dx = rng.normal(0, 0.2, 20)
    dy = rng.normal(0, 0.2, 20)
    dx[7] = big_dx
    ids = [f"P{i:02d}" for i in range(20)]
    return dx, dy, ids


def test_blunder_candidate_excluded_only_with_justification():
    dx, dy, ids = _twenty()
    res = detect_blunders(dx, dy, ids=ids, exclusions={"P07": "feature changed since survey"})
    assert res.limit_x == pytest.approx(3 * res.stats_all.rmse_x)
    assert res.candidates == ("P07",)
    assert res.excluded == ("P07",)
    d7 = res.decisions[7]
    assert d7.decision == EXCLUDED and d7.exceeds_x and "feature changed" in d7.reason
    assert res.stats_kept is not None and res.stats_kept.n == 19
    ref = accuracy_stats(np.delete(dx, 7), np.delete(dy, 7))
    assert res.stats_kept.rmse_x == pytest.approx(ref.rmse_x)
    assert res.stats_all.n == 20
    assert [d.decision for d in res.decisions].count(KEPT) == 19
    assert len(res.decisions) == 20 and not res.errors


def test_blunder_without_request_is_kept():
    dx, dy, ids = _twenty()
    res = detect_blunders(dx, dy, ids=ids)
    assert res.decisions[7].decision == CANDIDATE_KEPT
    assert res.stats_kept is res.stats_all


def test_exclusion_within_tolerance_is_an_error_never_silently_excluded():
    dx, dy, ids = _twenty()
    res = detect_blunders(dx, dy, ids=ids, exclusions={"P03": "looks odd", "P07": "  "})
    assert res.decisions[3].decision == ERROR_WITHIN_TOLERANCE
    assert res.decisions[7].decision == ERROR_NO_JUSTIFICATION
    assert {d.point_id for d in res.errors} == {"P03", "P07"}
    assert res.excluded == ()
    assert res.stats_kept is not None and res.stats_kept.n == 20


def test_radial_reported_separately_from_axis_candidates():
    dx, dy, ids = _twenty()
    res = detect_blunders(dx, dy, ids=ids)
    d7 = res.decisions[7]
    assert d7.candidate and d7.exceeds_x
    assert res.limit_r == pytest.approx(math.hypot(res.limit_x, res.limit_y))
    assert d7.exceeds_r is (d7.dr > res.limit_r)


def test_target_basis_uses_target_rmse():
    dx, dy, ids = _twenty(big_dx=0.9)
    calc = detect_blunders(dx, dy, ids=ids)
    tgt = detect_blunders(dx, dy, ids=ids, basis="target", target_rmse_xy=0.25)
    assert tgt.limit_x == pytest.approx(0.75) and tgt.basis == "target"
    assert "P07" in tgt.candidates
    assert calc.limit_x != tgt.limit_x
    with pytest.raises(MeasureError, match="target RMSE"):
        detect_blunders(dx, dy, ids=ids, basis="target")
    no_z = detect_blunders(dx, dy, dy, ids=ids, basis="target", target_rmse_xy=1.0)
    assert no_z.limit_z is None and "dz not screened" in no_z.note
    with pytest.raises(MeasureError, match="target_rmse_z"):
        detect_blunders(dx, dy, dy, ids=ids, basis="target", target_rmse_xy=1.0, target_rmse_z=0)
    z = detect_blunders(dx, dy, dy * 10, ids=ids, basis="target", target_rmse_xy=1.0,
                        target_rmse_z=0.2)
    assert z.limit_z == pytest.approx(0.6)
    assert set(z.ids[z.exceeds_z]) == set(np.asarray(ids)[np.abs(dy * 10) > 0.6])
    with pytest.raises(MeasureError, match="basis"):
        detect_blunders(dx, dy, ids=ids, basis="median")  # type: ignore[arg-type]


def test_unknown_exclusion_id_raises():
    dx, dy, ids = _twenty()
    with pytest.raises(MeasureError, match=r"unknown point id.*NOPE"):
        detect_blunders(dx, dy, ids=ids, exclusions={"NOPE": "x"})


def test_excluding_down_to_one_point_leaves_no_kept_stats():
    res = detect_blunders([0.0, 10.0], [0.0, 0.0], ids=["a", "b"], basis="target",
                          target_rmse_xy=1.0, exclusions={"b": "destroyed"})
    assert res.stats_kept is None and "1 point" in res.note


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 8).flatmap(lambda n: st.tuples(arrays(float, n, elements=finite),
                                                      arrays(float, n, elements=finite))))
def test_calculated_basis_cannot_flag_with_few_points(d):
    # max|d| <= sqrt(n)·RMSE <= 3·RMSE for n <= 9: documented limitation of §12.6 (n = 9 is
    # the equality case, left out to stay clear of rounding).
    dx, dy = d
    assert detect_blunders(dx, dy).candidates == ()


# --- systematic error: Student t of the mean error (JRC §12.4 guard; seed 000 bias) -----------

@pytest.mark.parametrize(("mean", "std", "n", "t", "p"), [
    # t = |mean| / (s / sqrt(n)); p from printed t-tables: t(0.975, 19) = 2.093, t(0.995, 9) = 3.250
    (0.45, 0.1, 20, 0.45 * math.sqrt(20) / 0.1, None),
    (2.093 * 0.1 / math.sqrt(20), 0.1, 20, 2.093, 0.05),
    (-3.250 * 0.2 / math.sqrt(10), 0.2, 10, 3.250, 0.01),
    (0.0, 0.3, 5, 0.0, 1.0),
])
def test_bias_significance_against_hand_values_and_t_tables(mean, std, n, t, p):
    from orthospec.measures.accuracy import bias_significance

    got_t, got_p = bias_significance(mean, std, n)
    assert got_t == pytest.approx(t, rel=1e-9)
    if p is None:
        assert got_p < 1e-12  # a 0.45 m shift with 0.1 m noise over 20 points is no accident
    else:
        assert got_p == pytest.approx(p, abs=5e-4)


def test_bias_significance_edge_cases():
    from orthospec.measures.accuracy import bias_significance

    assert bias_significance(0.2, 0.0, 5) == (math.inf, 0.0)   # every point shifted by exactly 0.2
    assert bias_significance(0.0, 0.0, 5) == (0.0, 1.0)
    assert bias_significance(0.2, 0.1, 1) == (None, None)      # one point: no spread, no test
    assert bias_significance(None, None, 10) == (None, None)   # absent axis (no z)


def test_blunder_reasons_per_decision_class_and_axes_with_target_basis():
    """Reason texts (built once per decision/axes class) name exactly the axes over 3 x the target
    RMSE (JRC Table 9) and carry each excluded point's own justification."""
    dx = np.full(12, 0.1)
    dy = np.full(12, -0.1)
    dz = np.full(12, 0.05)
    dx[[1, 3, 5]] = 2.0  # over 3 x 0.5 m in x
    dy[[3, 4, 5]] = 2.0  # over 3 x 0.5 m in y
    dz[[5, 6]] = 1.0  # over 3 x 0.25 m in z
    ids = [f"Q{i}" for i in range(12)]
    res = detect_blunders(
        dx,
        dy,
        dz,
        ids=ids,
        basis="target",
        target_rmse_xy=0.5,
        target_rmse_z=0.25,
        exclusions={"Q1": "target destroyed", "Q3": "mis-identified", "Q4": "", "Q8": "looks odd"},
    )
    over = "exceeds the maximum tolerable discrepancy in "
    expected = {
        "Q0": "within the maximum tolerable discrepancy",
        "Q1": over + "x; excluded: target destroyed",
        "Q3": over + "x, y; excluded: mis-identified",
        "Q4": over + "y; exclusion requested without a justification, kept",
        "Q5": over + "x, y, z; no exclusion requested, kept",
        "Q6": over + "z; no exclusion requested, kept",
        "Q8": "exclusion requested but the point is within the maximum tolerable discrepancy; it stays in "
        "the sample (JRC §12.6)",
    }
    got = dict(zip(ids, res.reasons.tolist(), strict=True))
    for pid, text in expected.items():
        assert got[pid] == text
    assert [d.reason for d in res.decisions] == res.reasons.tolist()
    assert res.excluded == ("Q1", "Q3")
    assert res.error_ids == ("Q4", "Q8") and tuple(d.point_id for d in res.errors) == ("Q4", "Q8")
    assert res.candidates == ("Q1", "Q3", "Q4", "Q5", "Q6")
    np.testing.assert_array_equal(res.dr, np.hypot(dx, dy))
    # built once: the per-point objects are not rebuilt on every access
    assert res.decisions is res.decisions and res.reasons is res.reasons


def test_ids_as_text_without_copying_a_table_column():
    """A table's id column (an object array of str) is used as it is; anything else is each
    converted with str(), as before."""
    from orthospec.measures.accuracy import str_ids

    column = np.array(["P1", "P2", "P10"], dtype=object)
    assert str_ids(column) is column
    mixed = np.array(["P1", 2, None], dtype=object)
    assert str_ids(mixed).tolist() == ["P1", "2", "None"]
    assert str_ids([3, "x"]).tolist() == ["3", "x"] and str_ids([3, "x"]).dtype == object
