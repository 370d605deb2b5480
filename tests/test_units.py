import numpy as np
import pytest

from orthospec.errors import UnitError
from orthospec.units import canonical, convert, parse_unit


@pytest.mark.parametrize("value, src, dst, expected", [
    (1500.0, "µm", "mm", 1.5),
    (1500.0, "um", "m", 0.0015),
    (1.0, "ft", "m", 0.3048),
    (1.0, "usft", "m", 1200 / 3937),
    (50.0, "%", "1", 0.5),
    (180.0, "deg", "radian", np.pi),
    (2.0, "px", "m", 0.5),  # with gsd 0.25 m
    (0.5, "m", "px", 2.0),
])
def test_convert(value, src, dst, expected):
    got = convert([value], src, dst, gsd_m=0.25)
    assert got[0] == pytest.approx(expected)


def test_micrometre_never_meets_millimetre_by_accident():
    # 5 µm is 0.005 mm: a naive comparison of magnitudes would call 5 > 1 mm
    assert convert([5.0], "µm", "mm")[0] == pytest.approx(0.005)


@pytest.mark.parametrize("src, dst", [("m", "%"), ("deg", "m"), ("DN", "m"), ("px", "%")])
def test_incompatible_units_fail_loudly(src, dst):
    with pytest.raises(UnitError):
        convert([1.0], src, dst, gsd_m=0.25)


def test_px_needs_a_gsd():
    with pytest.raises(UnitError, match="GSD"):
        convert([1.0], "px", "m")


def test_unknown_unit():
    with pytest.raises(UnitError, match="unknown unit 'furlongz'"):
        parse_unit("furlongz")


@pytest.mark.parametrize("name, shown", [("µm", "µm"), ("um", "µm"), ("%", "%"), ("px", "px"),
                                         ("deg", "deg"), ("m", "m"), ("1", "1"), ("usft", "usft")])
def test_canonical_spelling(name, shown):
    assert canonical(name) == shown
