"""Units for every parameter, measure and threshold (pint).

A value in µm never meets a threshold in mm by accident: comparisons convert
through pint or raise :class:`UnitError`. Pixels (``px``) are their own
dimension; they convert to lengths only through an item's GSD (see
:func:`convert`).
"""

from __future__ import annotations

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
