"""Units for every parameter, measure and threshold (pint).

A value in µm never meets a threshold in mm by accident: comparisons convert
through pint or raise :class:`UnitError`. Pixels (``px``) are their own
dimension; they convert to lengths only through an item's GSD (see
:func:`convert`).
"""

from __future__ import annotations

import math
import re
import threading
from functools import lru_cache
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from .errors import UnitError

if TYPE_CHECKING:
    import pint


_REGISTRY: list[pint.UnitRegistry] = []
_BUILDING = threading.Lock()


def _reg() -> pint.UnitRegistry:
    """pint's registry, built once on first use (importing pint and building it costs ~0.4 s,
    which commands that only read a profile, such as `explain`, should not pay).

    Locked: `check` builds it in a thread while the tables parse, and two threads must never
    build two registries (pint refuses to compare quantities of different registries)."""
    if not _REGISTRY:
        with _BUILDING:
            if not _REGISTRY:
                import pint

                ureg: pint.UnitRegistry = pint.UnitRegistry(
                    autoconvert_offset_to_baseunit=True, cache_folder=None
                )
                ureg.define("grey_level = [grey_level] = DN = dn = GL")
                ureg.define("US_survey_foot = 1200 / 3937 * meter = ftUS = us_ft")
                ureg.define("fraction = [] = frac")
                _REGISTRY.append(ureg)
    return _REGISTRY[0]


def __getattr__(name: str) -> Any:
    """``units.ureg`` and ``units.Q_`` as before, created lazily (PEP 562)."""
    if name == "ureg":
        return _reg()
    if name == "Q_":
        return _reg().Quantity
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _pint_errors() -> Any:
    import pint

    return pint.errors


#: Names accepted in profiles and deliveries, mapped to pint spellings.
ALIASES = {
    "%": "percent",
    "pct": "percent",
    "percent": "percent",
    "µm": "micrometer",
    "μm": "micrometer",
    "um": "micrometer",
    "deg": "degree",
    "°": "degree",
    "degrees": "degree",
    "px": "pixel",
    "pixels": "pixel",
    "ft": "foot",
    "usft": "US_survey_foot",
    "us-ft": "US_survey_foot",
    "1": "dimensionless",
    "": "dimensionless",
    "count": "dimensionless",
    "ratio": "dimensionless",
}

#: Units that are not physical quantities: text, booleans and dates are compared as such.
NON_NUMERIC = {"text", "bool", "date"}


@lru_cache(maxsize=512)
def parse_unit(name: str | None) -> pint.Unit:
    """Parse a unit name as written in a profile or a table; raise UnitError if unknown."""
    key = "" if name is None else str(name).strip()
    if key in NON_NUMERIC:
        raise UnitError(f"unit {key!r} is not numeric")
    spelled = ALIASES.get(key, key)
    try:
        return _reg().Unit(spelled)
    except (
        _pint_errors().UndefinedUnitError,
        _pint_errors().DefinitionSyntaxError,
        AttributeError,
        TypeError,
        ValueError,
    ) as exc:
        raise UnitError(
            f"unknown unit {name!r}; use e.g. m, mm, µm, ft, usft, px, %, deg, DN or 1"
        ) from exc


def canonical(name: str | None) -> str:
    """The canonical short spelling of a unit, for output (``m``, ``µm``, ``%``, ``px``...)."""
    key = "" if name is None else str(name).strip()
    if key in NON_NUMERIC:
        return key
    unit = parse_unit(key)
    if unit == _reg().dimensionless:
        return "1"
    text = f"{unit:~P}"
    return {"pixel": "px", "°": "deg", "ftUS": "usft"}.get(text, text)


def convert(
    values: Any,
    from_unit: str | None,
    to_unit: str | None,
    *,
    gsd_m: Any = None,
    what: str = "value",
) -> np.ndarray:
    """Convert magnitudes between units; px <-> length goes through ``gsd_m`` (m per px).

    Raises UnitError naming ``what`` when the units cannot meet.
    """
    arr = np.asarray(values, dtype=float)
    src, dst = parse_unit(from_unit), parse_unit(to_unit)
    if src == dst:
        return arr
    px = _reg().pixel.dimensionality
    length = _reg().meter.dimensionality
    if src.dimensionality == px and dst.dimensionality == length:
        if gsd_m is None:
            raise UnitError(f"{what}: cannot convert px to {to_unit} without the item's GSD")
        return (_reg().Quantity(arr * np.asarray(gsd_m, dtype=float), "meter")).to(dst).magnitude
    if src.dimensionality == length and dst.dimensionality == px:
        if gsd_m is None:
            raise UnitError(f"{what}: cannot convert {from_unit} to px without the item's GSD")
        metres = _reg().Quantity(arr, src).to("meter").magnitude
        return metres / np.asarray(gsd_m, dtype=float)
    try:
        return _reg().Quantity(arr, src).to(dst).magnitude
    except _pint_errors().DimensionalityError as exc:
        raise UnitError(
            f"{what}: {canonical(from_unit)!r} cannot be compared with {canonical(to_unit)!r}"
        ) from exc


# --- threshold numbers ------------------------------------------------------------------------
# One parser for every number a person types as a threshold (profile `value`/`default`, requirement
# literals, --param). Nothing here hands free text to pint's parser: pint reads "1,0" as 10 and
# "0,5" as 0 (the comma is taken as a separator), which silently changes a contract.

_NUM = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"
_NUMBER_RE = re.compile(rf"\s*({_NUM})\s*")
_WITH_UNIT_RE = re.compile(rf"\s*({_NUM})\s*([^\d\s.+-][^\s]*(?:\s+[^\s]+)*)?\s*")
_DECIMAL_COMMA_RE = re.compile(r"\s*[+-]?\d*,\d+(?:\s*\S.*)?")


class NumberError(UnitError):
    """A threshold that is not a plain, finite number (decimal comma, quoted, words, inf/nan)."""


def _comma_hint(text: str) -> str:
    fixed = text.strip().replace(",", ".", 1)
    return f"{text!r} has a decimal comma: write {fixed} (a point is the decimal separator)"


def number_problem(raw: Any) -> str | None:
    """Why a value written in a profile is not a threshold number, or None when it is one.

    A profile literal must be a YAML number: ``1.0``. A quoted ``"1.0"``, a decimal comma ``1,0``
    (YAML reads it as the text "1,0"), words, booleans and non-finite values are refused.
    """
    if isinstance(raw, bool):
        return f"expected a number, got {str(raw).lower()}"
    if isinstance(raw, int):
        return None
    if isinstance(raw, float):
        return None if math.isfinite(raw) else f"{raw!r} is not a finite number"
    if isinstance(raw, str):
        if _DECIMAL_COMMA_RE.fullmatch(raw):
            return _comma_hint(raw)
        m = _NUMBER_RE.fullmatch(raw)
        if m:
            if not math.isfinite(float(m.group(1))):
                return f"{raw!r} is not a finite number"
            return f"{raw!r} is a quoted number: write {m.group(1)} without quotes"
        return f"{raw!r} is not a number: write a number such as 1.0"
    return f"expected a number, got {type(raw).__name__}"


def parse_number_text(text: str, unit: str | None) -> float:
    """A number typed on the command line (``0.5``, ``0.5m``, ``50 cm``) in ``unit``'s magnitude.

    A bare number is taken in ``unit``; a number with a unit is converted to ``unit`` (lengths to
    lengths; px to a length needs a GSD, so it is refused here). Raises NumberError with a hint.
    """
    raw = str(text)
    if _DECIMAL_COMMA_RE.fullmatch(raw):
        raise NumberError(_comma_hint(raw))
    m = _WITH_UNIT_RE.fullmatch(raw)
    if not m:
        raise NumberError(
            f"{raw!r} is not a number: write e.g. 0.5"
            + (f" or 0.5 {canonical(unit)}" if unit and unit not in NON_NUMERIC else "")
        )
    value = float(m.group(1))
    if not math.isfinite(value):
        raise NumberError(f"{raw!r} is not a finite number")
    written = m.group(2)
    if not written:
        return value
    src = parse_unit(written)
    dst = parse_unit(unit)
    if src == dst:
        return value
    try:
        out = float(_reg().Quantity(value, src).to(dst).magnitude)
    except _pint_errors().DimensionalityError:
        raise NumberError(
            f"{raw!r} is in {canonical(written)}, which does not convert to {canonical(unit)}"
        ) from None
    if not math.isfinite(out):
        raise NumberError(f"{raw!r} is not a finite number in {canonical(unit)}")
    return out


def dimension_of(unit: str | None) -> Any:
    """The pint dimensionality of a unit name (raises UnitError for an unknown one)."""
    return parse_unit(unit).dimensionality


# --- dimensions without pint (profile validation) -----------------------------------------------
# Validating a profile needs only the dimension of each unit, and of an expression over parameters.
# Loading pint costs most of a cold `spec validate`, so the spellings profiles use are described
# here (tests/test_units.py checks every entry against pint) and any other spelling goes to pint.

Dims = tuple[tuple[str, int], ...]
_LEN: Dims = (("[length]", 1),)
_NONE: Dims = ()
#: spelling -> (dimensions, pure): pure is the plain number unit ("1"); % and deg are scaled.
STATIC_UNITS: dict[str, tuple[Dims, bool]] = {
    **{
        u: (_LEN, False)
        for u in (
            "m",
            "meter",
            "metre",
            "mm",
            "cm",
            "km",
            "µm",
            "μm",
            "um",
            "micrometer",
            "ft",
            "foot",
            "usft",
            "us-ft",
            "ftUS",
            "us_ft",
            "US_survey_foot",
        )
    },
    **{u: ((("[printing_unit]", 1),), False) for u in ("px", "pixel", "pixels")},
    **{u: (_NONE, True) for u in ("1", "", "count", "ratio", "dimensionless")},
    **{
        u: (_NONE, False)
        for u in ("%", "pct", "percent", "deg", "degree", "degrees", "°", "rad", "radian")
    },
    **{u: ((("[grey_level]", 1),), False) for u in ("DN", "dn", "GL", "grey_level")},
    **{
        u: ((("[time]", 1),), False)
        for u in ("s", "second", "min", "minute", "h", "hour", "day", "year")
    },
}


def unit_signature(name: str | None) -> tuple[Dims, bool]:
    """(dimensions, pure) of a unit name; pint only for spellings not in STATIC_UNITS."""
    key = "" if name is None else str(name).strip()
    hit = STATIC_UNITS.get(key)
    if hit is not None:
        return hit
    unit = parse_unit(key)
    # pint types an exponent as any scalar, complex included; a unit's exponents are real numbers
    dims = tuple(
        sorted((str(k), int(cast(float, v))) for k, v in dict(unit.dimensionality).items() if v)
    )
    return dims, unit == _reg().dimensionless


def check_unit(name: str | None) -> None:
    """Raise UnitError for a unit name nobody knows (cheap for the usual spellings)."""
    unit_signature(name)


def same_value(a: Any, b: Any) -> bool:
    """Two values of one parameter, in one unit, are the same contract value: numbers to 1e-9
    relative (50 cm read as 0.5 m), booleans by identity, anything else as text."""
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=0.0)
    return str(a) == str(b)


# --- the spellings a profile may write -------------------------------------------------------------
# A profile is a contract: one spelling per unit, so the annex, `spec diff` and the QCR print what
# the author wrote and a threshold is never a formula because `meters` is not `m`. pint reads far
# more (`M` is molar, `metres` works), which is right for delivery tables and --param and wrong for
# a contract document. Deliveries and the checker's file keep pint's reading (parse_unit).

#: every unit a profile's parameters, requirements, classes and lookup tables may name
PROFILE_UNITS: tuple[str, ...] = (
    "m",
    "cm",
    "mm",
    "µm",
    "um",
    "km",
    "ft",
    "usft",
    "px",
    "%",
    "deg",
    "DN",
    "s",
    "h",
    "day",
    "year",
    "1",
)
#: common other spellings -> the profile spelling (checked before any fuzzy match)
_PROFILE_SPELLING = {
    "meter": "m",
    "meters": "m",
    "metre": "m",
    "metres": "m",
    "M": "m",
    "mtr": "m",
    "millimeter": "mm",
    "millimeters": "mm",
    "millimetre": "mm",
    "millimetres": "mm",
    "MM": "mm",
    "centimeter": "cm",
    "centimeters": "cm",
    "centimetre": "cm",
    "centimetres": "cm",
    "kilometer": "km",
    "kilometers": "km",
    "kilometre": "km",
    "kilometres": "km",
    "KM": "km",
    "Km": "km",
    "micrometer": "µm",
    "micrometers": "µm",
    "micrometre": "µm",
    "micrometres": "µm",
    "μm": "µm",
    "micron": "µm",
    "microns": "µm",
    "foot": "ft",
    "feet": "ft",
    "us-ft": "usft",
    "ftUS": "usft",
    "us_ft": "usft",
    "US_survey_foot": "usft",
    "pixel": "px",
    "pixels": "px",
    "pix": "px",
    "percent": "%",
    "pct": "%",
    "per cent": "%",
    "percentage": "%",
    "degree": "deg",
    "degrees": "deg",
    "°": "deg",
    "dn": "DN",
    "GL": "DN",
    "grey_level": "DN",
    "digital number": "DN",
    "second": "s",
    "seconds": "s",
    "sec": "s",
    "hour": "h",
    "hours": "h",
    "days": "day",
    "years": "year",
    "yr": "year",
    "": "1",
    "count": "1",
    "ratio": "1",
    "dimensionless": "1",
    "number": "1",
    "string": "text",
    "str": "text",
    "boolean": "bool",
    "logical": "bool",
}


def profile_unit_problem(name: Any) -> str | None:
    """Why ``name`` is not a unit a profile may write (None when it is), with the spelling to use.

    One message per mistake: ``unit 'metres': write 'm' (a profile spells units m, mm, ...)``.
    """
    if name is None:
        return None
    if not isinstance(name, str):
        return f"unit {name!r} must be text such as 'm' or '1' (quote '1' and '%')"
    key = name.strip()
    if key in PROFILE_UNITS or key in NON_NUMERIC:
        return None
    allowed = ", ".join(PROFILE_UNITS) + " (numbers); text, bool, date"
    fix = _PROFILE_SPELLING.get(key) or _PROFILE_SPELLING.get(key.lower())
    if fix is None:
        lower = {u.lower(): u for u in (*PROFILE_UNITS, *NON_NUMERIC)}
        fix = lower.get(key.lower())
    if fix is None:
        import difflib

        near = difflib.get_close_matches(key, [*PROFILE_UNITS, *NON_NUMERIC], n=1, cutoff=0.7)
        fix = near[0] if near else None
    if fix is not None:
        return f"unit {name!r}: write {fix!r} (a profile spells its units {allowed})"
    return f"unknown unit {name!r}: a profile spells its units {allowed}"


def _dims_meet(a: Dims, b: Dims) -> bool:
    if a == b:
        return True
    pair = {a, b}
    return pair == {(("[printing_unit]", 1),), _LEN}


def _combine(a: Dims, b: Dims, sign: int) -> Dims:
    out: dict[str, int] = dict(a)
    for k, v in b:
        out[k] = out.get(k, 0) + sign * v
    return tuple(sorted((k, v) for k, v in out.items() if v))


class ProbeUnits:
    """The units of a :class:`UnitProbe`: dimensions and whether it is the plain number unit."""

    __slots__ = ("dims", "pure")

    def __init__(self, dims: Dims, pure: bool) -> None:
        self.dims, self.pure = dims, pure

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ProbeUnits) and (self.dims, self.pure) == (other.dims, other.pure)

    def __hash__(self) -> int:
        return hash((self.dims, self.pure))

    def describe(self) -> str:
        if not self.dims:
            return "a plain number" if self.pure else "a dimensionless ratio (%, deg)"
        names = {"printing_unit": "pixel", "grey_level": "DN"}
        return " ".join(
            names.get(k.strip("[]"), k.strip("[]")) + (f"^{v}" if v != 1 else "")
            for k, v in self.dims
        )


class UnitProbe:
    """Stands for "one of this unit" in a safe expression, to learn the unit the expression yields.

    Supports what the expression grammar does (+ - * / % **, comparisons, min/max/abs); adding or
    comparing values of different dimensions raises UnitError, as pint would.
    """

    __slots__ = ("magnitude", "units")

    def __init__(self, magnitude: Any, units: ProbeUnits) -> None:
        self.magnitude, self.units = 1.0, units

    @classmethod
    def of(cls, unit: str | None) -> UnitProbe:
        dims, pure = unit_signature(unit)
        return cls(1.0, ProbeUnits(dims, pure))

    @staticmethod
    def _u(v: Any) -> ProbeUnits:
        return v.units if isinstance(v, UnitProbe) else ProbeUnits((), True)

    def _same(self, other: Any, op: str) -> ProbeUnits:
        a, b = self.units, self._u(other)
        if a.dims != b.dims and not _dims_meet(a.dims, b.dims):
            raise UnitError(f"cannot {op} {a.describe()} and {b.describe()}")
        return a

    def __add__(self, o: Any) -> UnitProbe:
        return UnitProbe(1.0, self._same(o, "add"))

    __radd__ = __add__
    __sub__ = __add__
    __rsub__ = __add__
    __mod__ = __add__

    def __mul__(self, o: Any) -> UnitProbe:
        b = self._u(o)
        return UnitProbe(
            1.0, ProbeUnits(_combine(self.units.dims, b.dims, 1), self.units.pure and b.pure)
        )

    __rmul__ = __mul__

    def __truediv__(self, o: Any) -> UnitProbe:
        b = self._u(o)
        return UnitProbe(
            1.0, ProbeUnits(_combine(self.units.dims, b.dims, -1), self.units.pure and b.pure)
        )

    def __rtruediv__(self, o: Any) -> UnitProbe:
        return UnitProbe(1.0, ProbeUnits(_combine((), self.units.dims, -1), self.units.pure))

    def __pow__(self, o: Any) -> UnitProbe:
        n = (
            int(o)
            if isinstance(o, int | float) and not isinstance(o, bool) and float(o).is_integer()
            else 1
        )
        return UnitProbe(
            1.0, ProbeUnits(tuple((k, v * n) for k, v in self.units.dims), self.units.pure)
        )

    def __neg__(self) -> UnitProbe:
        return self

    __pos__ = __neg__
    __abs__ = __neg__

    def _cmp(self, o: Any) -> bool:
        self._same(o, "compare")
        return True

    __lt__ = __le__ = __gt__ = __ge__ = _cmp

    def __eq__(self, o: object) -> bool:
        return self._cmp(o)

    def __ne__(self, o: object) -> bool:
        return self._cmp(o)

    __hash__ = None  # type: ignore[assignment]  # unhashable: typeshed types __hash__ as a method


def probe_meets(result: Any, unit: str | None) -> bool:
    """Whether an expression's probe result can be compared with a requirement in ``unit``.

    A plain number means "in the requirement's unit" (as the evaluator reads it); px meets lengths.
    """
    if not isinstance(result, UnitProbe):
        return True
    if not result.units.dims and result.units.pure:
        return True
    return _dims_meet(result.units.dims, unit_signature(unit)[0])
