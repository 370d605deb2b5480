"""Quality control records (QCRs): the document every report and the ledger are built from.

A package since issue 28: the document's columns and stable values (:mod:`.columns`), its building
(:mod:`.build`), reading it back (:mod:`.records`), the natural order of item ids (:mod:`.order`),
and one module per machine output (:mod:`.json`, :mod:`.csv`, :mod:`.parquet`, :mod:`.junit`)
behind one registry (:mod:`.formats`). ``from orthospec.qcr import X`` keeps working for every name
the modules had before the split.
"""

from __future__ import annotations

# re-exported: every name other modules and tests imported from qcr.py before the split
from ..outputs import (  # noqa: F401
    atomic_write,
)
from ..qcr_model import (
    SCHEMA_IDS,
    qcr_schema,
)
from .blocks import (
    BLOCK_CHUNK,
)
from .build import (  # noqa: F401
    _int_array,
    build_document,
    iter_records,
)
from .cells import (  # noqa: F401
    _CSV_SPECIAL,
    _FORMULA_AT,
    _XML_SPECIAL,
    _any_csv_special,
    _csv_cells,
    _formula_at,
    _xml_special,
    csv_safe,
    evidence_rows,
    evidence_text,
    where_text,
    xml_text,
)
from .columns import (  # noqa: F401
    _LARGE,
    COMPACT_VERDICTS,
    ROWS_LISTED_MAX,
    SCHEMA_ID,
    _full,
    _numeric_column,
    _pass_message,
    _shown_unit,
    frame_table,
    point_frame,
    point_rows,
    round_sig,
    stable,
)
from .csv import (  # noqa: F401
    CSV_COLUMNS,
    _iter_csv_records,
    iter_csv,
    to_csv,
)
from .formats import (
    Output,
    render_all,
)
from .json import (  # noqa: F401
    _encode_columns,
    _json_texts,
    dumps,
    iter_dumps,
)
from .junit import (  # noqa: F401
    _iter_junit_records,
    iter_junit,
)
from .order import (  # noqa: F401
    _uniform_order,
    natural_key,
    natural_order,
)
from .parquet import (
    PARQUET_COLUMNS,
    PARQUET_ROWS,
    require_pyarrow,
    to_parquet,
)
from .records import (  # noqa: F401
    _expand,
    _expand_stored,
    all_records,
    block_columns,
    record_groups,
)

__all__ = [
    "BLOCK_CHUNK",
    "COMPACT_VERDICTS",
    "CSV_COLUMNS",
    "PARQUET_COLUMNS",
    "PARQUET_ROWS",
    "ROWS_LISTED_MAX",
    "SCHEMA_ID",
    "SCHEMA_IDS",
    "Output",
    "all_records",
    "block_columns",
    "build_document",
    "csv_safe",
    "dumps",
    "evidence_rows",
    "evidence_text",
    "frame_table",
    "iter_csv",
    "iter_dumps",
    "iter_junit",
    "iter_records",
    "natural_key",
    "natural_order",
    "point_frame",
    "point_rows",
    "qcr_schema",
    "record_groups",
    "render_all",
    "require_pyarrow",
    "round_sig",
    "stable",
    "to_csv",
    "to_parquet",
    "where_text",
    "xml_text",
]
