"""The spatial findings of a check as GIS layers (issue 30): one concept, three readers.

:func:`build_layers` turns what was judged (the QCR document: its records and the measured values
in ``details``, never a recomputation) plus the delivery's geometries (:func:`read_geometry`: image
footprints from the raster headers, kept in ``details.footprints`` by :func:`with_footprints` so
the report re-renders from qcr.json alone; seamline polygons) into layers in the delivery's CRS. The
GeoPackage (:func:`to_gpkg`, ``check --format gpkg``), the interactive HTML map and the report's
static map (``reports/interactive.py``) all draw these layers, so they never disagree.
"""

from __future__ import annotations

from .geometry import DeliveryGeometry, read_geometry, with_footprints
from .gpkg import to_gpkg
from .layers import LAYER_NAMES, FindingsLayers, Layer, build_layers

__all__ = [
    "LAYER_NAMES",
    "DeliveryGeometry",
    "FindingsLayers",
    "Layer",
    "build_layers",
    "read_geometry",
    "to_gpkg",
    "with_footprints",
]
