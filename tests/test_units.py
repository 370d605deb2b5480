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


def test_static_unit_dimensions_agree_with_pint():
    """Profile validation reads dimensions from STATIC_UNITS without loading pint: each entry must be
    what pint itself says (independent source: pint's unit definitions)."""
    from orthospec.units import STATIC_UNITS, ureg

    for name, (dims, pure) in STATIC_UNITS.items():
        unit = parse_unit(name)
        assert dict(dims) == {str(k): int(v) for k, v in dict(unit.dimensionality).items() if v}, (
            name
        )
        assert pure == (unit == ureg.dimensionless), name


def test_unit_probe_finds_the_unit_an_expression_yields():
    from orthospec.profile import expr
    from orthospec.units import UnitProbe, probe_meets

    def yields(text, **units):
        return expr.parse(text).evaluate({k: UnitProbe.of(u) for k, u in units.items()})

    assert probe_meets(yields("tol / factor", tol="m", factor="1"), "m")
    assert probe_meets(yields("2 * tol", tol="px"), "m")  # px meets lengths through the GSD
    assert not probe_meets(yields("tol", tol="%"), "m")
    assert probe_meets(
        yields("factor", factor="1"), "m"
    )  # a plain number is read in the rule's unit
    with pytest.raises(Exception, match="cannot add"):
        yields("a + b", a="m", b="%")


def test_importing_units_does_not_load_pint():
    import subprocess
    import sys

    code = "import sys, orthospec.units as u; u.check_unit('µm'); print('pint' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "False"


def test_one_registry_when_threads_race_to_build_it():
    """`check` builds pint's registry in a thread while the main thread parses tables (and may
    need a unit): every thread gets the same registry, and units from both compare (pint refuses
    quantities of two registries)."""
    import subprocess
    import sys

    code = (
        "import threading\n"
        "from orthospec import units\n"
        "got = []\n"
        "start = threading.Barrier(8)\n"
        "def use():\n"
        "    start.wait()\n"
        "    got.append((units.ureg, units.parse_unit('m')))\n"
        "threads = [threading.Thread(target=use) for _ in range(8)]\n"
        "[t.start() for t in threads]\n"
        "[t.join() for t in threads]\n"
        "assert len({id(r) for r, _ in got}) == 1, 'two registries'\n"
        "assert all(u == got[0][1] for _, u in got)\n"
        "print(units.convert([1.0], 'cm', 'm')[0])\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert float(run.stdout) == 0.01
