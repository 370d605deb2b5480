"""The bounds a delivery table is held to before any CSV parser sees it, and its bytes as the
parser reads them.

Tables are bounded (file size, columns per line, bytes per cell; see :class:`Limits`), so a
hostile table fails in well under a second with file and row; :func:`utf8_body` checks the
encoding and gives one line-end convention.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DeliveryError
from ..limits import env_limit


@dataclass(frozen=True)
class Limits:
    """What a delivery table may make orthospec read; defaults no real delivery meets.

    A national images table of a million rows is about 300 MB with two dozen columns and cells
    under 1 kB; the defaults leave a wide margin and are set by environment variables
    ``ORTHOSPEC_MAX_TABLE_BYTES``, ``ORTHOSPEC_MAX_CSV_COLUMNS`` and ``ORTHOSPEC_MAX_CSV_CELL_BYTES``.
    """

    table_bytes: int = 2**30
    columns: int = 10_000
    cell_bytes: int = 64 * 2**20

    @classmethod
    def from_env(cls) -> Limits:
        d = cls()
        return cls(
            table_bytes=env_limit("ORTHOSPEC_MAX_TABLE_BYTES", d.table_bytes, error=DeliveryError),
            columns=env_limit("ORTHOSPEC_MAX_CSV_COLUMNS", d.columns, error=DeliveryError),
            cell_bytes=env_limit("ORTHOSPEC_MAX_CSV_CELL_BYTES", d.cell_bytes, error=DeliveryError),
        )


def read_table_bytes(path: Path, *, file: str, limits: Limits) -> bytes:
    """The bytes of a table file, refused (file named) when they break ``limits``, before parsing."""
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > limits.table_bytes:
                raise DeliveryError(
                    f"table of {size:,} bytes exceeds the limit of {limits.table_bytes:,} bytes "
                    "(ORTHOSPEC_MAX_TABLE_BYTES)",
                    file=file,
                )
            data = fh.read(limits.table_bytes + 1)  # a file grown since fstat is still bounded
    except OSError as exc:
        raise DeliveryError(f"cannot read table: {exc.strerror or exc}", file=file) from None
    if len(data) > limits.table_bytes:
        raise DeliveryError(
            f"table of {len(data):,}+ bytes exceeds the limit of {limits.table_bytes:,} bytes "
            "(ORTHOSPEC_MAX_TABLE_BYTES)",
            file=file,
        )
    check_csv_bounds(
        io.BytesIO(data), file=file, limits=limits
    )  # one read; BytesIO shares the bytes
    return data


def check_csv_bounds(fh: Any, *, file: str, limits: Limits, chunk: int = 16 * 2**20) -> None:
    """Refuse a table whose raw bytes break the limits, before any CSV parser sees it.

    One streaming pass over the bytes with numpy (C speed, memory bounded by ``chunk``): the
    longest run between delimiters (a cell; quoted commas split a cell, so this is a lower bound,
    the file-size limit is the hard one), the delimiters per physical line (columns) and a header
    whose quotes do not close on its own line. Row numbers count physical lines after the header.
    """
    run = 0  # bytes since the last delimiter, carried across chunks
    commas = 0  # commas on the current physical line so far
    line_len = 0  # bytes of the current physical line so far
    line = 1  # physical line of the chunk start
    header_done = False
    while True:
        data = _read_chunk(fh, chunk)
        if not data:
            break
        arr = np.frombuffer(data, dtype=np.uint8)
        header_done = header_done or _header_closed(data, chunk, file)
        limit = min(limits.cell_bytes, limits.columns - 1)
        if b"\r" not in data and _short_lines(data, line_len, limit):
            # no line is longer than a cell may be or has more bytes than columns (seen without
            # scanning every byte): carry the state on, as below
            last = max(data.rfind(b","), data.rfind(b"\n"))
            run = len(data) - 1 - last if last >= 0 else run + len(data)
            nls = _count(arr, 10)
            last_nl = data.rfind(b"\n")
            commas = data.count(b",", last_nl + 1) if nls else commas + data.count(b",")
            line_len = len(data) - 1 - last_nl if nls else line_len + len(data)
            line += nls
            continue
        # a line ends at LF, or at a CR not followed by LF (old Mac files); CRLF counts once
        ends = (
            (arr == 10) | ((arr == 13) & (np.append(arr[1:], 0) != 10))
            if b"\r" in data
            else arr == 10
        )
        nl = np.flatnonzero(ends)
        longest = line_len + len(data)
        if nl.size:
            lens = np.diff(nl, prepend=-1) - 1
            lens[0] += line_len
            line_len = len(data) - 1 - int(nl[-1])
            longest = max(int(lens.max()), line_len)
        else:
            line_len = longest
        if longest <= min(limits.cell_bytes, limits.columns - 1):
            # no line is longer than a cell may be or has more bytes than columns: nothing to refuse
            # here, only the carried state (bytes since the last delimiter, commas on the open line)
            last = max(data.rfind(b","), int(nl[-1]) if nl.size else -1)
            run = len(data) - 1 - last if last >= 0 else run + len(data)
            commas = data.count(b",", int(nl[-1]) + 1) if nl.size else commas + data.count(b",")
            line += int(nl.size)
            continue
        delim = np.flatnonzero((arr == 44) | ends)
        if delim.size == 0:
            run += len(data)
        else:
            gaps = np.diff(delim, prepend=-1 - run) - 1
            big = np.flatnonzero(gaps > limits.cell_bytes)
            if big.size:
                at = int(delim[big[0]])
                _refuse_cell(file, line + int(np.count_nonzero(ends[:at])), limits)
            run = len(data) - 1 - int(delim[-1])
        if run > limits.cell_bytes:
            _refuse_cell(file, line + int(np.count_nonzero(ends)), limits)
        is_nl = ends[delim] if delim.size else np.zeros(0, dtype=bool)
        nl_idx = np.flatnonzero(is_nl)
        if nl_idx.size:
            per_line = np.diff(nl_idx, prepend=-1) - 1
            per_line[0] += commas
            wide = np.flatnonzero(per_line + 1 > limits.columns)
            if wide.size:
                _refuse_columns(file, line + int(wide[0]), int(per_line[wide[0]]) + 1, limits)
            commas = int(delim.size - 1 - nl_idx[-1])
        else:
            commas += int(delim.size)
        if commas + 1 > limits.columns:
            _refuse_columns(file, line + int(nl_idx.size), commas + 1, limits)
        line += int(nl_idx.size)


def _read_chunk(fh: Any, chunk: int) -> bytes:
    """The next ``chunk`` bytes, and more while they end in CR: a CRLF stays in one chunk, so it
    ends one line, not two."""
    data = fh.read(chunk)
    while data.endswith(b"\r"):
        more = fh.read(1)
        if not more:
            break
        data += more
    return bytes(data)


def _header_closed(data: bytes, chunk: int, file: str) -> bool:
    """Whether the header row ends in ``data`` (the first chunk still holding it, or the whole
    rest); a header whose quotes do not close on its own line is refused."""
    ends = [i for i in (data.find(b"\n"), data.find(b"\r")) if i >= 0]
    nl = min(ends) if ends else -1
    if nl < 0 and len(data) >= chunk:
        return False
    head = data if nl < 0 else data[:nl]
    if head.count(b'"') % 2:
        raise DeliveryError(
            "the header row has an unclosed quote or a quoted line break; "
            "column names are single-line text",
            file=file,
            line=1,
        )
    return True


def _count(arr: np.ndarray, value: int, step: int = 1 << 18) -> int:
    """How many bytes of ``arr`` equal ``value``: numpy over cache-sized windows, a quarter of
    the time of ``bytes.count`` and no table-sized mask."""
    mask = np.empty(min(step, len(arr)), dtype=bool)
    n = 0
    for i in range(0, len(arr), step):
        window = arr[i : i + step]
        out = mask[: len(window)]
        np.equal(window, value, out=out)
        n += int(np.count_nonzero(out))
    return n


def _short_lines(data: bytes, carried: int, limit: int) -> bool:
    """True when no line of ``data`` (the first continuing a line of ``carried`` bytes) is longer
    than ``limit`` bytes, told from one ``find`` per block of about ``limit / 2`` bytes: when every
    block holds a line end, no two line ends are ``limit + 1`` bytes apart. False also when that
    cannot be told so (short limits, a long line): the caller then counts every line."""
    block = (limit + 2) // 2
    if block < 256:
        return False
    first = data.find(b"\n")
    if first < 0 or carried + first > limit or len(data) - 1 - data.rfind(b"\n") > limit:
        return False
    last = data.rfind(b"\n")
    find = data.find
    return all(find(b"\n", p, p + block) >= 0 for p in range(first + 1, last - block + 1, block))


def _refuse_cell(file: str, line: int, limits: Limits) -> None:
    raise DeliveryError(
        f"a cell longer than {limits.cell_bytes:,} bytes (ORTHOSPEC_MAX_CSV_CELL_BYTES); not read",
        file=file,
        row=line - 1 if line > 1 else None,
        line=None if line > 1 else 1,
    )


def _refuse_columns(file: str, line: int, n: int, limits: Limits) -> None:
    raise DeliveryError(
        f"{n:,}+ fields on one line exceed the limit of {limits.columns:,} columns "
        "(ORTHOSPEC_MAX_CSV_COLUMNS); not read",
        file=file,
        row=line - 1 if line > 1 else None,
        line=None if line > 1 else 1,
    )


_BOM = b"\xef\xbb\xbf"


def utf8_body(data: bytes, *, file: str, chunk: int = 1 << 24) -> bytes:
    """A table's bytes as the parser reads them: UTF-8 checked, no BOM, LF line ends.

    UTF-8 is checked in chunks (an incremental decoder), so a table is never held as a Python
    string beside its bytes; the byte offset of a bad sequence counts after a BOM, as
    ``bytes.decode("utf-8-sig")`` reports it. CR-only and CRLF line ends become LF (one
    convention for the parsers below); ``\\r`` is one byte in UTF-8, so this is exact on bytes.
    """
    import codecs

    if data.startswith(_BOM):
        data = data[len(_BOM) :]
    view = memoryview(data)
    dec = codecs.getincrementaldecoder("utf-8")()
    # ASCII is UTF-8: one C scan instead of decoding (a national check-point table is plain ASCII)
    for start in range(0, max(len(data), 1) if not data.isascii() else 0, chunk):
        pending = len(dec.getstate()[0])
        try:
            dec.decode(view[start : start + chunk], final=start + chunk >= len(data))
        except UnicodeDecodeError as exc:
            raise DeliveryError(
                f"not UTF-8 text (byte {start - pending + exc.start})", file=file
            ) from None
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    return data
