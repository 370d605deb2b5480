"""Delivered vector files (GeoPackage, shapefile) read without touching the delivery."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..errors import MeasureError
from .opening import _head, gdal_errors

#: GeoPackage (SQLite) and shapefile magic; any other vector format (an OGR VRT can point at
#: any file or URL) is refused.
_VECTOR_MAGIC = ((b"SQLite format 3\x00", "GPKG"), (b"\x00\x00\x27\x0a", "ESRI Shapefile"))


def vector_driver(path: str | Path, name: str | None = None) -> str:
    """``GPKG`` or ``ESRI Shapefile`` from the file's first bytes; MeasureError for anything
    else."""
    label = name or str(path)
    head = _head(path, label, 72)
    for magic, driver in _VECTOR_MAGIC:
        if head.startswith(magic):
            # a GeoPackage says so in the SQLite application_id (offset 68, OGC 12-128r18
            # §1.1.1.1.1);
            # any other SQLite file would go to OGR's SQLite driver (VirtualOGR tables, SpatiaLite)
            if driver == "GPKG" and head[68:72] not in (b"GPKG", b"GP10", b"GP11"):
                break
            return driver
    kind = " (XML: an OGR VRT?)" if head.lstrip().startswith(b"<") else ""
    raise MeasureError(
        f"{label}: not a readable vector file: not a GeoPackage or shapefile{kind}; other "
        "vector formats are not read"
    )


@contextmanager
def readable_vector(path: str | Path, *, name: str | None = None) -> Iterator[tuple[str, str]]:
    """(a path GDAL may open, driver) for a delivered vector file, leaving the delivery untouched.

    A GeoPackage is copied (with its ``-wal``) to a temporary folder outside the delivery and read
    there: SQLite would otherwise checkpoint and delete the delivered ``-wal`` even on a read-only
    open. A shapefile is read in place (the driver writes nothing when reading).
    """
    label = name or str(path)
    driver = vector_driver(path, label)
    if driver != "GPKG":
        yield str(path), driver
        return
    with tempfile.TemporaryDirectory(prefix="orthospec-gpkg-") as tmp:
        local = Path(tmp) / "vector.gpkg"
        try:
            shutil.copyfile(path, local)
            wal = Path(f"{path}-wal")
            if wal.is_file() and not wal.is_symlink():
                shutil.copyfile(wal, Path(f"{local}-wal"))
        except OSError as exc:
            raise MeasureError(f"{label}: cannot read file: {exc.strerror or exc}") from None
        yield str(local), driver


#: Features read at once by :func:`read_vector`: the WKB of one batch is in memory beside the
#: geometries already made, never the whole layer's (a 150,000-polygon seamline layer).
VECTOR_BATCH = 20_000


def read_vector(
    path: str | Path, *, name: str | None = None, batch: int = VECTOR_BATCH
) -> tuple[list[Any], str | None]:
    """Geometries (shapely) and CRS (WKT/authority string) of a vector file, with pyogrio, read in
    batches of ``batch`` features (no attribute columns: only the geometries are measured)."""
    import pyogrio
    import shapely

    label = name or str(path)
    geoms: list[Any] = []
    crs = None
    with (
        readable_vector(path, name=label) as (local, _driver),
        gdal_errors(file=label, path=local, what="vector file"),
    ):
        total = pyogrio.read_info(local).get("features", -1)
        skip = 0
        while True:
            meta, _fids, geometry, _fields = pyogrio.raw.read(
                local, columns=[], skip_features=skip, max_features=batch
            )
            crs = meta.get("crs")
            n = 0 if geometry is None else len(geometry)
            if n:
                geoms.extend(g for g in shapely.from_wkb(geometry) if g is not None)
            del geometry
            skip += n
            if n < batch or (total >= 0 and skip >= total):
                break
    return geoms, crs
