"""The record shape of a CSV table's bytes: fields per record and whether a cell may need
stripping, counted vectorised (numpy over the bytes, or Arrow's buffers of the parsed cells)
exactly as the ``csv`` module counts them. Used by the table parser (:mod:`.table`).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from .table_bounds import _count


@dataclass(frozen=True)
class _Typed:
    """What the C parser's own type inference gave, checked against the spec: ``frame`` holds
    float64 number columns and text columns whose cells are the delivered text (NaN where empty;
    as categories where the parser's booleans or empty cells stand for that text);
    ``texts`` names the columns the parser inferred as text (their cells are what it read);
    ``reread``: some column was read a second time as text, so the parser's cells are not all
    from one pass (the record widths are then counted from the bytes)."""

    frame: pd.DataFrame
    texts: tuple[str, ...]
    reread: bool


#: Bytes at a cell's edge that str.strip() may remove: ASCII whitespace and the \x1c-\x1f
#: separators, and any non-ASCII byte (the Unicode spaces; letters are stripped of nothing).
_EDGE = np.zeros(256, dtype=bool)
_EDGE[[9, 10, 11, 12, 13, 28, 29, 30, 31, 32]] = True
_EDGE[0x80:] = True


def _shape_from_cells(body: bytes, typed: _Typed, header: list[str]) -> _Shape | None:
    """The record widths and padding from the parsed cells, when that is exact; else None.

    pandas pads a short record with empty cells and raises on a long one, except that a first
    data record one field longer than the header becomes an index. So: when the first data
    record has the header's width, every record has at most that width, and every comma of the
    table is either a delimiter or inside a cell; the table has exactly ``width - 1`` delimiters
    per record (no record short) iff its commas are ``(width - 1) * records`` plus the commas in
    its cells. Only text columns can hold a comma. Needs the cells of one pass as Arrow arrays
    (their bytes are counted, not the strings); a table with a NUL byte (which the parser and
    the csv module may read differently), an all-empty record (a blank line has no delimiters) or a
    re-read column goes by bytes.
    """
    frame = typed.frame
    if typed.reread or b"\x00" in body or not len(frame):
        return None
    arrays = [_arrow_text(frame[c]) for c in typed.texts]
    if any(a is None for a in arrays):
        return None
    if np.logical_and.reduce([frame[c].isna().to_numpy() for c in header]).any():
        return None
    if not _first_record_fits(body, len(header)):
        return None
    commas, padded = 0, False
    for a in arrays:
        for chunk in a.chunks:
            counted = _cell_bytes(chunk)
            if counted is None:
                return None
            commas += counted[0]
            padded = padded or counted[1]
    if (
        _count(np.frombuffer(body, dtype=np.uint8), 44)
        != (len(header) - 1) * (len(frame) + 1) + commas
    ):
        return None
    return _Shape(np.full(len(frame) + 1, len(header), dtype=np.int64), padded)


def _arrow_text(s: pd.Series) -> Any:
    """The pyarrow ChunkedArray behind an Arrow-backed text column (pandas 3's ``str``), else None."""
    if isinstance(s.dtype, pd.StringDtype) and s.dtype.storage == "pyarrow":
        return s.array.__arrow_array__()
    return None


def _cell_bytes(chunk: Any) -> tuple[int, bool] | None:
    """Commas in the cells of one Arrow string array, and whether a cell begins or ends with a
    byte str.strip() might remove (:data:`_EDGE`). Read from its offsets and data buffers (None
    for another layout than string / large_string)."""
    import pyarrow as pa

    if not (pa.types.is_string(chunk.type) or pa.types.is_large_string(chunk.type)):
        return None
    offset_type = np.int64 if pa.types.is_large_string(chunk.type) else np.int32
    _, offsets_buf, data_buf = chunk.buffers()
    if data_buf is None or len(chunk) == 0:
        return 0, False
    stored = np.frombuffer(offsets_buf, dtype=offset_type)[
        chunk.offset : chunk.offset + len(chunk) + 1
    ]
    offsets = stored.astype(np.int64, copy=False)
    data = np.frombuffer(data_buf, dtype=np.uint8)
    start, stop = offsets[:-1], offsets[1:]
    full = stop > start
    first, last = data[start[full]], data[stop[full] - 1]
    padded = bool(_EDGE[first].any() or _EDGE[last].any())
    commas = _count(data[int(offsets[0]) : int(offsets[-1])], 44)
    return commas, padded


def _first_record_fits(body: bytes, width: int) -> bool:
    """The header and first data record have ``width`` fields each (counted on a prefix of the
    bytes cut at a line end; False when the prefix cannot tell)."""
    cut = body.find(b"\n", 1 << 16)
    head = body if cut < 0 else body[: cut + 1]
    shape = _records_fast(head)
    return shape is not None and len(shape.widths) >= 2 and bool((shape.widths[:2] == width).all())


@dataclass(frozen=True)
class _Shape:
    """What the bytes say about the records: fields per record (header first), and whether a
    cell may begin or end with whitespace (else nothing needs stripping)."""

    widths: np.ndarray
    padded: bool


#: Whitespace str.strip() removes that is rare in tables (tabs, \v, \f, the separators
#: \x1c-\x1f): a table holding one is stripped cell by cell.
_RARE_SPACE = tuple(bytes([c]) for c in (9, 11, 12, 28, 29, 30, 31))


def _records(body: bytes) -> _Shape:
    """Fields per CSV record exactly as the ``csv`` module counts them, from a vectorised pass
    over the bytes when every quote is a plain one (:func:`_records_fast`), else the csv module."""
    fast = _records_fast(body)
    if fast is not None:
        return fast
    widths = np.fromiter(map(len, csv.reader(io.StringIO(body.decode("utf-8")))), dtype=np.int64)
    return _Shape(widths, True)


def _records_fast(body: bytes, chunk: int = 1 << 20) -> _Shape | None:
    """Record widths from the positions of quotes, delimiters and line ends (no per-byte state).

    Quotes alternate open/close (a doubled quote closes and reopens); delimiters and line ends
    between an open and its close are content. None when a quote opens mid-field or closes
    before the field ends (the csv module's state machine decides those) or stays open, or the
    table holds a NUL byte (the csv module refuses it, and says so). ``padded``: a space or a
    non-ASCII byte (Unicode spaces) sits beside a delimiter or line end, or inside a quote's
    edge (there a line end too), or the table holds a rare whitespace byte.
    """
    if b"\x00" in body:
        return None
    n = len(body)
    parity, carry, prev = 0, 0, 10
    padded = any(c in body for c in _RARE_SPACE)
    widths: list[np.ndarray] = []
    for start in range(0, n, chunk):
        view = np.frombuffer(body, dtype=np.uint8, count=min(chunk + 1, n - start), offset=start)
        m = min(chunk, n - start)
        ext = np.empty(m + 2, dtype=np.uint8)  # the chunk with its neighbouring bytes
        ext[0], ext[1:-1], ext[-1] = prev, view[:m], view[m] if len(view) > m else 10
        arr = ext[1:-1]
        is44 = arr == 44
        is10 = arr == 10
        ends = np.flatnonzero(is10)
        quotes = _quotes(ext, parity)
        if quotes is None:
            return None
        opens, closes, parity = quotes
        cpos = np.flatnonzero(is44)  # searchsorted(cpos, p): the delimiters before byte p
        padded = padded or _padded(ext, np.concatenate([cpos, ends]), opens, closes)
        if opens.size:
            ends = ends[~_quoted(ends, opens, closes)]
        per = np.diff(np.searchsorted(cpos, ends), prepend=0).astype(np.int64)
        tail = int(len(cpos) - (np.searchsorted(cpos, ends[-1]) if ends.size else 0))
        if opens.size:
            inside = (np.searchsorted(cpos, closes) - np.searchsorted(cpos, opens + 1)).astype(
                np.int64
            )
            bucket = np.bincount(
                np.searchsorted(ends, opens), weights=inside, minlength=len(ends) + 1
            ).astype(np.int64)
            per -= bucket[:-1]
            tail -= int(bucket[-1])
        if ends.size:
            per[0] += carry
            widths.append(per + 1)
            carry = tail
        else:
            carry += tail
        prev = int(arr[-1])
    if parity:
        return None
    if n and body[-1:] != b"\n":
        widths.append(np.array([carry + 1], dtype=np.int64))
    if n and not padded:
        first, last = body[0], body[-1]
        padded = first == 32 or first >= 0x80 or last == 32 or last >= 0x80
    out = (
        np.concatenate(widths).astype(np.int64, copy=False)
        if widths
        else np.zeros(0, dtype=np.int64)
    )
    return _Shape(out, padded)


def _quotes(ext: np.ndarray, parity: int) -> tuple[np.ndarray, np.ndarray, int] | None:
    """Open and close positions of the quotes of one chunk (``ext``: the chunk with its
    neighbouring bytes), a virtual open at -1 / close at the end when a quote spans the edge, and
    the parity carried on; None when a quote is not at a field's edge (or doubling a quote)."""
    m = len(ext) - 2
    qi = np.flatnonzero(ext[1:-1] == 34)
    if parity:
        qi = np.concatenate([[-1], qi])  # the chunk starts inside a quoted field
    opens, closes = qi[0::2], qi[1::2]
    parity = len(qi) % 2
    if parity:
        closes = np.append(closes, m)  # still open at the chunk's end
    real_opens, real_closes = opens[opens >= 0], closes[closes < m]
    if not (
        np.isin(ext[real_opens], (44, 10, 34)).all()
        and np.isin(ext[real_closes + 2], (44, 10, 34)).all()
    ):
        return None
    return opens, closes, parity


def _padded(ext: np.ndarray, structure: np.ndarray, opens: np.ndarray, closes: np.ndarray) -> bool:
    """A space or non-ASCII byte beside a delimiter or line end outside quotes, or a space, line
    end or non-ASCII byte just inside a quote: a cell there may need stripping. ``structure``:
    the positions of the delimiters and line ends (only their neighbours are looked at)."""
    m = len(ext) - 2
    before, after = ext[structure], ext[structure + 2]  # ext is the chunk shifted by one byte
    near = structure[(before == 32) | (before >= 0x80) | (after == 32) | (after >= 0x80)]
    if opens.size:
        near = near[~_quoted(near, opens, closes)]
    edges = np.concatenate([ext[opens[opens >= 0] + 2], ext[closes[closes < m]]])
    return bool(near.size) or bool(((edges == 32) | (edges == 10) | (edges >= 0x80)).any())


def _quoted(pos: np.ndarray, opens: np.ndarray, closes: np.ndarray) -> np.ndarray:
    """Mask of the positions (never a quote) that lie between an open quote and its close."""
    j = np.searchsorted(closes, pos)
    inside = j < len(opens)
    inside[inside] = opens[j[inside]] < pos[inside]
    return inside
