"""Where each delivered image lies and how its mosaic seamlines are attributed, read from the files.

:func:`image_footprints` reads each listed image's bounds once (``raster_bounds``: the header only);
:func:`read_seamlines` reads a seamline layer with the image each polygon was taken from (JRC §11 "A
shapefile of the seamlines polygons and the information regarding with the input images").
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import OrthospecError
from .reading import gdal_errors, readable_vector
from .roi import Bounds, raster_bounds

if TYPE_CHECKING:
    from ..delivery.reader import Delivery

#: attribute names read as "the image this seamline polygon shows", first match wins (case-insensitive)
IMAGE_FIELDS = ("image_id", "image", "photo_id", "scene_id", "source_image")


def image_footprints(d: Delivery) -> dict[str, tuple[Bounds | None, str | None]]:
    """Image id -> ((left, bottom, right, top), None) of its delivered raster, or (None, why)."""
    out: dict[str, tuple[Bounds | None, str | None]] = {}
    imgs = d.table("images")
    if imgs is None or "file" not in imgs.df:
        return out
    for iid, rel, row in zip(
        imgs.ids.astype(str), imgs.df["file"].tolist(), imgs.df["_row"].tolist(), strict=True
    ):
        if rel is None:
            out[iid] = (None, f"{imgs.file} row {row} names no file")
            continue
        try:
            out[iid] = (
                raster_bounds(d.path(str(rel), file=imgs.file, row=int(row)), name=str(rel)),
                None,
            )
        except (OrthospecError, OSError) as exc:
            out[iid] = (None, f"{rel}: {exc}")
    return out


def read_seamlines(
    path: str | Path, *, name: str | None = None
) -> tuple[list[tuple[Any, str | None]], str | None]:
    """([(polygon, image id or None)], the attribute read) of a seamline layer (GeoPackage or shapefile)."""
    import pyogrio
    import shapely

    label = name or str(path)
    with (
        readable_vector(path, name=label) as (local, _driver),
        gdal_errors(file=label, path=local, what="vector file"),
    ):
        meta, _fids, geometry, fields = pyogrio.raw.read(local)
    names = [str(f) for f in meta.get("fields", [])]
    lower = {n.lower(): k for k, n in enumerate(names)}
    col = next((lower[f] for f in IMAGE_FIELDS if f in lower), None)
    geoms = [] if geometry is None else list(shapely.from_wkb(geometry))
    out = []
    for k, g in enumerate(geoms):
        if g is None:
            continue
        img = None
        if col is not None:
            v = fields[col][k]
            img = None if v is None or str(v).strip() == "" else str(v).strip()
        out.append((g, img))
    return out, (names[col] if col is not None else None)
