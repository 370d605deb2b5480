"""Tile index, seamline and block-outline layers of a source folder, matched to the images.

Read with pyogrio through the delivery's own vector guard (``raster.reading.readable_vector``:
GeoPackage by its application id, read from a private copy so a ``-wal`` is never replayed into
the source; shapefile in place), plus GeoJSON (read in place; the check does not read GeoJSON, so
such a layer is used for matching and listed, not declared in the draft's manifest).

A layer's features are matched to the images by a name attribute (the attribute whose values name
the most images, by file name or stem) or else by geometry (a footprint and a feature covering
each other to 90 % of their union); what matched nothing on either side is listed.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import MeasureError

#: a feature and a footprint are the same tile when they overlap by this share of their union
SAME_TILE_IOU = 0.9
BLOCK_WORDS = ("block", "blocks", "lot", "lots", "los", "site", "sites", "bloc", "blocs")
SEAM_WORDS = (
    "seam",
    "seamline",
    "seamlines",
    "cutline",
    "cutlines",
    "mosaic",
    "naht",
    "nahtlinien",
)
ID_FIELDS = (
    "id",
    "block",
    "block_id",
    "blockid",
    "name",
    "lot",
    "los",
    "site",
    "code",
    "nr",
    "label",
)


@dataclass
class Layer:
    """One vector file as read: its role, features matched to images, what did not match."""

    file: str
    role: str  # tiles | seamlines | blocks | other
    driver: str | None = None
    features: int = 0
    crs: str | None = None
    matched_by: str | None = None  # "attribute NAME" | "geometry"
    #: image name -> feature index
    matched: dict[str, int] = field(default_factory=dict)
    unmatched_features: list[str] = field(default_factory=list)
    images_without_feature: list[str] = field(default_factory=list)
    #: block id -> shapely polygon (role blocks)
    outlines: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def declarable(self) -> bool:
        """The check can read it (GeoPackage or shapefile)."""
        return self.error is None and self.driver in ("GPKG", "ESRI Shapefile")


def _words(name: str) -> set[str]:
    import re

    return set(re.findall(r"[a-z]+", name.lower()))


def role_of(rel: str) -> str | None:
    """blocks / seamlines from a file's name (the producer's own word for it); None: not said."""
    w = _words(Path(rel).stem)
    if w & set(BLOCK_WORDS):
        return "blocks"
    if w & set(SEAM_WORDS):
        return "seamlines"
    return None


def _read(path: Path, name: str) -> tuple[str, str | None, list[Any], dict[str, list[Any]]]:
    """(driver, CRS, shapely geometries, attribute columns) of a vector file."""
    import pyogrio
    import shapely

    from ..raster.reading import gdal_errors, readable_vector

    head = path.open("rb").read(1).lstrip()
    if path.suffix.lower() == ".geojson" or head == b"{":
        local, driver = str(path), "GeoJSON"
        with gdal_errors(file=name, path=local, what="vector file"):
            meta, _fids, geometry, fields = pyogrio.raw.read(local)
    else:
        with (
            readable_vector(path, name=name) as (local, driver),
            gdal_errors(file=name, path=local, what="vector file"),
        ):
            meta, _fids, geometry, fields = pyogrio.raw.read(local)
    geoms = [] if geometry is None else list(shapely.from_wkb(geometry))
    cols = {str(n): list(v) for n, v in zip(meta.get("fields", []), fields, strict=True)}
    return driver, meta.get("crs"), geoms, cols


def read_layer(
    path: Path,
    rel: str,
    *,
    images: dict[str, tuple[float, float, float, float]],
    image_crs: str | None,
    role: str | None = None,
) -> Layer:
    """Read one vector file and match it to the images (name -> footprint bounds in ``image_crs``)."""

    lay = Layer(rel, role or role_of(rel) or "other")
    try:
        lay.driver, lay.crs, geoms, cols = _read(path, rel)
    except (MeasureError, OSError) as exc:
        lay.error = str(exc)
        return lay
    lay.features = len(geoms)
    if lay.crs and image_crs:
        geoms = _to_crs(geoms, lay.crs, image_crs, lay)
    if lay.role == "blocks":
        _outlines(lay, geoms, cols)
        return lay
    if lay.role == "seamlines":
        _cover(lay, geoms, images)
        return lay
    _match(lay, geoms, cols, images)
    if lay.role == "other" and lay.matched and len(lay.matched) >= 0.5 * max(1, lay.features):
        lay.role = "tiles"
    return lay


def _to_crs(geoms: list[Any], src: str, dst: str, lay: Layer) -> list[Any]:
    import shapely
    from pyproj import CRS, Transformer
    from pyproj.exceptions import CRSError

    try:
        a, b = CRS.from_user_input(src), CRS.from_user_input(dst)
    except CRSError as exc:
        lay.notes.append(f"CRS not readable ({exc}): geometry not compared")
        return []
    if a.equals(b, ignore_axis_order=True):
        return geoms
    t = Transformer.from_crs(a, b, always_xy=True)
    lay.notes.append(f"reprojected from {a.name} to {b.name} for matching")
    return [None if g is None else shapely.transform(g, lambda xy: _xy(t, xy)) for g in geoms]


def _xy(t: Any, xy: Any) -> Any:
    import numpy as np

    x, y = t.transform(xy[:, 0], xy[:, 1])
    return np.column_stack([x, y])


def _names(images: dict[str, tuple[float, float, float, float]]) -> dict[str, str]:
    """Every way a tile index may name an image (file name, stem, lower case) -> image name."""
    out: dict[str, str] = {}
    for img in images:
        base = img.rsplit("/", 1)[-1]
        for key in (img, base, os.path.splitext(base)[0]):
            out.setdefault(key.lower(), img)
    return out


def _lookup(v: Any, names: dict[str, str]) -> str | None:
    """The image a text attribute names: as written, or its file name or stem (a gdaltindex
    ``location`` holds the path the index was made from, e.g. ``/data/lot3/T0.tif``)."""
    if not isinstance(v, str) or not v.strip():
        return None
    text = v.strip().lower()
    base = text.replace("\\", "/").rsplit("/", 1)[-1]
    for key in (text, base, os.path.splitext(base)[0]):
        if key in names:
            return names[key]
    return None


def _match(
    lay: Layer,
    geoms: list[Any],
    cols: dict[str, list[Any]],
    images: dict[str, tuple[float, float, float, float]],
) -> None:
    import shapely

    names = _names(images)
    best: tuple[int, str] | None = None
    for col, values in cols.items():
        hits = sum(1 for v in values if _lookup(v, names) is not None)
        if hits and (best is None or hits > best[0]):
            best = (hits, col)
    if best is not None:
        lay.matched_by = f"attribute {best[1]}"
        for i, v in enumerate(cols[best[1]]):
            img = _lookup(v, names)
            if img is not None and img not in lay.matched:
                lay.matched[img] = i
            else:
                lay.unmatched_features.append(f"#{i + 1} {best[1]}={v!r}")
    elif geoms and images:
        lay.matched_by = "geometry"
        boxes = {img: shapely.box(*b) for img, b in images.items()}
        tree = shapely.STRtree(list(boxes.values()))
        keys = list(boxes)
        for i, g in enumerate(geoms):
            if g is None or g.is_empty:
                lay.unmatched_features.append(f"#{i + 1} (empty geometry)")
                continue
            hit = None
            for j in tree.query(g, predicate="intersects"):
                box = boxes[keys[int(j)]]
                union = shapely.union(g, box).area
                if union > 0 and shapely.intersection(g, box).area / union >= SAME_TILE_IOU:
                    hit = keys[int(j)]
                    break
            if hit is not None and hit not in lay.matched:
                lay.matched[hit] = i
            else:
                lay.unmatched_features.append(f"#{i + 1} (no tile with the same footprint)")
    else:
        lay.unmatched_features = [f"#{i + 1}" for i in range(len(geoms))]
    lay.images_without_feature = sorted(set(images) - set(lay.matched))


def _cover(
    lay: Layer, geoms: list[Any], images: dict[str, tuple[float, float, float, float]]
) -> None:
    """Seamline polygons are cut along the source images, not the tiles: an image is matched when
    the polygons cover its footprint (to 99 %), else listed as not covered."""
    import shapely

    lay.matched_by = "coverage of the footprints"
    valid = [g for g in geoms if g is not None and not g.is_empty]
    if not valid:
        lay.images_without_feature = sorted(images)
        return
    union = shapely.union_all(valid)
    for i, (img, b) in enumerate(sorted(images.items())):
        box = shapely.box(*b)
        if box.area > 0 and shapely.intersection(union, box).area / box.area >= 0.99:
            lay.matched[img] = i
        else:
            lay.images_without_feature.append(img)


def _outlines(lay: Layer, geoms: list[Any], cols: dict[str, list[Any]]) -> None:
    """Block id -> polygon, the id from the one attribute whose values are unique text."""
    import shapely

    idcol = None
    for col in cols:
        if col.lower() in ID_FIELDS:
            vals = [str(v).strip() for v in cols[col] if v is not None and str(v).strip()]
            if len(vals) == len(geoms) and len(set(vals)) == len(vals):
                idcol = col
                break
    if idcol is None:
        lay.error = (
            "no attribute names the blocks (a unique id, block, name or lot per feature): "
            "outlines not used"
        )
        return
    for g, v in zip(geoms, cols[idcol], strict=True):
        if g is None or g.is_empty or g.geom_type not in ("Polygon", "MultiPolygon"):
            lay.notes.append(f"block {v!r}: not a polygon, not used")
            continue
        if not g.is_valid:
            lay.notes.append(
                f"block {v!r}: invalid polygon ({shapely.is_valid_reason(g)}), not used"
            )
            continue
        lay.outlines[str(v).strip()] = g
    lay.matched_by = f"attribute {idcol}"
