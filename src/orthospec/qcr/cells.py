"""The text of one cell or one evidence entry, shared by the writers: spreadsheet-safe CSV cells,
XML-safe text, evidence in words, and the rows an evidence entry stands for.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import OrthospecError
from .columns import _LARGE

_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_safe(v: Any) -> Any:
    """Neutralise a spreadsheet formula (OWASP CSV injection): text starting with = + - @ tab CR
    gets a leading single quote. Numbers stay numbers (a negative dx is not a formula). A carriage
    return becomes a line feed: ``csv.writer`` (lineterminator ``\n``) would leave a lone CR
    unquoted, and a spreadsheet would split the row there; a LF is quoted."""
    if isinstance(v, str):
        if v.startswith(_FORMULA_START):
            v = "'" + v
        if "\r" in v:
            v = v.replace("\r\n", "\n").replace("\r", "\n")
    return v


class _SafeWriter:
    """csv.writer whose every cell passes through :func:`csv_safe`."""

    def __init__(self, buf: io.StringIO) -> None:
        self._w = csv.writer(buf, lineterminator="\n")

    def writerow(self, row: Iterable[Any]) -> None:
        self._w.writerow([csv_safe(v) for v in row])


_XML_BAD = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x84\x86-\x9f\ud800-\udfff\ufffe\uffff]")


def xml_text(v: Any) -> str:
    """Text that XML 1.0 can carry: control characters become visible \\xNN escapes."""
    return _XML_BAD.sub(lambda m: f"\\x{ord(m.group(0)):02x}", str(v))


def evidence_text(e: Mapping[str, Any]) -> str:
    """One evidence entry on one line: ``file#rows=1,2``, ``file#where=block=B02 (333412 rows)``,
    ``file#every row (n rows)``, ``file#yaml.path``."""
    out = str(e.get("file", ""))
    if e.get("rows"):
        out += "#rows=" + ",".join(map(str, e["rows"]))
    elif "where" in e:
        out += "#" + where_text(e)
    if e.get("path"):
        out += f"#{e['path']}"
    return out


def where_text(e: Mapping[str, Any]) -> str:
    """The rows a selector stands for, in words: ``where block = B02 (333412 rows)``."""
    where = e.get("where") or {}
    cond = " and ".join(f"{k} = {v}" for k, v in where.items())
    return (f"where {cond}" if cond else "every row") + f" ({e.get('rows_count', '?')} rows)"


def evidence_rows(entry: Mapping[str, Any], root: str | Path) -> list[int]:
    """The 1-based data rows an evidence entry stands for, re-read from the delivered file under
    ``root``: its listed ``rows``, or its ``where`` selector applied to the CSV table (cells
    stripped of surrounding whitespace, blank lines counted but never selected). The file must
    still have the entry's SHA-256 (OrthospecError otherwise): what an auditor re-applies."""
    if "where" not in entry:
        return list(entry.get("rows") or [])
    from ..delivery.table import rows_where  # the delivered table's own bounded parser

    rows = rows_where(Path(root) / str(entry["file"]), entry["where"] or {},
                      file=str(entry["file"]), sha256=entry.get("sha256"))
    if len(rows) != entry.get("rows_count", len(rows)):
        raise OrthospecError(
            f"{entry['file']}: the selector gives {len(rows)} rows, the record says "
            f"{entry.get('rows_count')}"
        )
    return rows


#: a cell holding one of these is quoted by csv.writer (a superset: such cells take csv.writer itself)
_CSV_SPECIAL = re.compile('[\n\r,"]')
_cell_buf = io.StringIO()
_cell_writer = csv.writer(_cell_buf, lineterminator="\n")


def _csv_cell(v: Any) -> str:
    """One cell, :func:`csv_safe` then exactly as ``csv.writer`` (QUOTE_MINIMAL) writes it in a line of
    several cells."""
    v = csv_safe(v)
    if type(v) is str and not _CSV_SPECIAL.search(v):
        return v
    _cell_buf.seek(0)
    _cell_buf.truncate()
    _cell_writer.writerow(["", v])
    return _cell_buf.getvalue()[1:-1]


def _csv_cells(values: list[Any]) -> list[str]:
    """Cells of one column, as :func:`_csv_cell` writes each: text without a formula start or a
    character to quote is kept as it is (checked over the column at once)."""
    try:
        joined = "\x00".join(values)  # text only (else TypeError); NUL is no csv special character
    except TypeError:
        return [_csv_cell(v) for v in values]
    if _any_csv_special(joined):
        return [_csv_cell(v) for v in values]
    if _formula_at(joined):  # a formula start at the start of a cell (or after a NUL: harmless)
        return [("'" + v) if v.startswith(_FORMULA_START) else v for v in values]
    return values


def _plain_cells(values: list[Any]) -> bool:
    """Every value is text that qcr.csv writes as it is (what :func:`_csv_cells` returns unchanged)."""
    try:
        joined = "\x00".join(values)
    except TypeError:
        return False
    return not _any_csv_special(joined) and not _formula_at(joined)


def _any_csv_special(text: str) -> bool:
    """``_CSV_SPECIAL.search(text)``, one fast substring search per character."""
    return any(c in text for c in '\n\r,"')


#: the bytes of :data:`_FORMULA_START`, as a table over byte values
_FORMULA_BYTE = np.zeros(256, dtype=bool)
_FORMULA_BYTE[[ord(c) for c in _FORMULA_START]] = True


def _formula_at(joined: str) -> bool:
    """``_FORMULA_AT.search(joined)`` (a formula start at the start of a NUL-joined cell); for ASCII
    text over the bytes, one pass, instead of the regular expression's match attempt per NUL."""
    if len(joined) < _LARGE or not joined.isascii():
        return bool(_FORMULA_AT.search(joined))
    b = np.frombuffer(joined.encode("ascii"), dtype=np.uint8)
    if not len(b):
        return False
    return bool(_FORMULA_BYTE[b[0]] or _FORMULA_BYTE[b[1:][b[:-1] == 0]].any())


#: a cell (of a NUL-joined column) starting with one of :data:`_FORMULA_START`
_FORMULA_AT = re.compile("(?:^|\x00)[" + re.escape("".join(_FORMULA_START)) + "]")


#: characters quoteattr/escape or xml_text would change: text without them is written as it is
_XML_SPECIAL = re.compile(
    "[&<>\"'\n\r\t\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x84\x86-\x9f\ud800-\udfff\ufffe\uffff]"
)
#: the ASCII characters :data:`_XML_SPECIAL` matches (bytes.translate deletes them in one C pass)
_XML_SPECIAL_ASCII = bytes(i for i in range(128) if _XML_SPECIAL.match(chr(i)))


def _xml_special(text: str) -> bool:
    """``_XML_SPECIAL.search(text)``; ASCII text by deleting those bytes (a tenth of the regex's time)."""
    if len(text) < _LARGE or not text.isascii():
        return bool(_XML_SPECIAL.search(text))
    b = text.encode("ascii")
    return len(b.translate(None, _XML_SPECIAL_ASCII)) != len(b)
