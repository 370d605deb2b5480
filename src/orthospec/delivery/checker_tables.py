"""The checker folder's tables: the external QC's check point measurements (JRC §12.6).

``CHECKER_DIR/tables/checkpoints.csv`` holds the check points the external QC measured on the
delivered orthoimages: the columns of the delivery convention's ``checkpoints`` table
(specs/delivery-tables.yaml) plus the measurement's provenance (issue 29: method, score, decision,
reason, reference file and its SHA-256, the SHA-256 of the image measured, chip size, tool version).
It is parsed by the one CSV table parser (``delivery.table.parse_csv``), with the same limits,
types and messages naming file, row and column as a delivery table.

The external-accuracy rules (JRC §12.4-§12.8, NSSDA, USGS, ASPRS) read these measurements; the
delivery's own check point table is the contractor's internal QC (§12.5, §7.2 "the same quality
requirements apply"). delivery/in_force.py puts the two in place for one evaluation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import DeliveryError, OrthospecError
from ..units import canonical
from .checker import CHECKPOINTS_TABLE, Checker
from .convention import ColumnSpec, TableSpec, table_specs

if TYPE_CHECKING:
    from .reader import Delivery, Table

#: the file name of the checker's table in evidence and messages ("checker:" marks the checker's side)
EVIDENCE_PREFIX = "checker:"
DECISIONS = ("accepted", "by_hand")
_SHA = re.compile(r"^[0-9a-fA-F]{64}$")

#: provenance of each measurement, beside the delivery convention's checkpoints columns
PROVENANCE: dict[str, ColumnSpec] = {
    c.name: c
    for c in (
        ColumnSpec(
            "method",
            "text",
            None,
            False,
            "How the image position was measured (e.g. phase_correlation, ncc, by_hand).",
        ),
        ColumnSpec(
            "score",
            "number",
            "1",
            False,
            "Match-quality score of an automatic measurement (peak ratio or correlation).",
        ),
        ColumnSpec(
            "decision",
            "text",
            None,
            False,
            "accepted (automatic match kept) or by_hand (measured by the checker).",
        ),
        ColumnSpec(
            "reason",
            "text",
            None,
            False,
            "Why the point was measured by hand (low texture, cloud, change, edge of image).",
        ),
        ColumnSpec(
            "reference_file",
            "text",
            None,
            False,
            "The reference chip or orthoimage the point was matched "
            "against (path in the checker folder, or as the checker keeps it).",
        ),
        ColumnSpec("reference_sha256", "text", None, False, "SHA-256 of the reference file."),
        ColumnSpec(
            "image_sha256",
            "text",
            None,
            False,
            "SHA-256 of the delivered image the point was measured on "
            "(written by the tool): a different image at check time leaves the point unused.",
        ),
        ColumnSpec("chip_px", "number", "1", False, "Chip size of the match, in pixels.", 0),
        ColumnSpec(
            "tool_version", "text", None, False, "orthospec version that measured the point."
        ),
    )
}


@lru_cache(maxsize=1)
def checkpoints_spec() -> TableSpec:
    """The checker's check point table: the delivery convention's columns plus :data:`PROVENANCE`."""
    base = table_specs()["checkpoints"]
    return replace(
        base,
        name="checkpoints",
        description=(
            "The external QC's check points measured on the delivered orthoimages (JRC §12.6), with the "
            "provenance of each measurement (issue 29)."
        ),
        columns={**base.columns, **PROVENANCE},
    )


@dataclass(frozen=True)
class CheckerPoints:
    """The checker's table as read: the typed table (evidence file ``checker:tables/checkpoints.csv``)."""

    table: Table
    path: Path


def read_checker_points(chk: Checker, d: Delivery) -> CheckerPoints | None:
    """The checker folder's tables/checkpoints.csv, parsed and checked, or None when the folder has none.

    Raises
    ------
    OrthospecError
        (exit 2) a bad table: header, types, an empty required cell, a duplicate point id, a block
        the delivery does not declare, a ``decision`` or SHA-256 cell that is no such value, a
        coordinate unit other than the delivery's project.crs unit: file, row and column named.
    """
    from .reader import Limits, Table, parse_csv, read_table_bytes, utf8_body

    p = chk.file(CHECKPOINTS_TABLE)
    if p is None:
        return None
    shown = f"{chk.folder}/{CHECKPOINTS_TABLE}" if chk.folder is not None else CHECKPOINTS_TABLE
    data = read_table_bytes(p, file=shown, limits=Limits.from_env())
    from ..provenance import sha256_bytes

    sha = sha256_bytes(data)
    spec = checkpoints_spec()
    df = parse_csv(utf8_body(data, file=shown), spec, file=shown)
    _check_cells(df, shown)
    d._check_blocks(df, shown)  # the one test that a block cell names a block of the delivery
    unit = chk.model.units.get("checkpoints", "m")
    crs_unit = d.crs_unit
    if crs_unit is not None and canonical(unit) != crs_unit:
        raise OrthospecError(
            f"checker file {chk.at('units')}: the coordinates of {CHECKPOINTS_TABLE} are in "
            f"{unit}, but the delivery's project.crs axes are in {crs_unit}: the check points "
            f"are positions in the map projection; set units: {{checkpoints: {crs_unit}}}"
        )
    units = {
        col: canonical(unit if cs.unit == "length" else cs.unit)
        for col, cs in spec.columns.items()
        if cs.type == "number" and col in df and cs.unit
    }
    table = Table("checkpoints", spec, EVIDENCE_PREFIX + CHECKPOINTS_TABLE, sha, df, units)
    return CheckerPoints(table, p)


def _check_cells(df: pd.DataFrame, file: str) -> None:
    """``decision`` is accepted or by_hand; the SHA-256 columns hold 64 hex digits (written by the tool)."""
    if "decision" in df:
        cells = df["decision"]
        bad = cells.notna() & ~cells.isin(DECISIONS)
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise DeliveryError(
                f"decision {cells.iloc[i]!r} is not one of {', '.join(DECISIONS)}",
                file=file,
                row=int(df["_row"].iloc[i]),
                field="decision",
            )
    for col in ("image_sha256", "reference_sha256"):
        if col not in df:
            continue
        cells = df[col]
        bad = cells.notna() & ~cells.astype(str).str.fullmatch(_SHA.pattern)
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise DeliveryError(
                f"{cells.iloc[i]!r} is not a SHA-256 (64 hexadecimal digits)",
                file=file,
                row=int(df["_row"].iloc[i]),
                field=col,
            )


def checkpoints_schema() -> dict[str, object]:
    """The published JSON Schema of one row of CHECKER_DIR/tables/checkpoints.csv
    (specs/schema/checker-checkpoints.schema.json): columns, types, units, which are required."""
    kinds = {
        "text": "string",
        "number": "number",
        "bool": "boolean",
        "date": "string",
        "datetime": "string",
    }
    spec = checkpoints_spec()
    props: dict[str, object] = {}
    for name, cs in spec.columns.items():
        p: dict[str, object] = {
            "type": [kinds[cs.type], "null"] if not cs.required else kinds[cs.type],
            "description": cs.description,
        }
        if cs.unit:
            p["x-unit"] = (
                "the checker's units.checkpoints (m by default)" if cs.unit == "length" else cs.unit
            )
        if cs.min is not None:
            p["minimum"] = cs.min
        if name == "decision":
            p["enum"] = [*DECISIONS, None]
        if name in ("image_sha256", "reference_sha256"):
            p["pattern"] = _SHA.pattern
        props[name] = p
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://orthospec.dev/schema/checker-checkpoints.schema.json",
        "title": "orthospec checker folder: tables/checkpoints.csv (one row)",
        "description": (
            "The external QC's check point measurements (JRC §12.6): a UTF-8 CSV with a header row, "
            "one row per point, read by the delivery convention's table parser. The columns of the "
            "delivery's checkpoints table plus each measurement's provenance (docs/CHECKER.md)."
        ),
        "type": "object",
        "additionalProperties": False,
        "required": spec.required,
        "properties": props,
    }
