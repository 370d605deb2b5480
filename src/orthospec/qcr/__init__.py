"""Quality control records (QCRs): the document every report and the ledger are built from.

A package since issue 28: the document's columns and stable values (:mod:`.columns`), its building
(:mod:`.build`), reading it back (:mod:`.records`), the natural order of item ids (:mod:`.order`),
and one module per machine output (:mod:`.json`, :mod:`.csv`, :mod:`.parquet`, :mod:`.junit`)
behind one registry (:mod:`.formats`). ``from orthospec.qcr import X`` keeps working for every name
the modules had before the split.
"""

from __future__ import annotations

from .build import (  # noqa: F401  (re-exported: the names other modules and tests import)
    _CSV_SPECIAL,
    _FORMULA_AT,
    _LARGE,
    _XML_SPECIAL,
    BLOCK_CHUNK,
    COMPACT_VERDICTS,
    CSV_COLUMNS,
    PARQUET_COLUMNS,
    PARQUET_ROWS,
    ROWS_LISTED_MAX,
    SCHEMA_ID,
    SCHEMA_IDS,
    Output,
    _any_csv_special,
    _csv_cells,
    _encode_columns,
    _expand,
    _expand_stored,
    _formula_at,
    _full,
    _int_array,
    _iter_csv_records,
    _iter_junit_records,
    _json_texts,
    _numeric_column,
    _pass_message,
    _shown_unit,
    _uniform_order,
    _xml_special,
    all_records,
    atomic_write,
    block_columns,
    build_document,
    csv_safe,
    dumps,
    evidence_rows,
    evidence_text,
    frame_table,
    iter_csv,
    iter_dumps,
    iter_junit,
    iter_records,
    natural_key,
    natural_order,
    point_frame,
    point_rows,
    qcr_schema,
    record_groups,
    render_all,
    require_pyarrow,
    round_sig,
    stable,
    to_csv,
    to_junit,
    to_parquet,
    where_text,
    xml_text,
)

__all__ = ["BLOCK_CHUNK", "COMPACT_VERDICTS", "CSV_COLUMNS", "PARQUET_COLUMNS", "PARQUET_ROWS", "ROWS_LISTED_MAX", "SCHEMA_ID", "SCHEMA_IDS", "Output", "all_records", "block_columns", "build_document", "csv_safe", "dumps", "evidence_rows", "evidence_text", "frame_table", "iter_csv", "iter_dumps", "iter_junit", "iter_records", "natural_key", "natural_order", "point_frame", "point_rows", "qcr_schema", "record_groups", "render_all", "require_pyarrow", "round_sig", "stable", "to_csv", "to_junit", "to_parquet", "where_text", "xml_text"]
