"""The one CSV table parser of orthospec: a table's bytes, bounded (:mod:`.table_bounds`), parsed
and typed against its spec (delivery tables, the external-QC sample, the point files of
``measure accuracy``, the checker's tables), every problem named by file, row and column; and
:func:`rows_where`, the bounded re-reading of a delivered table's rows by a selector.
"""

from __future__ import annotations

import csv
import io
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import controls
from ..errors import DeliveryError
from ..provenance import sha256_bytes
from .convention import ColumnSpec, TableSpec
from .table_bounds import Limits, read_table_bytes, utf8_body
from .table_shape import _arrow_text, _records, _shape_from_cells, _Typed

#: The one set of boolean words of every orthospec table (delivery tables and ``measure accuracy``
#: point files alike, issue 15), compared case-insensitively after stripping; an empty cell is unset.
BOOL_TRUE = ("true", "yes", "y", "1", "t")
BOOL_FALSE = ("false", "no", "n", "0", "f")


def parse_csv(
    text: str | bytes, spec: TableSpec, *, file: str, cell_bytes: int | None = None
) -> pd.DataFrame:
    """Parse and type a CSV table against its spec; every problem names file, row and column.

    The one CSV table parser of orthospec (delivery tables, the external-QC sample, the point
    files of ``measure accuracy``). ``text`` is the table (``bytes``: as :func:`utf8_body` gives
    them). pandas' C parser reads number columns straight to float64 and infers the others,
    each checked against the spec (:func:`_read_typed`); a table whose numbers it cannot read
    takes the exact path (every cell as text, converted column by column) that names the first
    bad cell. Cells are stripped of surrounding whitespace. Everything is vectorised: a
    million-row table parses in a small multiple of the time of ``pandas.read_csv``.

    Raises
    ------
    DeliveryError
        A bad header, a row with the wrong number of fields, an empty required cell, a cell
        that is not of its column's type, a duplicate id: file, row and column named.
    """
    return _parse_body(
        [text.encode("utf-8") if isinstance(text, str) else text],
        spec,
        file=file,
        cell_bytes=cell_bytes,
    )


def _parse_body(
    held: list[bytes], spec: TableSpec, *, file: str, cell_bytes: int | None
) -> pd.DataFrame:
    """:func:`parse_csv` of the body in ``held``, which it takes out: once the records are
    counted the bytes are let go (when the caller holds no other reference), so a national
    table is not held as bytes while its columns become Python objects."""
    body = held.pop()
    bad = controls.find_in_utf8(body)
    if bad is not None:
        raise DeliveryError(
            f"a control character ({controls.name(bad[1])}) in the table: a cell may not carry "
            "terminal or bidirectional-override controls",
            file=file,
            line=bad[0],
        )
    header = _header(body, spec, file)
    if cell_bytes is not None and csv.field_size_limit() < cell_bytes:
        csv.field_size_limit(cell_bytes)  # the bound is check_csv_bounds's, not csv's
    try:
        typed = _read_typed(body, header, spec, file)
        exact = typed is None
        frame = _read_cells(body, header, file) if typed is None else typed.frame
        shape = None if typed is None else _shape_from_cells(body, typed, header)
        if shape is None:
            shape = _records(body)
    except csv.Error as exc:  # the csv module's own complaints (NUL bytes, stray quotes...)
        raise DeliveryError(f"not a valid CSV table: {exc}", file=file) from None
    del body
    cols = _columns(frame, header, strip=exact or shape.padded)
    rows = np.arange(1, len(frame) + 1, dtype=np.int64)
    del frame, typed
    if len(rows):
        rows, cols = _drop_blank_rows(rows, cols, shape.widths, len(header), file)
    df = pd.DataFrame({"_row": rows})
    distinct = spec.id in cols and spec.columns[spec.id].type == "text" and _distinct(cols[spec.id])
    for col in header:
        cs = spec.columns[col]
        if col == spec.id and distinct:  # different texts, none empty: nothing to share or refuse
            df[col] = pd.Series(cols.pop(col)[0].to_numpy(dtype=object), dtype=object)
        else:
            df[col] = _convert_column(cols.pop(col), rows, cs.type, col, file, cs.required)
        if cs.type == "number":
            _check_bounds(df[col].to_numpy(float), rows, cs, file)
    if spec.id and spec.id in df and not distinct and not df[spec.id].is_unique:  # one hashed pass
        ids = df[spec.id]
        dups = ids.duplicated(keep=False).to_numpy()
        if dups.any():
            first_dup = ids.iloc[int(np.argmax(dups))]
            where = df.loc[ids == first_dup, "_row"].tolist()
            raise DeliveryError(
                f"duplicate id {first_dup!r} in rows {', '.join(map(str, where))}",
                file=file,
                field=spec.id,
            )
    return df


def _check_bounds(values: np.ndarray, rows: np.ndarray, cs: ColumnSpec, file: str) -> None:
    """A number outside its column's ``min:``/``max:`` (specs/delivery-tables.yaml) is refused.

    An RMSE, a precision, a square root of PRESS is >= 0 and a share <= 100 % by definition: a
    negative one passes every ``<=`` threshold (red team R14), so it is refused where the table is
    read, once for every table, rather than per rule. Empty cells (NaN) are not compared.
    """
    for bound, below in ((cs.min, True), (cs.max, False)):
        if bound is None:
            continue
        out = values < bound if below else values > bound
        if out.any():
            i = int(np.argmax(out))
            raise DeliveryError(
                f"{values[i]:g} is {'below the minimum' if below else 'above the maximum'} "
                f"{bound:g} of this column",
                file=file,
                row=int(rows[i]),
                field=cs.name,
            )


def header_names(body: bytes) -> list[str]:
    """The stripped column names of a table's first line ([] for an empty table)."""
    nl = body.find(b"\n")
    first = (body if nl < 0 else body[:nl]).decode("utf-8")
    return [h.strip() for h in next(csv.reader([first]))] if first.strip() else []


def _header(body: bytes, spec: TableSpec, file: str) -> list[str]:
    """The stripped column names, checked against the spec (line 1 named in every complaint)."""
    header = header_names(body)
    if not header:
        raise DeliveryError(
            "empty table: expected a header row with columns " + ", ".join(spec.columns), file=file
        )
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DeliveryError(f"duplicate column(s) {', '.join(dup)}", file=file, line=1)
    unknown = [h for h in header if h not in spec.columns]
    missing = [c for c in spec.required if c not in header]
    if unknown or missing:
        parts = []
        if missing:
            parts.append("missing required column(s) " + ", ".join(missing))
        if unknown:
            parts.append("unexpected column(s) " + ", ".join(unknown))
        raise DeliveryError(
            "; ".join(parts)
            + f". Expected columns for table '{spec.name}': required "
            + ", ".join(spec.required)
            + "; optional "
            + ", ".join(c for c in spec.columns if c not in spec.required),
            file=file,
            line=1,
        )
    return header


def _read_csv(body: bytes, header: list[str], file: str, **kw: Any) -> pd.DataFrame:
    """pandas' C parser over the table; a row with too many fields is named by its data row."""
    try:
        return pd.read_csv(
            io.BytesIO(body),
            header=0,
            names=header,
            keep_default_na=False,
            na_values={c: [""] for c in header},
            skip_blank_lines=False,
            skipinitialspace=False,
            engine="c",
            **kw,
        )
    except pd.errors.ParserError as exc:
        m = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        if m:
            raise DeliveryError(
                f"has {m.group(3)} fields, the header has {m.group(1)}",
                file=file,
                row=int(m.group(2)) - 1,
            ) from None
        raise DeliveryError(f"not a valid CSV table: {exc}", file=file) from None


def _read_typed(body: bytes, header: list[str], spec: TableSpec, file: str) -> _Typed | None:
    """One pass of pandas' C parser, number columns as float64, the others as it infers them,
    each checked against the spec; None when a number needs the exact path (every cell as text,
    converted column by column, which names the first bad cell).

    The C parser and ``pandas.to_numeric`` (the exact path) agree on every number they both
    read; the fast result is refused when the parser refuses a cell (words, ``nan``, a blank of
    spaces...) or read an infinity, and a number column holding an exact 0 or 1 is re-read as
    text (the parser reads a column, or a chunk of rows, of only boolean words as 0/1).

    The other columns are inferred (pandas 3: the Arrow-backed ``str`` dtype, about twice as fast
    as asking for object or category columns; pandas 2: object), and must come out as text, so
    no cell's text changes ("001" read as 1, "false" as False). Two other shapes are exact
    without the text: a column of empty cells (float NaN) and a bool column of the parser's
    boolean words (True, TRUE, true and the False words, all boolean words of ours). Any other
    column (numbers, or chunks of rows inferred differently: object of mixed types) is re-read
    as text.
    """
    nums = [c for c in header if spec.columns[c].type == "number"]
    try:
        with (
            warnings.catch_warnings()
        ):  # chunks inferred differently: checked below, column by column
            warnings.simplefilter("ignore", pd.errors.DtypeWarning)
            frame = _read_csv(body, header, file, dtype={c: "float64" for c in nums})
    except ValueError:
        return None
    n = len(frame)
    if not frame.index.equals(pd.RangeIndex(n)):  # a first record one field long made an index
        return None
    texts: list[str] = []
    reread: list[str] = []
    for c in header:
        s = frame[c]
        if c in nums:
            v = s.to_numpy()
            if np.isinf(v).any():
                return None
            if ((v == 0.0) | (v == 1.0)).any():
                reread.append(c)
        elif _is_text(s):
            texts.append(c)
        elif s.dtype == np.float64 and s.isna().all():  # a column of empty cells
            frame[c] = pd.Categorical.from_codes(
                np.full(n, -1, dtype=np.int8), categories=_NO_WORDS
            )
        elif spec.columns[c].type == "bool" and _parser_bools(s):
            codes = (s.to_numpy(dtype=object) == True).astype(np.int8)  # noqa: E712
            codes[s.isna().to_numpy()] = -1
            frame[c] = pd.Categorical.from_codes(codes, categories=_BOOL_WORDS)
        else:
            reread.append(c)
    if reread:
        try:
            text = _read_cells(body, header, file, usecols=reread)
        except ValueError:  # pandas refuses usecols when the first record is one field long
            return None
        for c in reread:
            frame[c] = text[c]
    return _Typed(frame, tuple(texts), bool(reread))


#: The text a parser boolean stands for (category codes 0 and 1); both are boolean words of ours.
_BOOL_WORDS = pd.Index(["false", "true"], dtype=object)
#: The categories of a column of empty cells (every code -1).
_NO_WORDS = pd.Index([], dtype=object)


def _is_text(s: pd.Series) -> bool:
    """The column holds the cells' text (NaN where empty), as the parser inferred it."""
    if isinstance(s.dtype, pd.StringDtype):
        return True
    return s.dtype == object and pd.api.types.infer_dtype(s, skipna=True) in ("string", "empty")


def _parser_bools(s: pd.Series) -> bool:
    """A column the parser read as booleans (bool dtype, or object of True/False and NaN)."""
    if s.dtype == bool:
        return True
    return s.dtype == object and pd.api.types.infer_dtype(s, skipna=True) == "boolean"


def _read_cells(
    body: bytes, header: list[str], file: str, usecols: list[str] | None = None
) -> pd.DataFrame:
    """Every cell as text (empty cells NaN): the exact path."""
    return _read_csv(body, header, file, dtype=object, usecols=usecols)


def _distinct(cells: Any) -> bool:
    """Text cells (Arrow-backed) that are all non-empty and all different, counted by Arrow's
    hash (False when that cannot be told so cheaply: the caller then checks the objects)."""
    if isinstance(cells, np.ndarray):
        return False
    s, empty = cells
    arrow = _arrow_text(s)
    if arrow is None or empty.any():
        return False
    if len(arrow) > 1:  # ids in order (the usual table) are distinct without hashing them
        import pyarrow.compute as pc

        if pc.all(pc.greater(arrow.slice(1), arrow.slice(0, len(arrow) - 1))).as_py():
            return True
    return len(arrow.unique()) == len(s)


def _columns(frame: pd.DataFrame, header: list[str], *, strip: bool) -> dict[str, Any]:
    """Per column: the float64 values the C parser read, or the text cells (a Series, stripped
    when a cell may need it) and the mask of empty ones."""
    out: dict[str, Any] = {}
    for c in header:
        s = frame[c]
        if s.dtype.kind == "f":
            out[c] = s.to_numpy()
            continue
        empty = s.isna().to_numpy()
        if strip:
            s = s.astype(object).str.strip()  # Python's strip, whatever the parser's dtype
            empty = empty | (s == "").to_numpy(bool)
        out[c] = (s, empty)
    return out


def _drop_blank_rows(
    rows: np.ndarray, cols: dict[str, Any], widths: np.ndarray, width: int, file: str
) -> tuple[np.ndarray, dict[str, Any]]:
    """Refuse a short row (pandas pads it silently; the csv module's count decides); drop rows
    whose every cell is empty (blank lines)."""
    blank = np.logical_and.reduce(
        [np.isnan(v) if isinstance(v, np.ndarray) else v[1] for v in cols.values()]
    )
    counts = widths[1:]  # the header is record 0
    n = len(rows)
    counts = counts[:n] if len(counts) >= n else np.pad(counts, (0, n - len(counts)))
    short = (counts != width) & ~blank & (counts > 0)
    if short.any():
        i = int(np.flatnonzero(short)[0])
        raise DeliveryError(
            f"has {int(counts[i])} fields, the header has {width}", file=file, row=int(rows[i])
        )
    if blank.any():
        keep = ~blank
        cols = {
            c: v[keep]
            if isinstance(v, np.ndarray)
            else (v[0][keep].reset_index(drop=True), v[1][keep])
            for c, v in cols.items()
        }
        rows = rows[keep]
    return rows, cols


_NONFINITE = ("nan", "inf", "-inf", "+inf", "infinity", "-infinity", "+infinity")


def _convert_column(
    cells: Any, rows: np.ndarray, kind: str, col: str, file: str, required: bool
) -> pd.Series:
    """Vectorised type conversion of one column: stripped text cells, or float64 already read."""
    if isinstance(cells, np.ndarray):  # a number column the C parser read (empty cells are NaN)
        empty = np.isnan(cells)
        if required and empty.any():
            raise DeliveryError(
                "required value is empty", file=file, row=int(rows[empty][0]), field=col
            )
        return pd.Series(cells, dtype=float)
    cells, empty = cells
    if required and empty.any():
        raise DeliveryError(
            "required value is empty", file=file, row=int(rows[empty][0]), field=col
        )

    def bad(mask: np.ndarray, what: str) -> DeliveryError:
        i = int(np.flatnonzero(mask)[0])
        return DeliveryError(
            f"expected {what}, got {str(cells.iloc[i])!r}", file=file, row=int(rows[i]), field=col
        )

    if kind == "text":
        return pd.Series(_objects(cells, empty), dtype=object)
    if kind == "number":
        num = pd.to_numeric(cells.where(~empty, "nan"), errors="coerce").to_numpy(dtype=float)
        suspect = ~np.isfinite(num) & ~empty
        if suspect.any():
            nonfinite = suspect & (
                cells.str.lower().isin(_NONFINITE).to_numpy(bool) | np.isinf(num)
            )
            if nonfinite.any():
                raise bad(
                    nonfinite, "a finite number (leave the cell empty when the value is unknown)"
                )
            raise bad(suspect, "a number")
        return pd.Series(num, dtype=float)
    if kind == "bool":
        # a handful of distinct words: each lowered and looked up once, then spread by its code
        codes, words = pd.factorize(cells)
        lowered = pd.Series(words, dtype=object).str.lower()
        is_t = np.append(lowered.isin(BOOL_TRUE).to_numpy(bool), False)  # code -1 (empty): neither
        is_f = np.append(lowered.isin(BOOL_FALSE).to_numpy(bool), False)
        t, f = is_t[codes], is_f[codes]
        wrong = ~(t | f | empty)
        if wrong.any():
            raise bad(wrong, "true/false")
        out = np.full(len(cells), None, dtype=object)
        out[t], out[f] = True, False
        return pd.Series(out, dtype=object)
    if kind in ("date", "datetime"):
        text = pd.Series(_objects(cells, empty), dtype=object)
        parsed = (
            pd.to_datetime(text, format="ISO8601", errors="coerce", utc=False)
            if len(text)
            else pd.Series([], dtype="datetime64[ns]")
        )
        wrong = parsed.isna().to_numpy() & ~empty
        if kind == "date":
            wrong |= ~empty & (cells.str.len().to_numpy() != 10)
        if wrong.any():
            fmt = "YYYY-MM-DD" if kind == "date" else "ISO 8601 (YYYY-MM-DDTHH:MM:SS)"
            raise bad(wrong, f"a {kind} {fmt}")
        return text
    raise AssertionError(kind)


def _objects(cells: pd.Series, empty: np.ndarray) -> np.ndarray:
    """Python strings, None where empty; one string object per distinct text (the C parser shares
    them in object columns; Arrow text is factorized so repeated block / source texts are shared)."""
    if cells.dtype == object:
        out = cells.to_numpy(dtype=object, copy=True)
    else:
        codes, uniques = pd.factorize(cells)
        none = np.array([None], dtype=object)
        out = np.append(np.asarray(uniques, dtype=object), none)[codes]  # code -1 (NaN): None
    out[empty] = None
    return out


def rows_where(
    path: str | Path,
    where: dict[str, str],
    *,
    file: str,
    sha256: str | None = None,
    limits: Limits | None = None,
) -> list[int]:
    """The 1-based data rows of a delivered CSV table whose cells (stripped of surrounding
    whitespace) equal ``where``'s value in every named column (``{}``: every row); blank lines
    are counted but never selected, as :func:`parse_csv` numbers rows.

    What an auditor re-applies to a qcr.json evidence selector (``where``). The file is read
    once, under the table bounds (:class:`Limits`, by default the environment's), checked as
    UTF-8 and, when ``sha256`` is given, against that checksum before anything is parsed; every
    cell is read as text (no spec: the table's own header names the columns).

    Raises
    ------
    DeliveryError
        The file cannot be read, breaks a bound, is not UTF-8 or not CSV, has changed (its
        SHA-256 differs from ``sha256``), or has no column ``where`` names.
    """
    data = read_table_bytes(Path(path), file=file, limits=limits or Limits.from_env())
    if sha256 is not None and sha256_bytes(data) != sha256:
        raise DeliveryError("the file has changed since the check (SHA-256 differs)", file=file)
    body = utf8_body(data, file=file)
    del data
    header = header_names(body)
    missing = [c for c in where if c not in header]
    if missing:
        raise DeliveryError(
            f"no column {missing[0]!r} to select rows by (columns: {', '.join(header)})",
            file=file,
            line=1,
        )
    if not header:
        return []
    try:
        frame = _read_cells(body, header, file)
        counts = _records(body).widths[1:]  # fields per record, the header's first
    except (csv.Error, ValueError) as exc:  # e.g. duplicate column names
        raise DeliveryError(f"not a valid CSV table: {exc}", file=file) from None
    del body
    n, width = len(frame), len(header)
    counts = counts[:n] if len(counts) >= n else np.pad(counts, (0, n - len(counts)))
    keep = np.zeros(n, dtype=bool)
    for c in header:  # a row is blank when every cell is empty after stripping
        keep |= (frame[c].fillna("").astype(object).str.strip() != "").to_numpy(bool)
    # pandas pads a short record, and makes a first one a field too long an index: the bytes decide
    wrong = (counts != width) & (counts > 0) & (keep | (counts > width))
    if wrong.any():
        i = int(np.flatnonzero(wrong)[0])
        raise DeliveryError(
            f"has {int(counts[i])} fields, the header has {width}", file=file, row=i + 1
        )
    for col, value in where.items():
        keep &= (frame[col].fillna("").astype(object).str.strip() == value).to_numpy(bool)
    return (np.flatnonzero(keep) + 1).tolist()
