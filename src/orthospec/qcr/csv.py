"""qcr.csv: one row per record, spreadsheet-safe, written block by block.
"""

from __future__ import annotations

import io
from collections.abc import Iterator, Mapping
from typing import Any

from ..present import cite
from .blocks import _merged, _rule_parts
from .cells import _SafeWriter, evidence_text
from .records import all_records

# --- writers --------------------------------------------------------------------------------

CSV_COLUMNS = ["rule", "clause", "scope", "item", "level", "consequence", "verdict", "measure",
               "measured_value", "measured_unit", "requirement", "evidence", "message", "reason"]


def to_csv(doc: Mapping[str, Any]) -> str:
    """qcr.csv: one row per record (expanded), spreadsheet-safe."""
    return "".join(iter_csv(doc))


def _csv_row(r: Mapping[str, Any]) -> list[Any]:
    """One record's qcr.csv cells (before :func:`csv_safe`)."""
    ev = "; ".join(evidence_text(e) for e in r["evidence"])
    return [
        r["rule"],
        cite(r["clause"], "columns"),
        r["scope"],
        r["item"],
        r["level"],
        r["consequence"],
        r["verdict"],
        r["measure"],
        "" if r["measured"]["value"] is None else r["measured"]["value"],
        r["measured"]["unit"] or "",
        r["requirement"].get("text", ""),
        ev,
        r["message"],
        r.get("reason") or "",
    ]


def _iter_csv_records(doc: Mapping[str, Any], *, rows_per_piece: int = 2000) -> Iterator[str]:
    """qcr.csv record by record through :func:`all_records`: the reference the block writer
    (:func:`iter_csv`) matches byte for byte, and the path for version 1 documents."""
    buf = io.StringIO()
    w = _SafeWriter(buf)
    w.writerow(CSV_COLUMNS)
    for n, r in enumerate(all_records(doc), start=1):
        if n % rows_per_piece == 0:
            yield buf.getvalue()
            buf.seek(0)
            buf.truncate()
        w.writerow(_csv_row(r))
    yield buf.getvalue()


def iter_csv(doc: Mapping[str, Any], *, rows_per_piece: int = 2000) -> Iterator[str]:
    """qcr.csv as a stream of pieces: records in full row by row, each rule's compact block a slice
    of items at a time (:class:`_Block`), the same bytes as :func:`_iter_csv_records` without a dict
    per record (issue 14: a million check points)."""
    if "compact" not in doc:
        yield from _iter_csv_records(doc, rows_per_piece=rows_per_piece)
        return
    buf = io.StringIO()
    w = _SafeWriter(buf)
    w.writerow(CSV_COLUMNS)
    rows = 0
    for summary, full, block in _rule_parts(doc):
        if summary is None:
            for r in full:
                w.writerow(_csv_row(dict(r)))
            continue
        for part in _merged(summary, full, block):
            if isinstance(part, dict):
                w.writerow(_csv_row(part))
                rows += 1
            else:
                assert block is not None
                yield buf.getvalue()
                buf.seek(0)
                buf.truncate()
                yield block.csv_text(*part)
                rows += part[1] - part[0]
            if rows >= rows_per_piece:
                yield buf.getvalue()
                buf.seek(0)
                buf.truncate()
                rows = 0
    yield buf.getvalue()
