import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from orthospec.errors import ExpressionError
from orthospec.profile.expr import parse
from orthospec.units import Q_


@pytest.mark.parametrize("src, names, expected", [
    ("3 * tolerance", {"tolerance": 2.0}, 6.0),
    ("tolerance / 3", {"tolerance": 1.5}, 0.5),
    ("max(a, b) - min(a, b)", {"a": 2.0, "b": 5.0}, 3.0),
    ("abs(a) ** 2", {"a": -3.0}, 9.0),
    ("a < b and not c", {"a": 1, "b": 2, "c": False}, True),
    ("a < b < c", {"a": 1, "b": 3, "c": 2}, False),
    ("manifest.sensor.type == 'aerial'", {"manifest.sensor.type": "aerial"}, True),
    ("x == true or y", {"x": False, "y": False}, False),
    ("7 % 4", {}, 3),
])
def test_evaluates(src, names, expected):
    assert parse(src).evaluate(names) == expected


def test_units_flow_through_arithmetic():
    got = parse("0.5 * pixel").evaluate({"pixel": Q_(0.25, "m")})
    assert got.to("cm").magnitude == pytest.approx(12.5)


def test_incompatible_units_are_refused():
    with pytest.raises(ExpressionError, match="cannot combine"):
        parse("a + b").evaluate({"a": Q_(1, "m"), "b": Q_(1, "degree")})


def test_vectorised_over_arrays():
    out = parse("min(a, 2 * b)").evaluate({"a": np.array([1.0, 9.0, 3.0]), "b": 2.0})
    assert out.tolist() == [1.0, 4.0, 3.0]


@pytest.mark.parametrize("src", [
    "__import__('os').system('true')", "a.__class__", "open('x')", "[1, 2]", "{'a': 1}",
    "lambda: 1", "a if b else c", "a[0]", "f'{a}'", "a @ b", "a << 1", "x := 1", "(a for a in b)",
    "min(*a)", "max(a, key=b)", "a.b()", "",
])
def test_outside_the_grammar_is_refused(src):
    with pytest.raises(ExpressionError):
        parse(src)


def test_unknown_name_is_named():
    with pytest.raises(ExpressionError, match="unknown name 'nope'"):
        parse("nope + 1").evaluate({})


def test_division_by_zero_is_a_clear_error():
    with pytest.raises(ExpressionError, match="division by zero"):
        parse("1 / a").evaluate({"a": 0})


def test_names_are_collected():
    assert parse("a + manifest.x.y * min(b, 2)").names == {"a", "manifest.x.y", "b"}


@given(st.floats(-1e6, 1e6, allow_nan=False), st.floats(-1e6, 1e6, allow_nan=False))
def test_min_max_agree_with_python(a, b):
    names = {"a": a, "b": b}
    assert parse("min(a, b)").evaluate(names) == min(a, b)
    assert parse("max(a, b)").evaluate(names) == max(a, b)


@pytest.mark.parametrize("src, names, expected", [
    ("roll > 1", {"roll": Q_(2.5, "degree")}, True),      # 1 deg, not 1 rad
    ("cloud < 5", {"cloud": Q_(3.0, "percent")}, True),   # 5 %, not 500 %
    ("cloud < 5", {"cloud": Q_(6.0, "percent")}, False),
    ("h + 10 > 100", {"h": Q_(95.0, "m")}, True),
    ("2 * tol > 1", {"tol": Q_(0.6, "m")}, True),
])
def test_bare_numbers_take_the_unit_they_meet(src, names, expected):
    assert bool(parse(src).evaluate(names)) is expected


def test_bare_numbers_meet_arrays_per_item():
    out = parse("roll > 1").evaluate({"roll": Q_(np.array([0.5, 2.5]), "degree")})
    assert out.tolist() == [False, True]


# --------------------------------------------------------------------------- limits (issue 17)


@pytest.mark.parametrize("src, message", [
    ("9**9**9 > 1", "exponent of \\*\\* must be a number or a name"),
    ("10**10**10", "exponent of \\*\\* must be a number or a name"),
    ("2**1000000 > 1", "exponent 1000000 is larger than 64"),
    ("'a' * 10**10 == 'a'", "string repetition"),
    ("10 * 'a'", "string repetition"),
    ("'%s' % x", "string repetition and formatting"),
    ("max(" + ", ".join(["1"] * 240) + ") > 0", "longer than 500 characters"),
    ("max(" + ",".join(["x"] * 20) + ") > 0", "20 arguments: at most 16"),
    ("1" + "0" * 30 + " > x", "integer 1000000000+ is larger than 1e\\+18"),
    ("-" * 40 + "x", "nested more than 32 levels"),
])
def test_resource_limits_refused_when_parsed(src, message):
    import time

    t0 = time.perf_counter()
    with pytest.raises(ExpressionError, match=message):
        parse(src)
    assert time.perf_counter() - t0 < 0.5


@pytest.mark.parametrize("src, names, message", [
    ("x ** n", {"x": 2, "n": 1000000}, "exponent larger than 64"),
    ("s * n", {"s": "a", "n": 10**10}, "string repetition"),
    ("x * x * x * x * x", {"x": 10**60}, "integer result larger than 256 bits"),
])
def test_resource_limits_checked_before_evaluating(src, names, message):
    with pytest.raises(ExpressionError, match=message):
        parse(src).evaluate(names)


def test_limits_leave_real_expressions_alone():
    assert parse("abs(a) ** 2").evaluate({"a": -3.0}) == 9.0
    assert parse("x ** -2").evaluate({"x": 2.0}) == 0.25
    assert parse("min(required_checkpoints, max_required_checkpoints)").evaluate(
        {"required_checkpoints": 20, "max_required_checkpoints": 120}) == 20
    assert parse("2 ** 64 > x").evaluate({"x": 1}) is True
