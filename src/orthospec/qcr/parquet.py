"""qcr.parquet: one row per record, the columns of docs/QCR.md's "Parquet table".
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from ..errors import OrthospecError
from ..present import cite
from .records import all_records

#: the columns of qcr.parquet, in order (docs/QCR.md "Parquet table"); one row per record
PARQUET_COLUMNS: tuple[tuple[str, str], ...] = (
    ("rule", "string"),
    ("title", "string"),
    ("clause", "string"),
    ("scope", "string"),
    ("item", "string"),
    ("level", "string"),
    ("consequence", "string"),
    ("manual", "bool"),
    ("verdict", "string"),
    ("measure", "string"),
    ("measured_value", "float64"),
    ("measured_text", "string"),
    ("measured_unit", "string"),
    ("requirement_op", "string"),
    ("requirement_value", "float64"),
    ("requirement_min", "float64"),
    ("requirement_max", "float64"),
    ("requirement_unit", "string"),
    ("requirement_text", "string"),
    ("message", "string"),
    ("evidence", "string"),
    ("waiver", "string"),
    ("waiver_requested", "string"),
    ("waived_verdict", "string"),
    ("reason", "string"),
)


#: records per Parquet row group (and per batch of Python values held while writing)
PARQUET_ROWS = 50_000


def _number(v: Any) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _text(v: Any) -> str | None:
    if v is None or _number(v) is not None:
        return None
    return ("true" if v else "false") if isinstance(v, bool) else str(v)


def _json_or_none(v: Any) -> str | None:
    return (
        None
        if v is None
        else json.dumps(v, ensure_ascii=False, sort_keys=True, separators=(",", ":"))
    )


def require_pyarrow() -> None:
    """OrthospecError (exit 2) before any work when ``--format parquet`` cannot be written."""
    try:
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise OrthospecError("--format parquet needs pyarrow: install orthospec[parquet]") from None


def to_parquet(doc: Mapping[str, Any]) -> bytes:
    """Every record (expanded) as one Parquet table, one row per record, typed columns
    (:data:`PARQUET_COLUMNS`); the same document gives the same bytes (no timestamps written).

    Raises OrthospecError when pyarrow is not installed (the ``[parquet]`` extra)."""
    require_pyarrow()
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = pa.schema(
        [
            pa.field(
                name, pa.bool_() if t == "bool" else pa.float64() if t == "float64" else pa.string()
            )
            for name, t in PARQUET_COLUMNS
        ],
        metadata={
            "orthospec.qcr.schema": str(doc.get("schema")),
            "orthospec.qcr.date": str(doc.get("date")),
            "orthospec.delivery": str((doc.get("delivery") or {}).get("id")),
        },
    )
    buf = pa.BufferOutputStream()
    cols: dict[str, list[Any]] = {name: [] for name, _ in PARQUET_COLUMNS}

    def flush(writer: Any) -> None:
        """One row group per PARQUET_ROWS records: Python objects held for one group only."""
        writer.write_table(
            pa.table(
                {
                    name: pa.array(values, type=schema.field(name).type)
                    for name, values in cols.items()
                },
                schema=schema,
            )
        )
        for values in cols.values():
            values.clear()

    n = 0
    with pq.ParquetWriter(buf, schema, compression="zstd", store_schema=True) as writer:
        for n, r in enumerate(all_records(doc), start=1):
            req = r.get("requirement") or {}
            value = r["measured"].get("value")
            row = {
                "rule": r["rule"],
                "title": r.get("title"),
                "clause": cite(r.get("clause"), "columns"),
                "scope": r.get("scope"),
                "item": r["item"],
                "level": r.get("level"),
                "consequence": r.get("consequence"),
                "manual": bool(r.get("manual", False)),
                "verdict": r["verdict"],
                "measure": r.get("measure"),
                "measured_value": _number(value),
                "measured_text": _text(value),
                "measured_unit": r["measured"].get("unit"),
                "requirement_op": req.get("op"),
                "requirement_value": _number(req.get("value")),
                "requirement_min": _number(req.get("min")),
                "requirement_max": _number(req.get("max")),
                "requirement_unit": req.get("unit"),
                "requirement_text": req.get("text"),
                "message": r.get("message"),
                "evidence": _json_or_none(r.get("evidence") or []),
                "waiver": _json_or_none(r.get("waiver")),
                "waiver_requested": _json_or_none(r.get("waiver_requested")),
                "waived_verdict": r.get("waived_verdict"),
                "reason": r.get("reason"),
            }
            for name, values in cols.items():
                values.append(row[name])
            if n % PARQUET_ROWS == 0:
                flush(writer)
        if cols["rule"] or n == 0:
            flush(writer)
    return buf.getvalue().to_pybytes()
