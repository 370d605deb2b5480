"""Units for every parameter, measure and threshold (pint).

A value in µm never meets a threshold in mm by accident: comparisons convert
through pint or raise :class:`UnitError`. Pixels (``px``) are their own
dimension; they convert to lengths only through an item's GSD (see
:func:`convert`).
"""

from __future__ import annotations

import math
import re
from functools import lru_cache
from typing import Any

import numpy as np
import pint

from .errors import UnitError

ureg = pint.UnitRegistry(autoconvert_offset_to_baseunit=True, cache_folder=None)
ureg.define("grey_level = [grey_level] = DN = dn = GL")
ureg.define("US_survey_foot = 1200 / 3937 * meter = ftUS = us_ft")
ureg.define("fraction = [] = frac")
Q_ = ureg.Quantity

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
        return ureg.Unit(spelled)
    except (pint.errors.UndefinedUnitError, pint.errors.DefinitionSyntaxError, AttributeError,
            TypeError, ValueError) as exc:
        raise UnitError(
            f"unknown unit {name!r}; use e.g. m, mm, µm, ft, usft, px, %, deg, DN or 1"
        ) from exc


def canonical(name: str | None) -> str:
    """The canonical short spelling of a unit, for output (``m``, ``µm``, ``%``, ``px``...)."""
    key = "" if name is None else str(name).strip()
    if key in NON_NUMERIC:
        return key
    unit = parse_unit(key)
    if unit == ureg.dimensionless:
        return "1"
    text = f"{unit:~P}"
    return {"pixel": "px", "°": "deg", "ftUS": "usft"}.get(text, text)


def is_pixel(unit: str | None) -> bool:
    return (unit or "").strip() not in NON_NUMERIC and parse_unit(unit).dimensionality == ureg.pixel.dimensionality


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
    px = ureg.pixel.dimensionality
    length = ureg.meter.dimensionality
    if src.dimensionality == px and dst.dimensionality == length:
        if gsd_m is None:
            raise UnitError(f"{what}: cannot convert px to {to_unit} without the item's GSD")
        return (Q_(arr * np.asarray(gsd_m, dtype=float), "meter")).to(dst).magnitude
    if src.dimensionality == length and dst.dimensionality == px:
        if gsd_m is None:
            raise UnitError(f"{what}: cannot convert {from_unit} to px without the item's GSD")
        metres = Q_(arr, src).to("meter").magnitude
        return metres / np.asarray(gsd_m, dtype=float)
    try:
        return Q_(arr, src).to(dst).magnitude
    except pint.errors.DimensionalityError as exc:
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
        raise NumberError(f"{raw!r} is not a number: write e.g. 0.5"
                          + (f" or 0.5 {canonical(unit)}" if unit and unit not in NON_NUMERIC else ""))
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
        out = float(Q_(value, src).to(dst).magnitude)
    except pint.errors.DimensionalityError:
        raise NumberError(f"{raw!r} is in {canonical(written)}, which does not convert to "
                          f"{canonical(unit)}") from None
    if not math.isfinite(out):
        raise NumberError(f"{raw!r} is not a finite number in {canonical(unit)}")
    return out


def dimension_of(unit: str | None) -> Any:
    """The pint dimensionality of a unit name (raises UnitError for an unknown one)."""
    return parse_unit(unit).dimensionality


def units_meet(a: str | None, b: str | None) -> bool:
    """Whether values in ``a`` can be compared with a requirement in ``b`` (px meets lengths via GSD)."""
    da, db = dimension_of(a), dimension_of(b)
    if da == db:
        return True
    px, length = ureg.pixel.dimensionality, ureg.meter.dimensionality
    return (da == px and db == length) or (da == length and db == px)
