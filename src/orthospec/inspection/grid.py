"""The inspection grid: written over the sampled orthoimages, marked by the checker, read back by `check`.

Layers of CHECKER_DIR/inspection.gpkg (one GeoPackage, pyogrio):

``cells`` (polygons, the images' CRS)
    one square cell of ``--cell`` size per grid step over each sampled image's footprint, clipped to
    it. Fields: ``cell_id``, ``image_id``, ``image_file``, ``image_sha256`` (written by the tool),
    ``col``, ``row`` (the cell's index on the grid), ``inspected`` (0/1, set by the checker), one
    0/1 field per defect class of specs/inspection.yaml, ``comment``, ``inspector``, ``date``.
``images`` (no geometry)
    the sampled images: ``image_id``, ``file``, ``sha256``, ``cells``.
``grid`` (no geometry)
    ``key``/``value``: format, delivery id, cell size and unit, tool version, the sample used.

A cell the checker adds, moves or attaches to another image, an unknown field (a defect class the
catalogue does not have) or a value other than 0/1 in a class field is bad input: exit 2 naming the
file, the cell's fid and the field. A cell whose image changed since the grid was written (another
SHA-256) gives that image no verdict, with the reason (issue 29 item 4).
"""

from __future__ import annotations

import itertools
import math
import os
import re
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import OrthospecError
from .defects import catalogue

FORMAT = "orthospec.inspection/1"
CELLS, IMAGES, META = "cells", "images", "grid"
#: the grid's own fields, in order; the defect classes' 0/1 fields follow ``inspected``
HEAD = ("cell_id", "image_id", "image_file", "image_sha256", "col", "row", "inspected")
TAIL = ("comment", "inspector", "date")
#: at most this many cells per grid (a cell size far too small for the sample is refused, not written)
MAX_CELLS = 2_000_000
#: relative tolerance of a cell's edited geometry (area and bounds) against the one the tool wrote
_TOL = 1e-6
_SIZE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(m|px)?\s*$")


def fields() -> tuple[str, ...]:
    """Every field of the ``cells`` layer, in order."""
    return (*HEAD, *catalogue().codes, *TAIL)


@dataclass(frozen=True)
class CellSize:
    """The cell edge: metres in the images' map projection (``m``), or image pixels (``px``)."""

    value: float
    unit: str = "m"

    @classmethod
    def parse(cls, text: str) -> CellSize:
        m = _SIZE.match(str(text))
        if not m or not math.isfinite(float(m.group(1))) or float(m.group(1)) <= 0:
            raise OrthospecError(
                f"--cell {text!r}: expected a positive size in metres or pixels, e.g. 250, "
                "250m or 512px"
            )
        return cls(float(m.group(1)), m.group(2) or "m")

    def __str__(self) -> str:
        return f"{self.value:g}{self.unit}"


@dataclass(frozen=True)
class GridImage:
    """One delivered image as the grid sees it: where it is and what it is (its SHA-256)."""

    image_id: str
    file: str
    sha256: str
    bounds: tuple[float, float, float, float]
    pixel: tuple[float, float]
    crs_wkt: str | None


def cell_count(img: GridImage, size: CellSize) -> float:
    """How many grid steps cover ``img`` (an upper bound of :func:`image_cells`' length, from its bounds
    alone): checked against :data:`MAX_CELLS` before any cell is built (a hostile ``--cell`` or an
    edited cell size in a grid file must not build a billion polygons). ``inf`` when it overflows."""
    left, bottom, right, top = img.bounds
    if size.unit == "px":
        sx, sy = size.value * abs(img.pixel[0]), size.value * abs(img.pixel[1])
        with np.errstate(all="ignore"):
            n = max(1.0, math.ceil((right - left) / sx - 1e-9) if sx > 0 else math.inf) * max(
                1.0, math.ceil((top - bottom) / sy - 1e-9) if sy > 0 else math.inf
            )
        return float(n)
    s = size.value
    with np.errstate(all="ignore"):
        spans = [np.float64(v) / s for v in (left, right, bottom, top)]
    if not all(np.isfinite(spans)):
        return math.inf
    return float(
        (math.ceil(spans[1]) - math.floor(spans[0])) * (math.ceil(spans[3]) - math.floor(spans[2]))
    )


def image_cells(
    img: GridImage, size: CellSize, *, limit: float = MAX_CELLS
) -> list[tuple[int, int, Any]]:
    """(col, row, polygon) of the cells over ``img``: squares on a grid anchored at the map origin
    (``m``) or at the image's top-left pixel (``px``), clipped to the footprint; deterministic, so
    ``check`` can recompute them to tell an edited or added cell.

    Raises
    ------
    OrthospecError
        more than ``limit`` cells (:func:`cell_count`)."""
    import shapely

    n = cell_count(img, size)
    if not n <= limit:
        raise OrthospecError(
            f"cell size {size} over image {img.image_id} gives {n:,.0f} cells, more than "
            f"{limit:,.0f}: choose a larger cell"
        )
    left, bottom, right, top = img.bounds
    if size.unit == "px":
        sx, sy = size.value * abs(img.pixel[0]), size.value * abs(img.pixel[1])
        ncol = max(1, math.ceil((right - left) / sx - 1e-9))
        nrow = max(1, math.ceil((top - bottom) / sy - 1e-9))
        rr, cc = np.meshgrid(
            np.arange(nrow), np.arange(ncol), indexing="ij"
        )  # rows outer, columns inner
        x0, x1 = np.maximum(left, left + cc * sx), np.minimum(right, left + (cc + 1) * sx)
        y0, y1 = np.maximum(bottom, top - (rr + 1) * sy), np.minimum(top, top - rr * sy)
    else:
        s = size.value
        c0, c1 = math.floor(left / s), math.ceil(right / s)
        r0, r1 = math.floor(bottom / s), math.ceil(top / s)
        rr, cc = np.meshgrid(
            np.arange(r1 - 1, r0 - 1, -1), np.arange(c0, c1), indexing="ij"
        )  # north first
        x0, x1 = np.maximum(left, cc * s), np.minimum(right, (cc + 1) * s)
        y0, y1 = np.maximum(bottom, rr * s), np.minimum(top, (rr + 1) * s)
    keep = ((x1 - x0) * (y1 - y0) > 0).ravel()
    geoms = shapely.box(x0.ravel()[keep], y0.ravel()[keep], x1.ravel()[keep], y1.ravel()[keep])
    return list(
        zip(cc.ravel()[keep].tolist(), rr.ravel()[keep].tolist(), geoms.tolist(), strict=True)
    )


def cell_id(image_id: str, col: int, row: int) -> str:
    return f"{image_id}/{col}/{row}"


def _write_gpkg(
    out: Path, layers: list[tuple[str, Any, list[Any], list[str], Any]], *, verb: str = "write"
) -> None:
    """Write ``layers`` (name, WKB geometries or None, field values, field names, CRS) into the GeoPackage
    ``out`` atomically: a temporary file beside it, renamed when whole (nothing half-written is left).
    GeoPackage timestamps are pinned (``OGR_CURRENT_DATE``): same inputs, same bytes."""
    from pyogrio import raw

    fd, tmp = tempfile.mkstemp(prefix=".inspection-", suffix=".gpkg", dir=out.parent)
    os.close(fd)
    os.unlink(tmp)  # pyogrio creates the file; the name is ours
    old = os.environ.get("OGR_CURRENT_DATE")
    os.environ["OGR_CURRENT_DATE"] = "2000-01-01T00:00:00Z"
    try:
        for i, (layer, geometry, values, names, crs) in enumerate(layers):
            raw.write(
                tmp,
                geometry,
                values,
                names,
                crs=crs,
                driver="GPKG",
                layer=layer,
                append=i > 0,
                geometry_type="Polygon" if geometry is not None else None,
            )
        os.replace(tmp, out)
    except OSError as exc:
        raise OrthospecError(f"cannot {verb} {out}: {exc.strerror or exc}") from None
    except Exception as exc:  # pyogrio/GDAL errors: name the file, leave nothing behind
        raise OrthospecError(f"cannot {verb} {out}: {exc}") from None
    finally:
        if old is None:
            os.environ.pop("OGR_CURRENT_DATE", None)
        else:
            os.environ["OGR_CURRENT_DATE"] = old
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_grid(
    path: str | Path, images: Iterable[GridImage], size: CellSize, *, meta: Mapping[str, str]
) -> dict[str, int]:
    """Write the grid atomically (a temporary file beside ``path``, then renamed); returns counts.

    Raises
    ------
    OrthospecError
        images in different CRS, more than :data:`MAX_CELLS` cells, or the file cannot be written.
    """
    import shapely

    imgs = list(images)
    crs = {i.crs_wkt for i in imgs}
    if len(crs) > 1:
        raise OrthospecError(
            "the sampled images are in different coordinate reference systems: one grid needs "
            "one (JRC §12.4 Table 12: every ortho in the ITT's map projection)"
        )
    cols: dict[str, list[Any]] = {f: [] for f in fields()}
    geoms = []
    per_image = {}
    budget = float(MAX_CELLS)
    for img in imgs:
        try:
            cells = image_cells(img, size, limit=budget)
        except OrthospecError:
            raise OrthospecError(
                f"--cell {size}: more than {MAX_CELLS:,} cells over the sample; choose a larger "
                "cell"
            ) from None
        per_image[img.image_id] = len(cells)
        budget -= len(cells)
        for c, r, poly in cells:
            geoms.append(poly)
            for k, v in (
                ("cell_id", cell_id(img.image_id, c, r)),
                ("image_id", img.image_id),
                ("image_file", img.file),
                ("image_sha256", img.sha256),
                ("col", c),
                ("row", r),
            ):
                cols[k].append(v)
    n = len(geoms)
    data = []
    for f in fields():
        if f in ("col", "row"):
            data.append(np.asarray(cols[f], dtype=np.int32))
        elif f == "inspected" or f in catalogue().codes:
            data.append(np.zeros(n, dtype=np.int32))
        elif f in TAIL:
            data.append(np.full(n, None, dtype=object))
        else:
            data.append(np.asarray(cols[f], dtype=object))
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    wkb = shapely.to_wkb(np.asarray(geoms, dtype=object)) if n else np.asarray([], dtype=object)
    keys = {"format": FORMAT, "cell": str(size), **meta}
    _write_gpkg(
        out,
        [
            (CELLS, wkb, data, list(fields()), next(iter(crs)) if crs else None),
            (
                IMAGES,
                None,
                [
                    np.asarray([i.image_id for i in imgs], dtype=object),
                    np.asarray([i.file for i in imgs], dtype=object),
                    np.asarray([i.sha256 for i in imgs], dtype=object),
                    np.asarray([per_image[i.image_id] for i in imgs], dtype=np.int32),
                ],
                ["image_id", "file", "sha256", "cells"],
                None,
            ),
            (
                META,
                None,
                [
                    np.asarray(list(keys), dtype=object),
                    np.asarray(list(keys.values()), dtype=object),
                ],
                ["key", "value"],
                None,
            ),
        ],
    )
    return {"images": len(imgs), "cells": n}


# --------------------------------------------------------------------------- reading a marked grid
@dataclass(frozen=True)
class ImageState:
    """A grid image at check time: bound (the delivered file is the one gridded) or why not."""

    image_id: str
    file: str
    sha256: str
    reason: str | None = None

    @property
    def bound(self) -> bool:
        return self.reason is None


@dataclass(frozen=True)
class GridVerdict:
    """What the grid says about one image for one rule: pass / fail / missing, why, the cells behind it."""

    verdict: str
    note: str
    cells: tuple[dict[str, Any], ...] = ()


@dataclass
class Grid:
    """A marked grid, read and checked against the delivery as delivered now."""

    path: Path
    display: str
    sha256: str
    cells: pd.DataFrame
    images: dict[str, ImageState]
    meta: dict[str, str]
    codes: tuple[str, ...] = field(default_factory=tuple)
    #: image id -> row positions of its cells (built once: a rule asks per image, many rules per run)
    _rows: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    _marks: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool), repr=False)
    _seen: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool), repr=False)

    def __post_init__(self) -> None:
        ids = self.cells["image_id"].to_numpy(dtype=object)
        order = np.argsort(ids, kind="stable")
        sorted_ids = ids[order]
        starts = (
            np.flatnonzero(np.r_[True, sorted_ids[1:] != sorted_ids[:-1]])
            if len(ids)
            else np.zeros(0, int)
        )
        bounds = np.r_[starts, len(ids)]
        self._rows = {
            str(sorted_ids[a]): np.sort(order[a:b]) for a, b in itertools.pairwise(bounds)
        }
        self._marks = (
            self.cells[list(self.codes)].to_numpy(dtype=bool)
            if self.codes
            else np.zeros((len(ids), 0), bool)
        )
        self._seen = self.cells["inspected"].to_numpy(dtype=bool) | self._marks.any(axis=1)

    def answers(self, rule: str) -> set[str]:
        """The images the grid gives ``rule`` a verdict on (none when the rule reads no defect class)."""
        return set(self.images) if rule in catalogue().rules else set()

    def verdict(self, rule: str, image_id: str, *, gone: bool = False) -> GridVerdict | None:
        """The grid's verdict on ``image_id`` for manual rule ``rule``; None when the grid does not answer it
        (the rule reads no defect class, or the image was not gridded). ``gone``: the delivery no longer
        lists the image; its marks are reported as given (the record names the item, the roll-up returns
        the delivery, engine/manual.py), never dropped."""
        codes = catalogue().rules.get(rule)
        state = self.images.get(image_id)
        if codes is None or state is None:
            return None
        if not state.bound and not gone:
            return GridVerdict(
                "missing",
                f"inspection grid {self.path.name}: {state.reason}: its marks are not used",
            )
        rows = self._rows.get(image_id, np.zeros(0, dtype=int))
        cols = np.array([self.codes.index(c) for c in codes], dtype=int)
        hit = (
            rows[self._marks[np.ix_(rows, cols)].any(axis=1)]
            if len(rows) and len(cols)
            else rows[:0]
        )
        if len(hit):
            marked = self.cells.iloc[hit]
            shown = [_cell_text(r, codes) for r in marked.itertuples(index=False)]
            return GridVerdict(
                "fail",
                f"inspection grid {self.path.name}: {len(marked)} of {len(rows)} cells of "
                f"{image_id} marked: "
                + "; ".join(shown[:8])
                + (f"; and {len(shown) - 8} more" if len(shown) > 8 else ""),
                tuple(_cell_record(r, codes) for r in marked.itertuples(index=False)),
            )
        unseen = int((~self._seen[rows]).sum())
        if unseen:
            return GridVerdict(
                "missing",
                f"inspection grid {self.path.name}: {unseen} of {len(rows)} "
                f"cells of {image_id} not inspected yet",
            )
        # one wording for every image: a report groups the passing images of a rule into one line
        return GridVerdict(
            "pass", "inspection grid: every cell inspected, no defect of this rule marked"
        )

    def inspected_share(self) -> tuple[float | None, str]:
        """(% of the gridded area inspected, the note); cells of changed images count as not inspected."""
        if not len(self.cells):
            return None, f"inspection grid {self.display} holds no cells"
        bound = self.cells["image_id"].map(lambda i: self.images[i].bound).to_numpy(bool)
        seen = (self.cells["inspected"] | self.cells[list(self.codes)].any(axis=1)).to_numpy(
            bool
        ) & bound
        area = self.cells["area"].to_numpy(float)
        share = float(area[seen].sum() / area.sum() * 100.0)
        stale = sorted(i for i, s in self.images.items() if not s.bound)
        note = (
            f"{int(seen.sum())} of {len(seen)} cells inspected ({share:.1f} % of the gridded area) over "
            f"{len(self.images)} images"
        )
        if stale:
            note += (
                f"; not counted: the cells of {', '.join(stale[:5])}"
                + (" ..." if len(stale) > 5 else "")
                + " (image changed since the grid was written)"
            )
        return share, note

    def defect_cells(self) -> pd.DataFrame:
        """The marked cells (any defect class) with their bounds, for the block maps of the report."""
        marked = self.cells[self.cells[list(self.codes)].any(axis=1)]
        return marked


def _cell_text(r: Any, codes: tuple[str, ...]) -> str:
    got = [c for c in codes if getattr(r, c)]
    comment = f' "{r.comment}"' if isinstance(r.comment, str) and r.comment else ""
    return f"cell {r.cell_id} (fid {r.fid}): {', '.join(got)}{comment}"


def _cell_record(r: Any, codes: tuple[str, ...]) -> dict[str, Any]:
    out = {"cell_id": r.cell_id, "fid": int(r.fid), "defects": [c for c in codes if getattr(r, c)]}
    if isinstance(r.comment, str) and r.comment:
        out["comment"] = r.comment
    return out


def read_grid(
    path: str | Path,
    *,
    display: str,
    delivery_id: str,
    now: Mapping[str, GridImage | str],
) -> Grid:
    """Read and check a marked grid. ``now`` maps each image id of the delivery to the image as delivered
    now (:class:`GridImage`), or to why it cannot be read.

    Raises
    ------
    OrthospecError
        (exit 2) the grid is not one `inspect grid` wrote for this delivery, or the checker's edits are
        not marks: a cell added, moved or attached to another image, an unknown field, a value other
        than 0/1 in a class field: file, fid and field named.
    """
    import shapely
    from pyogrio import list_layers, raw

    from ..provenance import sha256_file
    from ..raster.reading import gdal_errors, readable_vector

    p = Path(path)
    cat = catalogue()
    with (
        readable_vector(p, name=display) as (local, _driver),
        gdal_errors(file=display, path=local, what="inspection grid"),
    ):
        layers = {str(n) for n, _ in list_layers(local)}
        missing = [x for x in (CELLS, IMAGES, META) if x not in layers]
        if missing:
            raise OrthospecError(
                f"{display}: not an inspection grid written by `orthospec inspect grid`: no layer "
                f"{', '.join(missing)} (layers: {', '.join(sorted(layers)) or 'none'})"
            )
        cmeta, fids, geometry, values = raw.read(local, layer=CELLS, return_fids=True)
        _, _, _, ivalues = raw.read(local, layer=IMAGES)
        mmeta, _, _, mvalues = raw.read(local, layer=META)
    meta = _table(mmeta, mvalues)
    keys = dict(zip(meta.get("key", []), meta.get("value", []), strict=True))
    if keys.get("format") != FORMAT:
        raise OrthospecError(
            f"{display}: layer {META}: format {keys.get('format')!r}, expected {FORMAT}"
        )
    if keys.get("delivery") != delivery_id:
        raise OrthospecError(
            f"{display}: the grid was written for delivery {keys.get('delivery')}; this delivery "
            f"is {delivery_id}: the checker's marks were given on other content"
        )
    size = CellSize.parse(keys.get("cell", ""))
    names = [str(f) for f in cmeta["fields"]]
    known = set(fields())
    extra = [f for f in names if f not in known]
    if extra:
        raise OrthospecError(
            f"{display}: layer {CELLS}: unknown field {extra[0]!r}: not a field of the grid nor a "
            f"defect class of specs/inspection.yaml ({', '.join(cat.codes)}); mark defects in "
            "those fields (0/1) and say more in comment"
        )
    lacking = [f for f in fields() if f not in names and f not in TAIL]
    if lacking:
        raise OrthospecError(
            f"{display}: layer {CELLS}: field {lacking[0]!r} is missing (the grid's fields: "
            f"{', '.join(fields())})"
        )
    col = dict(zip(names, values, strict=True))
    n = len(fids)
    fid = np.asarray(fids, dtype=np.int64)
    df = pd.DataFrame({"fid": fid})
    for f in ("cell_id", "image_id", "image_sha256", "comment", "inspector", "date"):
        df[f] = [None if v is None else str(v) for v in col[f]] if f in col else [None] * n
    for f in ("col", "row"):
        df[f] = _ints(col[f], f, fid, display)
    for f in ("inspected", *cat.codes):
        df[f] = _flags(col[f], f, fid, display)
    geoms = shapely.from_wkb(geometry) if geometry is not None else np.full(n, None, dtype=object)
    df["area"] = [0.0 if g is None else float(g.area) for g in geoms]
    df["bounds"] = pd.Series(
        [None if g is None else tuple(float(v) for v in g.bounds) for g in geoms],
        index=df.index,
        dtype=object,
    )
    images = _table_images(ivalues)
    states = _bind(images, now)
    _check_cells(df, geoms, images, states, size, now, display)
    return Grid(p, display, sha256_file(p), df.reset_index(drop=True), states, keys, cat.codes)


def _table(meta: dict[str, Any], values: list[Any]) -> dict[str, list[str]]:
    return {str(f): [str(v) for v in vals] for f, vals in zip(meta["fields"], values, strict=True)}


def _table_images(values: list[Any]) -> dict[str, tuple[str, str]]:
    ids, files, shas = values[0], values[1], values[2]
    return {str(i): (str(f), str(s)) for i, f, s in zip(ids, files, shas, strict=True)}


def _ints(values: Any, name: str, fid: np.ndarray, display: str) -> np.ndarray:
    arr = np.asarray(values)
    if arr.dtype.kind in "iu":
        return arr.astype(np.int64)
    out = np.zeros(len(arr), dtype=np.int64)
    for i, v in enumerate(arr.tolist()):
        try:
            if (
                v is None
                or (isinstance(v, float) and not math.isfinite(v))
                or float(v) != int(float(v))
            ):
                raise ValueError
            out[i] = int(float(v))
        except (TypeError, ValueError):
            raise _bad(
                display,
                int(fid[i]),
                name,
                f"{v!r} is not a whole number (written by the tool; do not edit it)",
            ) from None
    return out


def _flags(values: Any, name: str, fid: np.ndarray, display: str) -> np.ndarray:
    """0/1 (empty = 0) per cell; any other value is no mark the grid knows: refused naming the cell."""
    arr = np.asarray(values, dtype=object) if not isinstance(values, np.ndarray) else values
    if isinstance(arr, np.ma.MaskedArray):
        arr = arr.filled(0)
    out = np.zeros(len(arr), dtype=bool)
    for i, v in enumerate(arr.tolist()):
        if v is None or (isinstance(v, float) and math.isnan(v)) or v == 0 or v == "0" or v == "":
            continue
        if v == 1 or v == "1":
            out[i] = True
            continue
        what = "an inspection mark" if name == "inspected" else f"a mark of defect class {name}"
        raise _bad(
            display,
            int(fid[i]),
            name,
            f"{v!r} is not {what}: 1 (yes) or 0 / empty (no); unknown defect "
            f"codes are not read (the classes are fields: {', '.join(catalogue().codes)})",
        )
    return out


def _bind(
    images: dict[str, tuple[str, str]], now: Mapping[str, GridImage | str]
) -> dict[str, ImageState]:
    out = {}
    for image_id, (file, sha) in images.items():
        cur = now.get(image_id)
        if cur is None:
            why = f"image {image_id} is no longer delivered"
        elif isinstance(cur, str):
            why = f"image {image_id} cannot be read ({cur})"
        elif (
            cur.sha256.lower() != sha.lower()
        ):  # the content gridded, whatever the file is named now
            now_file = cur.file if cur.file == file else f"now {cur.file}"
            why = (
                f"image {image_id} ({now_file}) has SHA-256 {cur.sha256[:12]}…, the grid was written on {file} "
                f"{sha[:12]}… (changed or swapped since)"
            )
        else:
            why = None
        out[image_id] = ImageState(image_id, file, sha, why)
    return out


def _check_cells(
    df: pd.DataFrame,
    geoms: np.ndarray,
    images: dict[str, tuple[str, str]],
    states: dict[str, ImageState],
    size: CellSize,
    now: Mapping[str, GridImage | str],
    display: str,
) -> None:
    """Every cell is one the tool wrote: its image gridded, its index and outline those of the image's
    grid (for an image still delivered as gridded), its id and hash unedited, no cell twice, and none
    of an image's cells deleted (a deleted cell would leave its area out of the inspected share)."""
    expected: dict[str, dict[tuple[int, int], Any]] = {}
    present: dict[str, set[tuple[int, int]]] = {}
    budget = float(MAX_CELLS)
    seen: set[str] = set()
    rows: Iterable[Any] = df.itertuples(
        index=False
    )  # the columns' types are checked where the table is read
    for i, r in enumerate(rows):
        fid = int(r.fid)
        if r.image_id not in images:
            raise _bad(
                display,
                fid,
                "image_id",
                f"cell {r.cell_id!r} names image {r.image_id!r}, which the grid did "
                "not sample: a cell added outside the sample is not inspection evidence",
            )
        if r.cell_id != cell_id(r.image_id, r.col, r.row) or r.cell_id in seen:
            why = (
                "is given twice"
                if r.cell_id in seen
                else f"does not match image/col/row {r.image_id}/{r.col}/{r.row}"
            )
            raise _bad(
                display, fid, "cell_id", f"cell {r.cell_id!r} {why}: cells are written by the tool"
            )
        seen.add(r.cell_id)
        if (r.image_sha256 or "").lower() != images[r.image_id][1].lower():
            raise _bad(
                display,
                fid,
                "image_sha256",
                f"cell {r.cell_id!r}: image_sha256 was edited (the grid wrote "
                f"{images[r.image_id][1][:12]}…)",
            )
        if not states[r.image_id].bound:
            continue  # the image changed: its cells cannot be recomputed; the image gets no verdict
        img = now[r.image_id]
        assert isinstance(img, GridImage)
        if r.image_id not in expected:
            try:
                expected[r.image_id] = {
                    (c, w): poly for c, w, poly in image_cells(img, size, limit=budget)
                }
            except OrthospecError as exc:
                raise OrthospecError(
                    f"{display}: layer {META}: {exc} (the grid's cell size was edited?)"
                ) from None
            budget -= len(expected[r.image_id])
        present.setdefault(r.image_id, set()).add((int(r.col), int(r.row)))
        want = expected[r.image_id].get((int(r.col), int(r.row)))
        g = geoms[i]
        if want is None or g is None or not _same(g, want):
            raise _bad(
                display,
                fid,
                None,
                f"cell {r.cell_id!r} is not a cell of image {r.image_id}'s grid (added "
                "or moved): a cell outside the sample is not inspection evidence",
            )
    for image_id, cells in sorted(expected.items()):
        gone = sorted(set(cells) - present[image_id], key=lambda k: (-k[1], k[0]))
        if gone:
            raise OrthospecError(
                f"{display}: layer {CELLS}: cell {cell_id(image_id, *gone[0])} of image {image_id} "
                f"is missing ({len(gone)} of its {len(cells)} cells deleted): the cells are written "
                "by the tool; leave a cell you did not inspect unmarked instead"
            )


def _bad(display: str, fid: int, name: str | None, message: str) -> OrthospecError:
    """Bad input in a marked grid: the file, the cell's fid (QGIS shows it) and the field named."""
    return OrthospecError(
        f"{display}: layer {CELLS}: fid {fid}"
        + (f": field {name!r}" if name else "")
        + f": {message}"
    )


def delivered_images(d: Any, ids: Iterable[str] | None = None) -> dict[str, GridImage | str]:
    """Image id -> the image as delivered now (footprint, pixel size, CRS, SHA-256), or why it cannot be
    read; ``ids`` limits it to those images (default: every image of the images table)."""
    from ..raster.reading import open_read_only, read_only_env

    t = d.table("images")
    if t is None:
        return {}
    want = None if ids is None else set(ids)
    out: dict[str, GridImage | str] = {}
    files = t.df["file"] if "file" in t.df else pd.Series([None] * len(t.df))
    for image_id, rel, row in zip(
        t.ids.tolist(), files.tolist(), t.df["_row"].tolist(), strict=True
    ):
        if want is not None and image_id not in want:
            continue
        if rel is None:
            out[image_id] = f"{t.file} row {row} gives no file"
            continue
        try:
            p = d.path(str(rel), what="image file", file=t.file, row=int(row))
            if not p.is_file():
                out[image_id] = f"{rel} is not in the delivery"
                continue
            with read_only_env(), open_read_only(p, name=str(rel)) as ds:
                b = ds.bounds
                bounds = (float(b.left), float(b.bottom), float(b.right), float(b.top))
                pixel = (float(ds.transform.a), float(ds.transform.e))
                crs = ds.crs.to_wkt() if ds.crs is not None else None
        except OrthospecError as exc:
            out[image_id] = str(exc)
            continue
        out[image_id] = GridImage(image_id, str(rel), d.sha256(str(rel)), bounds, pixel, crs)
    return out


def _same(a: Any, b: Any) -> bool:
    ea, eb = np.asarray(a.bounds), np.asarray(b.bounds)
    scale = max(1.0, float(np.abs(eb).max()))
    return bool(
        np.all(np.abs(ea - eb) <= _TOL * scale) and abs(a.area - b.area) <= _TOL * max(b.area, 1.0)
    )


def make_grid(
    d: Any,
    size: CellSize,
    out: str | Path,
    *,
    sample: tuple[str, set[str]] | None = None,
    sample_name: str | None = None,
    version: str = "",
) -> dict[str, Any]:
    """Write the inspection grid of delivery ``d`` over the sampled images (all images without a sample;
    a block sample takes the images of those blocks). Returns what was written.

    Raises
    ------
    OrthospecError
        (exit 2) no images, a sampled id the delivery does not list, an unreadable sampled image, images in
        different CRS, too many cells, ``out`` inside the delivery or not writable.
    """
    t = d.table("images")
    if t is None:
        raise OrthospecError("the delivery has no images table: nothing to inspect")
    ids = t.ids.tolist()
    if sample is None:
        chosen = ids
    elif sample[0] == "image":
        unknown = sorted(set(sample[1]) - set(ids))
        if unknown:
            raise OrthospecError(
                f"sample {sample_name}: image {unknown[0]} is not in the delivery's images table"
            )
        chosen = [i for i in ids if i in sample[1]]
    else:
        if "block" not in t.df:
            raise OrthospecError(
                f"sample {sample_name} draws blocks, but {t.file} has no block column"
            )
        blocks = t.df["block"].astype(str).tolist()
        chosen = [i for i, b in zip(ids, blocks, strict=True) if b in sample[1]]
    if not chosen:
        raise OrthospecError("no image to inspect (the sample selects none)")
    now = delivered_images(d, chosen)
    bad = [(i, v) for i, v in now.items() if isinstance(v, str)]
    if bad:
        raise OrthospecError(f"image {bad[0][0]} cannot be gridded: {bad[0][1]}")
    meta = {
        "delivery": d.id,
        "manifest_sha256": d.manifest_sha256,
        "orthospec": version,
        "sample": sample_name or "all images",
    }
    got = write_grid(out, [v for v in now.values() if isinstance(v, GridImage)], size, meta=meta)
    return {"path": str(out), "cell": str(size), **got, "sample": meta["sample"]}


def mark_cells(path: str | Path, marks: Mapping[str, Mapping[str, Any]]) -> int:
    """Set fields of cells by id (``{cell_id: {"inspected": 1, "haze": 1, "comment": "..."}}``), as a checker
    does in a GIS, rewriting the grid file atomically; returns the cells changed. For scripts and tests
    that mark a grid without QGIS; `check` reads the result like any marked grid.

    Raises
    ------
    OrthospecError
        a cell id or field the grid does not have, or the file cannot be rewritten.
    """
    from pyogrio import raw

    p = Path(path)
    metas, tables = {}, {}
    for layer in (CELLS, IMAGES, META):
        meta, _, geometry, values = raw.read(p, layer=layer)
        metas[layer], tables[layer] = meta, (geometry, [np.asarray(v) for v in values])
    names = [str(f) for f in metas[CELLS]["fields"]]
    geometry, values = tables[CELLS]
    col = dict(zip(names, values, strict=True))
    index = {str(c): i for i, c in enumerate(col["cell_id"].tolist())}
    for cid, change in marks.items():
        if cid not in index:
            raise OrthospecError(f"{p}: no cell {cid!r}")
        for f, v in change.items():
            if f not in col:
                raise OrthospecError(f"{p}: the grid has no field {f!r}")
            if col[f].dtype.kind in "iu":
                col[f][index[cid]] = int(v)
            else:
                col[f] = col[f].astype(object)
                col[f][index[cid]] = v
    _write_gpkg(
        p,
        [
            (CELLS, geometry, [col[f] for f in names], names, metas[CELLS].get("crs")),
            *(
                (layer, None, tables[layer][1], [str(f) for f in metas[layer]["fields"]], None)
                for layer in (IMAGES, META)
            ),
        ],
        verb="rewrite",
    )
    return len(marks)


def cells_schema() -> dict[str, Any]:
    """The published JSON Schema of the properties of one cell of the ``cells`` layer
    (specs/schema/checker-inspection.schema.json)."""
    cat = catalogue()
    props: dict[str, Any] = {
        "cell_id": {"type": "string", "description": "image_id/col/row, written by the tool."},
        "image_id": {
            "type": "string",
            "description": "The sampled image the cell lies on, written by the tool.",
        },
        "image_file": {
            "type": "string",
            "description": "Its file in the delivery, written by the tool.",
        },
        "image_sha256": {
            "type": "string",
            "pattern": "^[0-9a-fA-F]{64}$",
            "description": "The image's SHA-256 when the grid was written (written by the tool).",
        },
        "col": {
            "type": "integer",
            "description": "Column index of the cell on the grid (written by the tool).",
        },
        "row": {
            "type": "integer",
            "description": "Row index of the cell on the grid (written by the tool).",
        },
        "inspected": {
            "enum": [0, 1, None],
            "description": "1 once the checker looked at the cell.",
        },
    }
    for d in cat.defects:
        props[d.code] = {
            "enum": [0, 1, None],
            "description": f'{d.title} ({d.cite()}: "{d.quote}"); 1: marked.',
        }
    props.update(
        {
            "comment": {
                "type": ["string", "null"],
                "description": "The checker's words on the cell.",
            },
            "inspector": {"type": ["string", "null"], "description": "Who inspected the cell."},
            "date": {"type": ["string", "null"], "description": "When (YYYY-MM-DD)."},
        }
    )
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://orthospec.dev/schema/checker-inspection.schema.json",
        "title": "orthospec checker folder: inspection.gpkg, layer cells (one feature's properties)",
        "description": (
            "The inspection grid `orthospec inspect grid` writes (GeoPackage: layers cells, images, "
            "grid) and the checker marks in a GIS; `check` reads the marks as the checker's evidence "
            "(docs/CHECKER.md). Polygon geometry in the images' CRS."
        ),
        "type": "object",
        "additionalProperties": False,
        "required": [f for f in fields() if f not in TAIL],
        "properties": props,
    }
