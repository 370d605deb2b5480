"""Generic measures every delivery table and the manifest expose to rules without code.

``<table>.<column>`` (the raw column at the table's scope), ``<table>.present``,
``<table>.count``, ``<table>.count_per_block``, ``<table>.<column>.complete`` and
``manifest.<dotted.path>``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ..delivery.convention import table_specs
from ..delivery.reader import MANIFEST, Delivery
from ..errors import OrthospecError
from ..provenance import Evidence
from ..units import canonical
from .registry import Measured, RowEvidence

_COL_UNIT = {"text": "text", "bool": "bool", "date": "date", "datetime": "date"}


def info(name: str) -> tuple[str, str] | None:
    """(scope, unit) of a generic measure name, or None when it is not one."""
    if name.startswith("manifest."):
        return "delivery", "any"
    parts = name.split(".")
    specs = table_specs()
    if parts[0] not in specs:
        return None
    spec = specs[parts[0]]
    if len(parts) == 2:
        if parts[1] == "present":
            return "delivery", "bool"
        if parts[1] == "count":
            return "delivery", "1"
        if parts[1] == "count_per_block":
            return ("block", "1") if "block" in spec.columns else None
        col = spec.columns.get(parts[1])
        if col is None or spec.id is None:
            return None
        return spec.scope, _unit(col.type, col.unit)
    if len(parts) == 3 and parts[2] == "complete" and parts[1] in spec.columns:
        return "delivery", "%"
    if len(parts) == 3 and parts[2] in AGGREGATES and parts[1] in spec.columns:
        col = spec.columns[parts[1]]
        return ("delivery", _unit(col.type, col.unit)) if col.type == "number" else None
    return None


#: ``<table>.<column>.<aggregate>`` at delivery scope, over the table's non-empty values
AGGREGATES = {
    "mean": np.nanmean,
    "max": np.nanmax,
    "min": np.nanmin,
    "max_abs": lambda a: np.nanmax(np.abs(a)),
    "mean_abs": lambda a: np.nanmean(np.abs(a)),
}


def _unit(kind: str, unit: str | None) -> str:
    if kind in _COL_UNIT:
        return _COL_UNIT[kind]
    if unit == "length":
        return "length"
    return canonical(unit or "1")


def compute(name: str, d: Delivery) -> Measured:
    found = info(name)
    assert found is not None
    scope, unit = found
    if name.startswith("manifest."):
        return _manifest(name, d)
    parts = name.split(".")
    tname = parts[0]
    t = d.table(tname)
    if parts[1] == "present":
        ev = (d.evidence(t.file),) if t else (d.manifest_evidence(f"tables.{tname}"),)
        return _one(name, "delivery", "bool", d.id, t is not None, ev)
    if t is None:
        note = d.table_absent_reason(tname)
        if scope == "delivery":
            return _one(name, scope, unit, d.id, None, (d.manifest_evidence("tables"),), note=note)
        return Measured(
            name,
            scope,
            unit,
            pd.Series(dtype=object),
            pd.Series(dtype=object),
            notes=pd.Series({"*": note}, dtype=object),
        )
    df = t.df
    if parts[1] == "count":
        return _one(name, scope, "1", d.id, float(len(df)), t.evidence(df["_row"]))
    if parts[1] == "count_per_block":
        blocks = d.block_ids
        counts = df.groupby(df["block"].astype(str))["_row"].agg(list)
        vals = pd.Series({b: float(len(counts.get(b, []))) for b in blocks}, dtype=float)
        per_block = pd.Series({b: t.evidence(counts.get(b, [])) for b in blocks}, dtype=object)
        return Measured(name, "block", "1", vals, per_block)
    col = parts[1]
    if len(parts) == 3 and parts[2] in AGGREGATES:
        col = parts[1]
        arr = df[col].to_numpy(float) if col in df else np.array([], dtype=float)
        have = ~np.isnan(arr)
        agg: Any = AGGREGATES[parts[2]]
        value = float(agg(arr)) if have.any() else None
        u = (
            (t.units.get(col) or canonical(d.manifest.units.get(tname, "m")))
            if unit == "length"
            else unit
        )
        return _one(
            name,
            "delivery",
            u,
            d.id,
            value,
            t.evidence(df["_row"][have] if have.any() else df["_row"]),
            note=None if value is not None else f"no values in column {col!r} of {t.file}",
        )
    if len(parts) == 3:  # .complete
        if col not in df:
            share = 0.0 if len(df) else None
            rows: Any = []
        else:
            # None, NaN (and pandas' NA) are what a blank cell reads as: not filled
            filled = df[col].notna()
            share = float(filled.mean() * 100.0) if len(df) else None
            rows = df.loc[~filled, "_row"] if len(df) else []
        return _one(
            name,
            "delivery",
            "%",
            d.id,
            share,
            t.evidence(rows if len(rows) else df["_row"]),
            note=None if col in df else f"column {col!r} absent from {t.file}",
        )
    ids = t.ids
    u = (
        (t.units.get(col) or canonical(d.manifest.units.get(tname, "m")))
        if unit == "length"
        else unit
    )
    if col not in df:
        vals = pd.Series([None] * len(df), index=ids.values, dtype=object)
        notes = pd.Series(
            [f"column {col!r} absent from {t.file}"] * len(df), index=ids.values, dtype=object
        )
    else:
        vals = pd.Series(df[col].values, index=ids.values)
        notes = None
    rows_ev = RowEvidence(
        t.file, t.sha256, pd.Series(df["_row"].to_numpy(), index=ids.astype(str).values)
    )
    return Measured(name, scope, u, vals, rows_ev, notes=notes)


def _one(
    name: str,
    scope: str,
    unit: str,
    item: str,
    value: Any,
    ev: tuple[Evidence, ...] | pd.Series,
    note: str | None = None,
) -> Measured:
    return Measured(
        name,
        scope,
        unit,
        pd.Series({item: value}, dtype=object),
        pd.Series({item: ev}, dtype=object),
        notes=pd.Series({item: note}, dtype=object) if note else None,
    )


def _manifest(name: str, d: Delivery) -> Measured:
    flat = d.flat_manifest()
    path = name[len("manifest.") :]
    ev = (d.manifest_evidence(path),)
    if name not in flat:
        return _one(name, "delivery", "any", d.id, None, ev, note=f"{MANIFEST} has no {path}")
    v = flat[name]
    if path.startswith(("documents.", "vectors.")) and isinstance(v, str):
        # a document or vector file counts only when it is really in the delivery, and not empty
        try:
            p = d.path(v, what=path)
            size = p.stat().st_size if p.is_file() else None
        except (OrthospecError, OSError):  # outside the delivery root or unreadable: not delivered
            size = None
        if size is None:
            return _one(
                name,
                "delivery",
                "text",
                d.id,
                None,
                ev,
                note=f"{MANIFEST} lists {path}: {v}, but the file is not in the delivery",
            )
        if size == 0:  # JRC §2.5: the internal QCRs are delivered; an empty file is no document
            return _one(
                name,
                "delivery",
                "text",
                d.id,
                None,
                (*ev, d.evidence(v)),
                note=f"{MANIFEST} lists {path}: {v}, but the file is empty (0 bytes): no document delivered",
            )
        return _one(name, "delivery", "text", d.id, v, (*ev, d.evidence(v)))
    if isinstance(v, dict) and set(v) == {"value", "unit"}:
        return _one(name, "delivery", canonical(v["unit"]), d.id, float(v["value"]), ev)
    if isinstance(v, bool):
        return _one(name, "delivery", "bool", d.id, v, ev)
    if isinstance(v, int | float):
        return _one(name, "delivery", "1", d.id, float(v), ev)
    if isinstance(v, list):
        return _one(name, "delivery", "text", d.id, ";".join(map(str, v)), ev)
    return _one(name, "delivery", "text", d.id, None if v is None else str(v), ev)
