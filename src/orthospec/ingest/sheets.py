"""Cells of a survey spreadsheet: CSV (any of , ; tab |, UTF-8 or Windows-1252), XLSX and ODS.

XLSX and ODS are read with python-calamine: the values a spreadsheet program stored, formulas
never evaluated (a formula cell without a stored result reads as empty, and the row that needs it
is refused naming the cell). Merged cells hold their value in the top-left cell only; a merged
range over header cells is spread across the columns it covers (a group title such as "GNSS"
over E/N/H), a merged range over data cells is refused (a value that stands for several rows is
not a measurement of each). Everything is bounded before it is read: the file's bytes, the
uncompressed size of an XLSX/ODS archive (a zip bomb), and the number of rows.
"""

from __future__ import annotations

import csv
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import DeliveryError
from ..limits import env_limit

#: a survey file larger than this is not a check point table (bytes; ORTHOSPEC_MAX_SHEET_BYTES)
SHEET_BYTES = 256 << 20
#: rows of one survey file (ORTHOSPEC_MAX_SHEET_ROWS); more is refused, naming the file
SHEET_ROWS = 2_000_000
#: how far the header search looks
HEADER_SCAN = 20

Cell = str | float | int | bool | None


@dataclass
class Cells:
    """A sheet's rows as read (text or numbers), with what the reading noticed."""

    file: str
    rows: Iterator[list[Cell]]
    #: merged ranges (first row, first col, last row, last col), 0-based, rows of the sheet
    merged: list[tuple[int, int, int, int]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    delimiter: str | None = None
    encoding: str | None = None
    sheet: str | None = None


def _limit(name: str, default: int) -> int:
    return env_limit(name, default, error=DeliveryError)


def read_cells(path: Path, name: str) -> Cells:
    """Open a survey file for reading its rows.

    Raises
    ------
    DeliveryError
        naming the file: too large, not a spreadsheet, an archive that inflates beyond the limit,
        no sheet with data.
    """
    limit = _limit("ORTHOSPEC_MAX_SHEET_BYTES", SHEET_BYTES)
    size = path.stat().st_size
    if size > limit:
        raise DeliveryError(
            f"{size} bytes, larger than ORTHOSPEC_MAX_SHEET_BYTES ({limit})", file=name
        )
    suffix = path.suffix.lower()
    if suffix in (".xlsx", ".xlsm", ".ods"):
        return _workbook(path, name, limit)
    return _csv(path, name)


def _csv(path: Path, name: str) -> Cells:
    head = path.open("rb").read(64 << 10)
    encoding = "utf-8-sig"
    notes = []
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:  # not a character cut by the 64 KiB window
            encoding = "cp1252"
            notes.append("not UTF-8: read as Windows-1252 (Western European)")
    text = head.decode(encoding, errors="replace")
    lines = [ln for ln in text.splitlines()[:50] if ln.strip()]
    delimiter = _delimiter(lines)
    if delimiter is None:
        raise DeliveryError(
            "cannot tell the column separator (tried , ; tab |): the first lines split "
            "into different numbers of columns with each",
            file=name,
        )
    if delimiter != ",":
        notes.append(f"columns separated by {_DELIM_NAME[delimiter]}")

    def rows() -> Iterator[list[Cell]]:
        with path.open("r", encoding=encoding, errors="strict", newline="") as fh:
            reader = csv.reader(fh, delimiter=delimiter)
            try:
                for row in reader:
                    yield [c if c.strip() else None for c in row]
            except UnicodeDecodeError as exc:
                raise DeliveryError(
                    f"not {encoding} text past byte {exc.start}: mixed encodings", file=name
                ) from None
            except csv.Error as exc:
                raise DeliveryError(f"line {reader.line_num}: {exc}", file=name) from None

    return Cells(
        name, rows(), notes=notes, delimiter=delimiter, encoding=encoding.replace("-sig", "")
    )


_DELIM_NAME = {",": "commas", ";": "semicolons", "\t": "tabs", "|": "vertical bars"}


def _delimiter(lines: list[str]) -> str | None:
    """The separator that splits the data lines into one constant number (> 1) of fields."""
    best = None
    for d in (";", "\t", "|", ","):
        counts = [len(next(csv.reader([ln], delimiter=d))) for ln in lines]
        tail = counts[-min(len(counts), 20) :]  # data lines (a title line above may differ)
        if tail and min(tail) > 1 and len(set(tail)) == 1 and (best is None or tail[0] > best[1]):
            best = (d, tail[0])
    return best[0] if best else None


def _workbook(path: Path, name: str, limit: int) -> Cells:
    try:
        with zipfile.ZipFile(path) as z:
            inflated = sum(i.file_size for i in z.infolist())
    except (zipfile.BadZipFile, OSError) as exc:
        raise DeliveryError(f"not a readable XLSX/ODS archive ({exc})", file=name) from None
    if inflated > 4 * limit:
        raise DeliveryError(
            f"the archive inflates to {inflated} bytes, more than 4 x ORTHOSPEC_MAX_SHEET_BYTES: "
            "refused unread (a zip bomb?)",
            file=name,
        )
    import python_calamine as pc

    try:
        wb = pc.CalamineWorkbook.from_path(str(path))
        sheet = None
        for i, meta in enumerate(wb.sheets_metadata):
            s = wb.get_sheet_by_index(i)
            if s.height and s.width and str(meta.visible).endswith("Visible"):
                sheet = s
                break
    except (
        Exception
    ) as exc:  # calamine's errors (XmlError, ZipError, CalamineError, PasswordError) share no base
        raise DeliveryError(
            f"cannot be read as a spreadsheet ({type(exc).__name__}: {exc})", file=name
        ) from None
    if sheet is None:
        raise DeliveryError("no visible sheet holds data", file=name)
    notes = (
        [f"sheet {sheet.name!r} (the first visible sheet with data)"]
        if len(wb.sheet_names) > 1
        else []
    )
    merged: list[tuple[int, int, int, int]] = []
    try:
        ranges = sheet.merged_cell_ranges or []
    except Exception:  # ODS: calamine does not report merges
        ranges = []
    for (r0, c0), (r1, c1) in ranges:
        merged.append((int(r0), int(c0), int(r1), int(c1)))
    start = sheet.start or (0, 0)
    r_off, c_off = int(start[0]), int(start[1])
    merged = [(a - r_off, b - c_off, c - r_off, d - c_off) for a, b, c, d in merged]

    def rows() -> Iterator[list[Cell]]:
        for row in sheet.iter_rows():
            yield [_cell(v) for v in row]

    return Cells(name, rows(), merged=merged, notes=notes, sheet=sheet.name)


def _cell(v: Any) -> Cell:
    if v is None or v == "":
        return None
    if isinstance(v, bool | int | float):
        return v
    if isinstance(v, str):
        return v if v.strip() else None
    return str(v)  # dates, times: text (an id or a date column, never a coordinate)


def count_guard(rows: Iterator[list[Cell]], name: str) -> Iterator[tuple[int, list[Cell]]]:
    """(1-based sheet row, cells), refusing past ORTHOSPEC_MAX_SHEET_ROWS rows."""
    limit = _limit("ORTHOSPEC_MAX_SHEET_ROWS", SHEET_ROWS)
    for i, row in enumerate(rows, start=1):
        if i > limit:
            raise DeliveryError(
                f"more than ORTHOSPEC_MAX_SHEET_ROWS ({limit}) rows: refused (a check point or "
                "GCP survey holds far fewer; raise the limit if this one is real)",
                file=name,
            )
        yield i, row


def text_of(v: Cell) -> str:
    if v is None:
        return ""
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return str(v).strip()


__all__ = ["Cells", "count_guard", "read_cells", "text_of"]
