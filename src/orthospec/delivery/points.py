"""Read a standalone checkpoint CSV for ``orthospec measure accuracy``.

Two layouts (header row, comma separated, UTF-8):

* coordinates: ``id,x,y[,z],x_ref,y_ref[,z_ref]`` — deltas are image minus reference;
* deltas: ``id,dx,dy[,dz]``.

``point_id`` is accepted for ``id``. Optional columns: ``unit`` (one length unit for the
whole file; mixed units are an error), ``excluded`` (true/false) and ``exclusion_reason``
(a blunder exclusion request and its justification, JRC §12.6). Rows are numbered 1-based
after the header, as everywhere in orthospec. Values are returned in metres.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DeliveryError, UnitError
from ..units import canonical, convert, parse_unit

__all__ = ["PointTable", "read_points_csv"]

_COORD = ("x", "y", "x_ref", "y_ref")
_DELTA = ("dx", "dy")
_OPTIONAL = ("z", "z_ref", "dz", "unit", "excluded", "exclusion_reason")
_EXPECTED = ("id (or point_id), x, y, x_ref, y_ref [, z, z_ref]  or  id, dx, dy [, dz]; "
             "optional: unit, excluded, exclusion_reason")
_TRUE = {"true", "yes", "y", "1", "x"}
_FALSE = {"false", "no", "n", "0", ""}


@dataclass(frozen=True)
class PointTable:
    """Checkpoint deltas read from a CSV, in metres."""

    file: str
    ids: np.ndarray
    rows: np.ndarray  # 1-based data-row numbers
    dx: np.ndarray
    dy: np.ndarray
    dz: np.ndarray | None
    source_unit: str
    layout: str  # "coordinates" | "deltas"
    exclusions: dict[str, str]  # point id -> justification ("" = requested without one)


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
    name = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            raw_header = next(reader, None)
            records = [r for r in reader if r]  # csv.DictReader skips empty lines too
    except FileNotFoundError:
        raise DeliveryError("file not found", file=name) from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise DeliveryError(f"cannot read CSV: {exc}", file=name) from None
    header = [h.strip() for h in (raw_header or [])]
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
        raise DeliveryError(f"both coordinate and delta columns given; expected {_EXPECTED}",
                            file=name)
    layout = "deltas" if has_delta else "coordinates"
    required = _DELTA if has_delta else _COORD
    missing = [c for c in required if c not in cols]
    if missing:
        raise DeliveryError(
            f"missing column(s) {', '.join(missing)}; expected columns: {_EXPECTED}", file=name)
    allowed = {id_col, *required, *_OPTIONAL}
    allowed -= {"z", "z_ref"} if layout == "deltas" else {"dz"}
    unknown = [c for c in header if c not in allowed]
    if unknown:
        raise DeliveryError(
            f"unknown column(s) {', '.join(unknown)}; expected columns: {_EXPECTED}", file=name)
    if layout == "coordinates" and (("z" in cols) != ("z_ref" in cols)):
        raise DeliveryError("columns z and z_ref must be given together", file=name)

    n = len(records)
    if n < 2:
        raise DeliveryError(f"{n} point(s); at least 2 are needed for statistics", file=name)
    table = _columns(records, header)

    ids = table[id_col]
    empty = np.flatnonzero(ids == "")
    if empty.size:
        raise DeliveryError("empty point id", file=name, row=int(empty[0]) + 1, field=id_col)
    if len(set(ids.tolist())) != n:
        seen: dict[str, int] = {}
        for i, pid in enumerate(ids.tolist(), start=1):
            if pid in seen:
                raise DeliveryError(f"duplicate point id {pid!r} (first on row {seen[pid]})",
                                    file=name, row=i, field=id_col)
            seen[pid] = i

    def number(col: str) -> np.ndarray:
        return _numbers(table[col], name, col)

    def optional_number(col: str) -> np.ndarray | None:
        if col not in cols:
            return None
        filled = table[col] != ""
        if not filled.any():
            return None
        if not filled.all():
            raise DeliveryError("empty cell in a partly filled column (fill all rows or none)",
                                file=name, row=int(np.argmin(filled)) + 1, field=col)
        return number(col)

    if layout == "coordinates":
        dx = number("x") - number("x_ref")
        dy = number("y") - number("y_ref")
        z, z_ref = optional_number("z"), optional_number("z_ref")
        if (z is None) != (z_ref is None):
            raise DeliveryError("z and z_ref must both be filled or both be empty", file=name)
        dz = None if z is None or z_ref is None else z - z_ref
    else:
        dx, dy, dz = number("dx"), number("dy"), optional_number("dz")

    unit = _resolve_unit(table.get("unit"), units, name)
    try:
        dx, dy = convert(dx, unit, "m", what=name), convert(dy, unit, "m", what=name)
        dz = None if dz is None else convert(dz, unit, "m", what=name)
    except UnitError as exc:
        raise DeliveryError(str(exc), file=name, field="unit") from None

    exclusions: dict[str, str] = {}
    reasons = table.get("exclusion_reason")
    if "excluded" in cols:
        flags = np.char.lower(table["excluded"].astype(str))
        bad = ~np.isin(flags, sorted(_TRUE | _FALSE))
        if bad.any():
            i = int(np.argmax(bad))
            raise DeliveryError(f"expected true/false, got {table['excluded'][i]!r}", file=name,
                                row=i + 1, field="excluded")
        chosen = np.flatnonzero(np.isin(flags, sorted(_TRUE)))
    elif reasons is not None:
        chosen = np.flatnonzero(reasons != "")
    else:
        chosen = np.zeros(0, dtype=np.intp)
    for i in chosen.tolist():
        exclusions[ids[i]] = "" if reasons is None else reasons[i]

    return PointTable(
        file=name, ids=ids.astype(object), rows=np.arange(1, n + 1),
        dx=dx, dy=dy, dz=dz, source_unit=unit, layout=layout, exclusions=exclusions,
    )


def _columns(records: list[list[str]], header: list[str]) -> dict[str, np.ndarray]:
    """Stripped cells by column, as ``csv.DictReader`` would give them: a missing trailing cell
    is empty, cells beyond the header are dropped."""
    width = len(header)
    if set(map(len, records)) != {width}:
        records = [r[:width] if len(r) >= width else r + [""] * (width - len(r)) for r in records]
    out = {}
    for h, cells in zip(header, zip(*records, strict=True), strict=True):
        out[h] = np.array(list(map(str.strip, cells)), dtype=object)  # C loop, no frame per cell
    return out


def _numbers(cells: np.ndarray, name: str, col: str) -> np.ndarray:
    """Python ``float`` of every cell (numpy calls it per object, in C), finite; else the first
    offending row, as a per-row loop would report it."""
    try:
        values = np.asarray(cells, dtype=np.float64)
    except (ValueError, TypeError):
        parsed = []
        for i, text in enumerate(cells.tolist(), start=1):
            try:
                parsed.append(float(text))
            except ValueError:
                raise DeliveryError(f"expected a number, got {text!r}", file=name, row=i,
                                    field=col) from None
        values = np.asarray(parsed, dtype=np.float64)
    finite = np.isfinite(values)
    if not finite.all():
        i = int(np.argmin(finite))
        raise DeliveryError(f"expected a finite number, got {cells[i]!r}", file=name, row=i + 1,
                            field=col)
    return values


def _resolve_unit(cells: np.ndarray | None, units: str | None, name: str) -> str:
    """The file's one length unit (validated once per distinct spelling, in row order)."""
    column_unit = None
    if cells is not None:
        empty = np.flatnonzero(cells == "")
        if empty.size:
            raise DeliveryError("empty unit", file=name, row=int(empty[0]) + 1, field="unit")
        spellings, first = np.unique(cells.astype(str), return_index=True)
        found: dict[str, int] = {}
        for i, u in sorted(zip(first.tolist(), spellings.tolist(), strict=True)):
            try:
                key = canonical(u)
                ok = parse_unit(u).dimensionality == parse_unit("m").dimensionality
            except UnitError:
                raise DeliveryError(f"unknown unit {u!r}; expected m, ft or usft", file=name,
                                    row=i + 1, field="unit") from None
            if not ok:
                raise DeliveryError(f"unit {u!r} is not a length; expected m, ft or usft",
                                    file=name, row=i + 1, field="unit")
            found.setdefault(key, i + 1)
        if len(found) > 1:
            listed = ", ".join(f"{k} (row {v})" for k, v in found.items())
            raise DeliveryError(f"mixed units in one file: {listed}; use one unit", file=name,
                                field="unit")
        column_unit = next(iter(found))
    if column_unit and units and canonical(units) != column_unit:
        raise DeliveryError(
            f"the unit column says {column_unit} but --units says {canonical(units)}",
            file=name, field="unit")
    return column_unit or (canonical(units) if units else "m")
