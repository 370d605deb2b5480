"""Trigonometry with units in the profile expression grammar (issue 26: JRC Figure 2, dx = dh x tan θ).

Expected values are computed independently (math, exact angles) or taken from the seed's worked
relation, never from the grammar's own output.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from orthospec.errors import ExpressionError
from orthospec.profile.expr import parse
from orthospec.units import Q_


@pytest.mark.parametrize(
    ("src", "angle", "expected"),
    [
        ("sin(a)", Q_(30.0, "degree"), 0.5),
        ("cos(a)", Q_(60.0, "degree"), 0.5),
        ("tan(a)", Q_(45.0, "degree"), 1.0),
        ("tan(a)", Q_(math.pi / 4, "radian"), 1.0),
        ("sin(a)", Q_(math.pi / 2, "radian"), 1.0),
        ("cos(a)", Q_(0.0, "degree"), 1.0),
    ],
)
def test_exact_angles(src: str, angle: object, expected: float) -> None:
    assert float(parse(src).evaluate({"a": angle})) == pytest.approx(expected, abs=1e-12)


def test_figure_2_displacement_from_dem_error_and_off_nadir_angle() -> None:
    """JRC §9.2 Figure 2: a DEM error dh displaces the orthoimage by dx = dh x tan(θ).
    1.5 m at 17° off nadir: 1.5 x tan(17°) = 0.4586 m (math.tan, independent of pint)."""
    got = parse("dh * tan(theta)").evaluate({"dh": Q_(1.5, "m"), "theta": Q_(17.0, "degree")})
    assert got.to("m").magnitude == pytest.approx(1.5 * math.tan(math.radians(17.0)), rel=1e-12)
    assert got.to("m").magnitude == pytest.approx(0.4586, abs=5e-5)


def test_atan_gives_degrees_the_largest_angle_a_dem_allows() -> None:
    """The inverse: the largest off-nadir angle for dx <= tolerance/3 with dh = 1.5 m and a 1 m
    tolerance is atan(0.3333 / 1.5) = 12.53°."""
    got = parse("atan(tolerance / 3 / dh)").evaluate(
        {"tolerance": Q_(1.0, "m"), "dh": Q_(150.0, "cm")}
    )
    assert str(got.units) == "degree"
    assert got.magnitude == pytest.approx(math.degrees(math.atan((1 / 3) / 1.5)), rel=1e-12)


def test_atan2_of_two_lengths_in_different_units() -> None:
    got = parse("atan2(a, b)").evaluate({"a": Q_(-1.0, "m"), "b": Q_(-100.0, "cm")})
    assert got.to("degree").magnitude == pytest.approx(-135.0)


def test_vectorised_over_a_column() -> None:
    out = parse("dh * tan(theta)").evaluate(
        {
            "dh": Q_(np.array([1.0, 2.0, 3.0]), "m"),
            "theta": Q_(np.array([0.0, 45.0, 60.0]), "degree"),
        }
    )
    assert out.to("m").magnitude == pytest.approx([0.0, 2.0, 3.0 * math.sqrt(3.0)])


@pytest.mark.parametrize(
    ("src", "names", "match"),
    [
        ("tan(17)", {}, "needs an angle with its unit"),
        ("sin(a)", {"a": Q_(3.0, "m")}, "needs an angle"),
        ("cos(a)", {"a": True}, "needs an angle with its unit"),
        ("atan(a)", {"a": Q_(1.0, "m")}, "expected a pure number"),
        (
            "atan2(a, b)",
            {"a": Q_(1.0, "m"), "b": Q_(1.0, "degree")},
            "both must have one dimension",
        ),
        ("tan(a)", {"a": None}, "not given"),
    ],
)
def test_what_is_not_an_angle_is_refused(src: str, names: dict[str, object], match: str) -> None:
    with pytest.raises(ExpressionError, match=match):
        parse(src).evaluate(names)


@pytest.mark.parametrize(
    "src", ["tan(a, b)", "sin()", "atan2(a)", "atan2(a, b, c)", "exp(a)", "tan(a=1)"]
)
def test_arity_and_unknown_functions_are_refused_at_parse(src: str) -> None:
    with pytest.raises(ExpressionError):
        parse(src)


@given(st.floats(-89.0, 89.0))
def test_atan_inverts_tan_in_degrees(deg: float) -> None:
    names = {"a": Q_(deg, "degree")}
    assert float(parse("atan(tan(a))").evaluate(names).magnitude) == pytest.approx(deg, abs=1e-9)
    assert float(parse("sin(a) ** 2 + cos(a) ** 2").evaluate(names)) == pytest.approx(
        1.0, abs=1e-12
    )
