"""Stable values and the compact column vocabulary of the QCR document (issue 28 item 1).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from .. import verdicts as V
from ..engine.evaluator import (
    NA,
    PASS,
)
from ..engine.registry import SCOPES
from ..present import fmt_value

SCHEMA_ID = (
    "orthospec.qcr/3"  # version 3: version 2 + evidence selectors and row columns (docs/QCR.md)
)

SIG_DIGITS = 10
_SCOPE_ORDER = {s: i for i, s in enumerate(SCOPES)}


def stable(x: Any) -> Any:
    """JSON-safe, deterministic value: floats rounded to 10 significant digits, NaN -> None."""
    if isinstance(x, bool | np.bool_):
        return bool(x)
    if isinstance(x, int | np.integer):
        return int(x)
    if isinstance(x, float | np.floating):
        f = float(x)
        if math.isnan(f) or math.isinf(f):
            return None
        if f == 0:
            return 0.0
        r = float(f"{f:.{SIG_DIGITS}g}")
        return r
    if isinstance(x, dict):
        return {str(k): stable(v) for k, v in x.items() if not str(k).startswith("_")}
    if isinstance(x, list | tuple):
        return [stable(v) for v in x]
    if isinstance(x, np.ndarray):
        return [stable(v) for v in x.tolist()]
    if _is_frame(x):
        return frame_table(x)
    return x


def _is_frame(x: Any) -> bool:
    """A pandas DataFrame, without importing pandas for documents that hold none."""
    return type(x).__name__ == "DataFrame" and type(x).__module__.startswith("pandas")


def round_sig(values: np.ndarray) -> np.ndarray:
    """Floats rounded to SIG_DIGITS significant digits, vectorised: the value ``float(f"{v:.10g}")``
    gives (n / 10**k with both exact is one correctly rounded division), NaN/inf kept."""
    v = np.asarray(values, dtype=np.float64)
    out = v.copy()
    ok = np.isfinite(v) & (v != 0)
    if not ok.any():
        return out
    x = v[ok]
    k = (SIG_DIGITS - 1) - np.floor(np.log10(np.abs(x))).astype(np.int64)
    r = np.empty_like(x)
    pos = (k >= 0) & (k <= 22)
    neg = (k < 0) & (k >= -22)
    r[pos] = np.rint(x[pos] * 10.0 ** k[pos]) / 10.0 ** k[pos]
    r[neg] = np.rint(x[neg] / 10.0 ** -k[neg]) * 10.0 ** -k[neg]
    rest = ~(pos | neg)
    r[rest] = [float(f"{f:.{SIG_DIGITS}g}") for f in x[rest].tolist()]
    out[ok] = r
    return out


def _stable_column(values: np.ndarray) -> list[Any]:
    """One column, vectorised where it is numeric: 10 significant digits, NaN/inf -> None."""
    if values.dtype.kind == "f":
        finite = np.isfinite(values)
        r = round_sig(values) + 0.0  # -0.0 -> 0.0, as stable() writes it
        return [f if ok else None for f, ok in zip(r.tolist(), finite.tolist(), strict=True)]
    if values.dtype.kind in "iu":
        return values.tolist()
    if values.dtype.kind == "b":
        return values.tolist()
    from pandas.api.types import infer_dtype  # only reached for frames: pandas is loaded

    if infer_dtype(values, skipna=False) == "string":  # text only (ids, decisions): as it is
        return values.tolist()
    return [stable(v) for v in values.tolist()]


def frame_table(frame: Any) -> dict[str, Any]:
    """A DataFrame as the column table qcr.json stores (docs/QCR.md):
    ``{"columns": [names...], "data": {name: [values...]}}``, rows in frame order."""
    cols = [str(c) for c in frame.columns if not str(c).startswith("_")]
    data = {}
    for c in cols:
        col = frame[c]
        data[c] = _stable_column(col.to_numpy())
    return {"columns": cols, "data": data}


def point_rows(table: Any) -> list[dict[str, Any]]:
    """Rows (dicts) of a per-point table: a column table, a DataFrame or the old list of dicts."""
    if table is None:
        return []
    if _is_frame(table):
        table = frame_table(table)
    if isinstance(table, dict):
        cols = list(table.get("columns") or [])
        data = table.get("data") or {}
        n = max((len(data.get(c) or []) for c in cols), default=0)
        return [
            {c: (data[c][i] if c in data and i < len(data[c]) else None) for c in cols}
            for i in range(n)
        ]
    return [dict(p) for p in table]


def point_frame(table: Any) -> Any:
    """A per-point table as a pandas DataFrame (column table, DataFrame or list of dicts)."""
    import pandas as pd

    if _is_frame(table):
        return table
    if isinstance(table, dict):
        cols = list(table.get("columns") or [])
        data = table.get("data") or {}
        return pd.DataFrame({c: data.get(c, []) for c in cols}, columns=cols)
    return pd.DataFrame(list(table or []))


#: verdicts recorded compactly (columnar, per rule); every other verdict is a record in full
COMPACT_VERDICTS = (V.PASS, V.NOT_APPLICABLE)
_COMPACT_CODES = (PASS, NA)


#: an evidence entry lists its CSV rows up to this many; beyond, a selector stands for them when one
#: reproduces them exactly (``where``: column = value, or every row), else the rows are listed
ROWS_LISTED_MAX = 1000


def _pass_message(measure: str, measured: Any, shown_unit: str, req_text: str) -> str:
    """The message of a pass/fail/warn record whose rule gave no note (one wording, two callers)."""
    return f"{measure} = {fmt_value(measured)}{shown_unit}; required {req_text}"


def _shown_unit(unit: str | None) -> str:
    from ..profile.wording import unit_suffix

    return unit_suffix(unit)


def _full(
    rule: Mapping[str, Any],
    item: str,
    verdict: str,
    measured: Any,
    requirement: dict[str, Any],
    evidence: list[dict[str, Any]],
    message: str,
    waiver: Any = None,
    waiver_requested: Any = None,
    waived_verdict: str | None = None,
    reason: str | None = None,
) -> dict[str, Any]:
    """A record as readers see it: what is particular to the item, plus what its rule summary
    holds for every item (title, clause, quote, level, consequence, measure, unit, audit)."""
    rec = {
        "rule": rule["rule"],
        "title": rule.get("title", ""),
        "clause": rule.get("citation") or {},
        "quote": rule.get("quote", ""),
        "scope": rule.get("scope", ""),
        "item": item,
        "level": rule.get("level"),
        "consequence": rule.get("consequence"),
        "manual": rule.get("manual", False),
        "verdict": verdict,
        "measure": rule.get("measure", ""),
        "measured": {"value": measured, "unit": rule.get("unit")},
        "requirement": requirement,
        "evidence": evidence,
        "message": message,
        "waiver": waiver,
        "waiver_requested": waiver_requested,
    }
    if waived_verdict is not None:
        rec["waived_verdict"] = waived_verdict
    if rule.get("audit") is not None:
        rec["audit"] = rule["audit"]
    rec["reason"] = V.reason_of(verdict, reason)
    return rec


#: from this many items on, a column takes the whole-column shortcuts (below, their fixed cost is
#: more than the per-item work they save)
_LARGE = 4096


def _every(idx: np.ndarray, n: int) -> bool:
    """``idx`` is 0..n-1 in order (a rule whose items are all compact and already in natural order)."""
    return len(idx) == n and (
        n == 0 or (int(idx[0]) == 0 and int(idx[-1]) == n - 1 and bool((np.diff(idx) == 1).all()))
    )


def _numeric_column(values: np.ndarray) -> list[Any] | dict[str, Any]:
    """A numeric compact column (stable values), ``{"all": v}`` when every item has the same one."""
    n = len(values)
    if n > 1:
        if values.dtype.kind == "f" and bool((values == values[0]).all()):  # one value (never NaN)
            one = float(round_sig(values[:1])[0] + 0.0)
            return {"all": one if math.isfinite(one) else None}
        if values.dtype.kind == "f":
            r = round_sig(values) + 0.0
            finite = np.isfinite(r)
            if not finite.any():
                return {"all": None}
            if finite.all() and bool((r == r[0]).all()):
                return {"all": float(r[0])}
        elif bool((values == values[0]).all()):
            return {"all": values[:1].tolist()[0]}
    return _stable_column(values)
