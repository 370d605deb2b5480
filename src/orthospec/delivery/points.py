"""Read a standalone checkpoint CSV for ``orthospec measure accuracy``.

Two layouts (header row, comma separated, UTF-8):

* coordinates: ``id,x,y[,z],x_ref,y_ref[,z_ref]`` — deltas are image minus reference;
* deltas: ``id,dx,dy[,dz]``.

``point_id`` is accepted for ``id``. Optional columns: ``unit`` (one length unit for the
whole file; mixed units are an error), ``excluded`` (a boolean word, as in every orthospec
table) and ``exclusion_reason`` (a blunder exclusion request and its justification, JRC §12.6).
Rows are numbered 1-based after the header, as everywhere in orthospec. Values are returned in
metres.

The file is parsed by the one table parser of orthospec (:func:`orthospec.delivery.table.parse_csv`,
issue 15): the same limits, field counts, boolean words and messages naming file, row and column
as a delivery table. This module only decides the layout and the point semantics.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DeliveryError, UnitError
from ..units import canonical, convert, parse_unit
from .convention import ColumnSpec, TableSpec
from .table import header_names, parse_csv
from .table_bounds import Limits, read_table_bytes, utf8_body

__all__ = ["PointFile", "PointTable", "point_table", "read_point_file", "read_points_csv"]

_COORD = ("x", "y", "x_ref", "y_ref")
_DELTA = ("dx", "dy")
_OPTIONAL = ("z", "z_ref", "dz", "unit", "excluded", "exclusion_reason")
_NUMBERS = frozenset({"x", "y", "z", "x_ref", "y_ref", "z_ref", "dx", "dy", "dz"})
_EXPECTED = ("id (or point_id), x, y, x_ref, y_ref [, z, z_ref]  or  id, dx, dy [, dz]; "
             "optional: unit, excluded, exclusion_reason")


@dataclass(frozen=True)
class PointTable:
    """Checkpoint deltas read from a CSV, in metres."""

    file: str
    ids: np.ndarray
    rows: np.ndarray  # 1-based data-row numbers of the file
    dx: np.ndarray
    dy: np.ndarray
    dz: np.ndarray | None
    source_unit: str
    layout: str  # "coordinates" | "deltas"
    exclusions: dict[str, str]  # point id -> justification ("" = requested without one)


@dataclass(frozen=True)
class PointFile:
    """A parsed point file: the typed table (``_row`` = file row), its layout and id column, and
    the columns it holds that are not point columns (when they were allowed)."""

    file: str
    df: pd.DataFrame
    layout: str
    id_col: str
    ignored: list[str]


def read_point_file(path: str | Path, *, extra_ok: frozenset[str] | None = None) -> PointFile:
    """Parse and validate a point CSV (layout, columns, every cell) with the one table parser.

    ``extra_ok``: other columns allowed (read as text, reported in ``ignored``); ``None`` allows
    all other columns, an empty set none.

    Raises
    ------
    DeliveryError
        Unreadable file, missing/unknown columns (listing the expected ones), a ragged row, a
        bad cell (file, row and column named): everything a delivery table is refused for.
    """
    name = str(path)
    p = Path(path)
    if not p.is_file():
        raise DeliveryError("file not found", file=name)
    body = utf8_body(read_table_bytes(p, file=name, limits=Limits.from_env()), file=name)
    header = header_names(body)
    if not header:
        raise DeliveryError(f"empty file; expected a header with columns {_EXPECTED}", file=name)
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DeliveryError(f"duplicate column(s) {', '.join(dup)} in the header", file=name)
    cols = set(header)
    id_col = "id" if "id" in cols else "point_id" if "point_id" in cols else None
    if id_col is None:
        raise DeliveryError(f"missing column 'id'; expected columns: {_EXPECTED}", file=name)
    has_coord = any(c in cols for c in _COORD)
    has_delta = any(c in cols for c in _DELTA)
    if has_coord and has_delta:
        raise DeliveryError(
            f"both coordinate and delta columns given; expected {_EXPECTED}", file=name
        )
    layout = "deltas" if has_delta else "coordinates"
    required = _DELTA if has_delta else _COORD
    missing = [c for c in required if c not in cols]
    if missing:
        raise DeliveryError(
            f"missing column(s) {', '.join(missing)}; expected columns: {_EXPECTED}", file=name
        )
    allowed = {id_col, *required, *_OPTIONAL}
    allowed -= {"z", "z_ref"} if layout == "deltas" else {"dz"}
    ignored = [c for c in header if c not in allowed]
    unknown = [c for c in ignored if extra_ok is not None and c not in extra_ok]
    if unknown:
        raise DeliveryError(
            f"unknown column(s) {', '.join(unknown)}; expected columns: {_EXPECTED}", file=name
        )
    if layout == "coordinates" and (("z" in cols) != ("z_ref" in cols)):
        raise DeliveryError("columns z and z_ref must be given together", file=name)
    df = parse_csv(body, _spec(header, id_col, required), file=name)
    return PointFile(name, df, layout, id_col, ignored)


def _spec(header: list[str], id_col: str, required: tuple[str, ...]) -> TableSpec:
    """The table spec of one point file (ids are checked here, with the first row named)."""

    def kind(c: str) -> str:
        return "number" if c in _NUMBERS else "bool" if c == "excluded" else "text"

    columns = {
        c: ColumnSpec(
            c,
            kind(c),  # type: ignore[arg-type]
            "length" if c in _NUMBERS else None,
            c == id_col or c in required,
            "",
        )
        for c in header
    }
    return TableSpec("points", "checkpoint", None, "measure accuracy point file", columns)


def read_points_csv(path: str | Path, *, units: str | None = None) -> PointTable:
    """Read and validate a checkpoint CSV; convert lengths to metres.

    ``units`` is the unit of the coordinate columns when the file has no ``unit`` column
    (default m); if both are given they must agree.

    Raises
    ------
    DeliveryError
        Unreadable file, missing/unknown columns (listing the expected ones), a non-numeric
        or non-finite cell (with row and column), blank or duplicate ids, mixed units, a
        partly filled z column, fewer than 2 points.
    """
    return point_table(read_point_file(path, extra_ok=frozenset()), units=units)


def point_table(
    pf: PointFile, rows: np.ndarray | None = None, *, units: str | None = None
) -> PointTable:
    """The points of ``pf`` (or of its rows at positions ``rows``: one block), in metres."""
    df = pf.df if rows is None else pf.df.iloc[rows]
    name = pf.file
    n = len(df)
    if n < 2:
        raise DeliveryError(f"{n} point(s); at least 2 are needed for statistics", file=name)
    row_no = df["_row"].to_numpy(np.int64)
    ids = df[pf.id_col].to_numpy(dtype=object)
    dup = pd.Index(ids).duplicated()
    if dup.any():
        i = int(np.argmax(dup))
        first = int(row_no[int(np.argmax(ids == ids[i]))])
        raise DeliveryError(
            f"duplicate point id {ids[i]!r} (first on row {first})",
            file=name,
            row=int(row_no[i]),
            field=pf.id_col,
        )

    def optional(col: str) -> np.ndarray | None:
        if col not in df:
            return None
        v = df[col].to_numpy(dtype=float)
        empty = np.isnan(v)
        if empty.all():
            return None
        if empty.any():
            raise DeliveryError(
                "empty cell in a partly filled column (fill all rows or none)",
                file=name,
                row=int(row_no[np.argmax(empty)]),
                field=col,
            )
        return v

    def number(col: str) -> np.ndarray:
        return df[col].to_numpy(dtype=float)

    if pf.layout == "coordinates":
        dx, dy = number("x") - number("x_ref"), number("y") - number("y_ref")
        z, z_ref = optional("z"), optional("z_ref")
        if (z is None) != (z_ref is None):
            raise DeliveryError("z and z_ref must both be filled or both be empty", file=name)
        dz = None if z is None or z_ref is None else z - z_ref
    else:
        dx, dy, dz = number("dx"), number("dy"), optional("dz")
    unit = _resolve_unit(df.get("unit"), row_no, units, name)
    try:
        dx, dy = convert(dx, unit, "m", what=name), convert(dy, unit, "m", what=name)
        dz = None if dz is None else convert(dz, unit, "m", what=name)
    except UnitError as exc:
        raise DeliveryError(str(exc), file=name, field="unit") from None
    return PointTable(
        file=name,
        ids=ids,
        rows=row_no,
        dx=dx,
        dy=dy,
        dz=dz,
        source_unit=unit,
        layout=pf.layout,
        exclusions=_exclusions(df, ids),
    )


def _exclusions(df: pd.DataFrame, ids: np.ndarray) -> dict[str, str]:
    """Point id -> justification of every exclusion request: ``excluded`` true, or (without that
    column) a filled ``exclusion_reason``."""
    reasons = df["exclusion_reason"].to_numpy(dtype=object) if "exclusion_reason" in df else None
    if "excluded" in df:
        chosen = np.flatnonzero(df["excluded"].to_numpy(dtype=object) == True)  # noqa: E712 (None: unset)
    elif reasons is not None:
        chosen = np.flatnonzero(pd.notna(reasons))
    else:
        chosen = np.zeros(0, dtype=np.intp)
    return {
        ids[i]: "" if reasons is None or reasons[i] is None else reasons[i] for i in chosen.tolist()
    }


def _resolve_unit(cells: pd.Series | None, rows: np.ndarray, units: str | None, name: str) -> str:
    """The file's one length unit (validated once per distinct spelling, in row order)."""
    column_unit = None
    if cells is not None:
        values = cells.to_numpy(dtype=object)
        empty = np.flatnonzero(pd.isna(values))
        if empty.size:
            raise DeliveryError("empty unit", file=name, row=int(rows[empty[0]]), field="unit")
        codes, spellings = pd.factorize(values)
        first = np.full(len(spellings), len(values))
        np.minimum.at(first, codes, np.arange(len(values)))
        found: dict[str, int] = {}
        for i, u in sorted(zip(first.tolist(), spellings.tolist(), strict=True)):
            try:
                key = canonical(u)
                ok = parse_unit(u).dimensionality == parse_unit("m").dimensionality
            except UnitError:
                raise DeliveryError(
                    f"unknown unit {u!r}; expected m, ft or usft",
                    file=name,
                    row=int(rows[i]),
                    field="unit",
                ) from None
            if not ok:
                raise DeliveryError(
                    f"unit {u!r} is not a length; expected m, ft or usft",
                    file=name,
                    row=int(rows[i]),
                    field="unit",
                )
            found.setdefault(key, int(rows[i]))
        if len(found) > 1:
            listed = ", ".join(f"{k} (row {v})" for k, v in found.items())
            raise DeliveryError(
                f"mixed units in one file: {listed}; use one unit", file=name, field="unit"
            )
        column_unit = next(iter(found))
    if column_unit and units and canonical(units) != column_unit:
        raise DeliveryError(
            f"the unit column says {column_unit} but --units says {canonical(units)}",
            file=name,
            field="unit",
        )
    return column_unit or (canonical(units) if units else "m")
