"""Coordinate reference systems as the checker and the delivery name them (pyproj, never by hand).

The map projection a delivery must be in is the ITT's (JRC EUR 23638 EN §12.4, Table 12 "Ortho-image:
... georeferenced to the (national) map projection"), stated on the checker's side as a parameter
(``map_crs``); the manifest's ``project.crs`` is the contractor's declaration of the CRS its
coordinates are written in (red team R16). Both are read here, with pyproj, imported lazily: a
command that compares no CRS never loads it.
"""

from __future__ import annotations

from typing import Any


class CrsProblem(ValueError):
    """A CRS text pyproj cannot read, or one without the EPSG code the comparisons need."""


def read_crs(text: Any) -> Any:
    """The pyproj CRS a text names; CrsProblem saying why when there is none."""
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    if isinstance(text, bool) or not isinstance(text, str | int) or not str(text).strip():
        raise CrsProblem(
            f"expected a coordinate reference system such as 'EPSG:25832', got {text!r}"
        )
    try:
        return CRS.from_user_input(str(text).strip())
    except CRSError as exc:
        raise CrsProblem(
            f"{text!r} is not a coordinate reference system pyproj can read ({exc})"
        ) from None


def epsg_name(text: Any) -> str:
    """``EPSG:<code>`` of a CRS given as pyproj reads it (``epsg:25832``, ``urn:ogc:def:crs:EPSG::25832``,
    a PROJ string); CrsProblem when unreadable or when it has no EPSG code (the rasters' CRS is
    compared with an EPSG definition, raster/filechecks.py)."""
    crs = read_crs(text)
    code = crs.to_epsg()
    if code is None:
        raise CrsProblem(
            f"{text!r} ({crs.name}) has no EPSG code; name the map projection as EPSG:<code>"
        )
    return f"EPSG:{code}"


def same_crs(a: Any, b: Any) -> bool:
    """Both texts name the same CRS (axis order ignored, as GIS software does); CrsProblem when either
    cannot be read."""
    return bool(read_crs(a).equals(read_crs(b), ignore_axis_order=True))
