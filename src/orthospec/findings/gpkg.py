"""The findings layers as one GeoPackage (``check --format gpkg``), styled for QGIS.

Written with pyogrio into a private temporary folder and returned as bytes, so the caller's
all-or-none writer puts it in ``--out`` atomically (never into the delivery). The ``layer_styles``
table is QGIS's own (the one "Save style > in database" creates), one default style per layer,
coloured by verdict, so opening the file shows the result at once. Same document, geometry and
``--date`` give the same bytes (GDAL's timestamps are the QCR date).
"""

from __future__ import annotations

import sqlite3
import tempfile
from collections.abc import Mapping
from contextlib import closing
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import OrthospecError
from .layers import FindingsLayers, Layer, build_layers, visible
from .styles import qml, sld

__all__ = ["STYLE_COLUMNS", "to_gpkg", "write_gpkg"]

#: QGIS's layer_styles schema (QgsOgrProviderUtils / the GeoPackage provider's saveStyle)
STYLE_COLUMNS = (
    "f_table_catalog",
    "f_table_schema",
    "f_table_name",
    "f_geometry_column",
    "styleName",
    "styleQML",
    "styleSLD",
    "useAsDefault",
    "description",
    "owner",
    "ui",
    "update_time",
)
_STYLE_TABLE = (
    "CREATE TABLE layer_styles (id INTEGER PRIMARY KEY AUTOINCREMENT, f_table_catalog TEXT(256), "
    "f_table_schema TEXT(256), f_table_name TEXT(256), f_geometry_column TEXT(256), "
    "styleName TEXT(30), styleQML TEXT, styleSLD TEXT, useAsDefault BOOLEAN, description TEXT, "
    "owner TEXT(30), ui TEXT(30), update_time DATETIME DEFAULT CURRENT_TIMESTAMP)"
)
GEOMETRY_COLUMN = "geom"


def _columns(layer: Layer) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
    data: list[np.ndarray] = []
    masks: list[np.ndarray | None] = []
    for name, kind in layer.fields:
        vals = [props.get(name) for _, props in layer.features]
        if kind == "float":
            data.append(
                np.array([np.nan if v is None else float(v) for v in vals], dtype=np.float64)
            )
            masks.append(None)  # NaN is written as null
        elif kind == "int":
            data.append(np.array([0 if v is None else int(v) for v in vals], dtype=np.int64))
            masks.append(np.array([v is None for v in vals], dtype=bool))
        else:
            data.append(np.array([None if v is None else visible(v) for v in vals], dtype=object))
            masks.append(None)
    return data, masks


def _write_layer(path: Path, layer: Layer, crs: str | None, date: str) -> None:
    import pyogrio
    import shapely

    data, masks = _columns(layer)
    fields = [n for n, _ in layer.fields]
    opts: dict[str, Any] = {
        "driver": "GPKG",
        "layer": layer.name,
        "append": path.exists(),
        "layer_options": {"DESCRIPTION": layer.description} if layer.description else None,
        "layer_metadata": layer.metadata or None,
    }
    if any(m is not None for m in masks):
        opts["field_mask"] = [
            np.zeros(len(layer.features), dtype=bool) if m is None else m for m in masks
        ]
    if layer.geometry_type is None:
        geom = None
    else:
        geom = np.array(
            [
                None if g is None else shapely.to_wkb(g, output_dimension=2)
                for g, _ in layer.features
            ],
            dtype=object,
        )
        opts.update(
            geometry_type=layer.geometry_type,
            crs=crs,
            layer_options={**(opts["layer_options"] or {}), "GEOMETRY_NAME": GEOMETRY_COLUMN},
        )
    with _config({"OGR_CURRENT_DATE": f"{date}T00:00:00.000Z"}):
        pyogrio.raw.write(str(path), geom, data, fields, **opts)


class _config:
    """GDAL configuration options for the block, restored after (the process is shared)."""

    def __init__(self, options: Mapping[str, str]) -> None:
        self.options = dict(options)

    def __enter__(self) -> None:
        import pyogrio

        self.before = {k: pyogrio.get_gdal_config_option(k) for k in self.options}
        pyogrio.set_gdal_config_options(self.options)

    def __exit__(self, *exc: object) -> None:
        import pyogrio

        pyogrio.set_gdal_config_options(self.before)


def _styles(path: Path, layers: FindingsLayers, date: str) -> None:
    stamp = f"{date}T00:00:00Z"
    with closing(sqlite3.connect(path)) as con, con:
        con.execute(_STYLE_TABLE)
        con.execute(
            "INSERT INTO gpkg_contents (table_name, data_type, identifier, description, last_change) "
            "VALUES ('layer_styles', 'attributes', 'layer_styles', 'QGIS layer styles', ?)",
            (stamp,),
        )
        for lay in layers.layers.values():
            if lay.geometry_type is None:
                continue
            con.execute(
                f"INSERT INTO layer_styles ({', '.join(STYLE_COLUMNS)}) VALUES "
                f"({', '.join('?' * len(STYLE_COLUMNS))})",
                (
                    "",
                    "",
                    lay.name,
                    GEOMETRY_COLUMN,
                    f"{lay.name} by verdict",
                    qml(lay),
                    sld(lay),
                    1,
                    f"orthospec: {lay.name} coloured by verdict",
                    "",
                    None,
                    stamp,
                ),
            )


def write_gpkg(layers: FindingsLayers, path: str | Path, *, date: str) -> None:
    """Write every layer and the styles table to a new file ``path`` (which must not exist)."""
    path = Path(path)
    for lay in layers.layers.values():
        _write_layer(path, lay, layers.crs, date)
    _styles(path, layers, date)


def to_gpkg(doc: Mapping[str, Any], geometry: Any = None) -> bytes:
    """The GeoPackage of ``doc``'s findings as bytes (``findings.gpkg`` in ``--out``)."""
    layers = build_layers(doc, geometry)
    with tempfile.TemporaryDirectory(prefix="orthospec-gpkg-") as tmp:
        path = Path(tmp) / "findings.gpkg"
        try:
            write_gpkg(layers, path, date=str(doc.get("date") or "1970-01-01"))
        except (
            OSError,
            RuntimeError,
            ValueError,
            sqlite3.Error,
        ) as exc:  # GDAL / sqlite: name the output
            raise OrthospecError(f"cannot write findings.gpkg: {exc}") from exc
        return path.read_bytes()
