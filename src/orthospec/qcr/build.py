"""Quality control records (QCRs): the document every report and the ledger are built from.

``build_document`` turns an :class:`~orthospec.engine.evaluator.Evaluation` into a plain,
JSON-safe dict; ``write_outputs`` writes qcr.json / qcr.csv / junit.xml atomically. The same
delivery, profile and date always give byte-identical JSON (sorted records, rounded floats, no
wall-clock time, no absolute paths).
"""

from __future__ import annotations

import bisect
import csv
import heapq
import io
import itertools
import json
import math
import re
import sys
from collections import Counter as _Counter
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape as _escape
from xml.sax.saxutils import quoteattr as _quoteattr

import numpy as np

from .. import __version__
from .. import verdicts as V
from ..engine.evaluator import (
    ERROR,
    FAIL,
    MISSING,
    NA,
    PASS,
    WAIVED,
    WARN,
    Evaluation,
    RuleResult,
)
from ..engine.registry import SCOPES
from ..errors import OrthospecError
from ..outputs import atomic_write  # noqa: F401  (re-exported: the one atomic writer lives in outputs.py)
from ..provenance import Evidence
from ..qcr_model import SCHEMA_IDS, qcr_schema
from ..verdicts import VERDICTS

__all__ = ["SCHEMA_IDS", "all_records", "block_columns", "build_document", "dumps", "evidence_rows", "evidence_text",
           "iter_dumps", "natural_order", "point_frame", "point_rows", "qcr_schema", "record_groups", "render_all", "stable"]

SCHEMA_ID = "orthospec.qcr/3"  # version 3: version 2 + evidence selectors and row columns (docs/QCR.md)

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
    """A DataFrame as the column table qcr.json stores (INTERFACES item 3):
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
        return [{c: (data[c][i] if c in data and i < len(data[c]) else None) for c in cols} for i in range(n)]
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


def _fmt(v: Any) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


#: verdicts recorded compactly (columnar, per rule); every other verdict is a record in full
COMPACT_VERDICTS = (V.PASS, V.NOT_APPLICABLE)
_COMPACT_CODES = (PASS, NA)


#: an evidence entry lists its CSV rows up to this many; beyond, a selector stands for them when one
#: reproduces them exactly (``where``: column = value, or every row), else the rows are listed
ROWS_LISTED_MAX = 1000


class _Evidence:
    """Evidence as qcr.json writes it, and the document's ``evidence`` table (what compact columns index).

    An entry with more than :data:`ROWS_LISTED_MAX` rows of a delivered table is written as a
    selector ``{"file", "sha256", "where": {column: value}, "rows_count"}`` when exactly those rows
    of the table carry that value in that column (``where: {}``: every data row), checked here on
    the parsed table before it is written; otherwise its rows are listed (docs/QCR.md)."""

    def __init__(self, delivery: Any = None) -> None:
        self.d = delivery
        self.index: dict[Any, int] = {}
        self.table: list[dict[str, Any]] = []
        #: id(e) -> (e, kept alive so the id stays its own; its entry; the entry's canonical text)
        self._long: dict[int, tuple[Evidence, dict[str, Any], str]] = {}
        self._columns: dict[Any, Any] = {}  # (file, column) -> codes and distinct values (selectors)

    def _long_entry(self, e: Evidence) -> tuple[Evidence, dict[str, Any], str]:
        hit = self._long.get(id(e))
        if hit is None:
            entry = _selector(self.d, e, self._columns) or e.to_dict()
            hit = self._long[id(e)] = (e, entry, _canonical(entry))
        return hit

    def entry(self, e: Evidence) -> dict[str, Any]:
        """One evidence entry as written (rows listed, or a selector for many rows)."""
        return e.to_dict() if len(e.rows) <= ROWS_LISTED_MAX else self._long_entry(e)[1]

    def _intern(self, key: Any, entry: dict[str, Any]) -> int:
        k = self.index.get(key)
        if k is None:
            k = self.index[key] = len(self.table)
            self.table.append(entry)
        return k

    def ids(self, ev: tuple[Evidence, ...] | list[Evidence]) -> list[int]:
        out = []
        for e in (sorted(set(ev)) if len(ev) > 1 else ev):
            if len(e.rows) <= ROWS_LISTED_MAX:
                k = self.index.get(e)
                out.append(k if k is not None else self._intern(e, e.to_dict()))
            else:
                _, entry, key = self._long_entry(e)
                out.append(self._intern(key, entry))
        return out

    def file_id(self, file: str, sha256: str) -> int:
        """The table entry ``{file, sha256}`` a row column points to."""
        e = Evidence(file, sha256)
        k = self.index.get(e)
        return k if k is not None else self._intern(e, e.to_dict())

    def records(self, ev: Any) -> list[dict[str, Any]]:
        """A record's evidence entries (sorted, each once)."""
        return [self.entry(e) for e in (sorted(set(ev)) if len(ev) > 1 else ev)]


def _canonical(entry: Mapping[str, Any]) -> str:
    return json.dumps(entry, sort_keys=True, ensure_ascii=False, separators=(",", ":"))


def _selector(d: Any, e: Evidence, cache: dict[Any, Any]) -> dict[str, Any] | None:
    """``{file, sha256, where, rows_count}`` standing for exactly ``e.rows`` of a delivered table, or
    None: the rows must be increasing and be every row of the table (``where: {}``) or every row
    whose cell in one text column (stripped, as the reader parsed it) equals one value."""
    rows = _int_array(e.rows)
    if d is None or e.path or len(rows) < 2 or not bool((np.diff(rows) > 0).all()):
        return None
    table = None
    for name, rel in (getattr(d.manifest, "tables", None) or {}).items():
        if rel == e.file:
            try:
                table = d.table(name)
            except OrthospecError:
                return None
            break
    if table is None or table.sha256 != e.sha256:
        return None
    df = table.df
    all_rows = df["_row"].to_numpy(np.int64)

    def found(where: dict[str, str]) -> dict[str, Any]:
        return {"file": e.file, "sha256": e.sha256, "where": where, "rows_count": len(rows)}

    if len(rows) == len(all_rows) and np.array_equal(rows, all_rows):
        return found({})
    at = np.searchsorted(all_rows, rows[0])
    if at >= len(all_rows) or all_rows[at] != rows[0]:
        return None
    texts = [c for c, cs in table.spec.columns.items() if cs.type == "text" and c in df and c != table.spec.id]
    for col in sorted(texts, key=lambda c: c != "block"):  # the block column first: the usual grouping
        codes, values = _factorized(table, col, cache)
        k = int(codes[at])
        if k < 0 or not isinstance(values[k], str):
            continue
        mask = codes == k
        if int(np.count_nonzero(mask)) == len(rows) and np.array_equal(all_rows[mask], rows):
            return found({col: values[k]})
    return None


def _int_array(values: Any) -> np.ndarray:
    """Row numbers as int64 (a ``range``, as a provider may give every row, without one int per row)."""
    if isinstance(values, range):
        return np.arange(values.start, values.stop, values.step, dtype=np.int64)
    return np.fromiter(values, dtype=np.int64, count=len(values))


def _factorized(table: Any, col: str, cache: dict[Any, Any]) -> tuple[np.ndarray, list[Any]]:
    """A text column as codes and distinct values, once per document, table and column (each
    block's selector then costs an integer comparison, not a text comparison over every row)."""
    key = (table.file, col)
    hit = cache.get(key)
    if hit is None:
        import pandas as pd  # a selector is only built for a delivered table: pandas is loaded

        codes, values = pd.factorize(table.df[col].to_numpy(dtype=object))
        hit = cache[key] = (np.asarray(codes), list(values))
    return hit


def _column(values: list[Any]) -> list[Any] | dict[str, Any]:
    """A compact column: ``{"all": v}`` when every item has the same value, else the list."""
    if len(values) > 1 and all(v == values[0] for v in values[1:]):
        return {"all": values[0]}
    return values


class _Shared:
    """A compact column equal to one written before (rules over the same images share their item
    list, often their evidence) is written as ``{"ref": [rule, column]}`` to that first one."""

    MIN_LEN = 4
    COLUMNS = ("items", "measured", "requirement", "evidence", "message", "waiver_requested")

    def __init__(self) -> None:
        #: a cheap fingerprint of a column -> the columns written with it ([rule, column], value)
        self.seen: dict[tuple[Any, ...], list[tuple[list[str], Any]]] = {}

    @staticmethod
    def _fingerprint(values: Any) -> tuple[Any, ...]:
        """Length and a few elements (in their JSON text, so 1 and 1.0 or True stay apart): equal
        columns share it; candidates are then compared in full."""
        seq = values if isinstance(values, list) else values["rows"]
        n = len(seq)
        probe = [seq[i] for i in sorted({0, n // 3, n // 2, (2 * n) // 3, n - 1})]
        return (type(values).__name__, n, json.dumps(probe, sort_keys=True, ensure_ascii=False),
                json.dumps(values.get("entry") if isinstance(values, dict) else None))

    def apply(self, rule_id: str, block: dict[str, Any]) -> dict[str, Any]:
        for col in self.COLUMNS:
            values = block.get(col)
            size = (len(values) if isinstance(values, list) else
                    len(values["rows"]) if isinstance(values, dict) and "entry" in values else 0)
            if size < self.MIN_LEN:
                continue
            known = self.seen.setdefault(self._fingerprint(values), [])
            first = next((ref for ref, v in known if _same(v, values)), None)
            if first is None:
                known.append(([rule_id, col], values))
            else:
                block[col] = {"ref": first}
        return block


def _same(a: Any, b: Any) -> bool:
    """Equal as JSON would write them: 1 == 1.0 == True in Python, not in the file."""
    if a is b:
        return True
    if a != b:
        return False
    enc = json.JSONEncoder(ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode
    return bool(enc(a) == enc(b))


def _pass_message(measure: str, measured: Any, shown_unit: str, req_text: str) -> str:
    """The message of a pass/fail/warn record whose rule gave no note (one wording, two callers)."""
    return f"{measure} = {_fmt(measured)}{shown_unit}; required {req_text}"


def _shown_unit(unit: str | None) -> str:
    from ..spec.wording import unit_suffix

    return unit_suffix(unit)


def _full(rule: Mapping[str, Any], item: str, verdict: str, measured: Any, requirement: dict[str, Any],
          evidence: list[dict[str, Any]], message: str, waiver: Any = None, waiver_requested: Any = None,
          waived_verdict: str | None = None) -> dict[str, Any]:
    """A record as readers see it: what is particular to the item, plus what its rule summary
    holds for every item (title, clause, quote, level, consequence, measure, unit, audit)."""
    rec = {"rule": rule["rule"], "title": rule.get("title", ""), "clause": rule.get("citation") or {},
           "quote": rule.get("quote", ""), "scope": rule.get("scope", ""), "item": item,
           "level": rule.get("level"), "consequence": rule.get("consequence"), "manual": rule.get("manual", False),
           "verdict": verdict, "measure": rule.get("measure", ""),
           "measured": {"value": measured, "unit": rule.get("unit")}, "requirement": requirement,
           "evidence": evidence, "message": message, "waiver": waiver, "waiver_requested": waiver_requested}
    if waived_verdict is not None:
        rec["waived_verdict"] = waived_verdict
    if rule.get("audit") is not None:
        rec["audit"] = rule["audit"]
    return rec


class _RuleRecords:
    """Builds the records of one rule result; everything constant per rule is computed once."""

    def __init__(self, r: RuleResult, evidence: _Evidence) -> None:
        from ..spec.wording import requirement_text

        self.r = r
        self.ev = evidence
        rule = r.rule
        self.text = requirement_text
        self.req = stable({k: v for k, v in r.threshold.items() if not k.startswith("_")})
        self.arrays = r.threshold.get("_arrays")
        self.unit = r.unit if r.unit not in ("", "any") else None
        self.shown_unit = _shown_unit(self.unit)
        self.summary: dict[str, Any] = {
            "rule": rule.id, "title": rule.title, "scope": rule.scope, "level": rule.level,
            "consequence": rule.consequence, "citation": rule.clause.model_dump(mode="json", exclude_none=True),
            "quote": rule.quote, "manual": rule.manual, "measure": rule.measure, "unit": self.unit,
            "requirement": self.req,
        }
        if rule.audit is not None:
            self.summary["audit"] = rule.audit.model_dump(mode="json", exclude_none=True)

    def summary_fields(self) -> dict[str, Any]:
        """What every record of this rule shares: records take it from the rule summary."""
        return {k: v for k, v in self.summary.items()
                if k not in ("rule", "title", "scope", "level", "consequence")}

    def _measured(self, i: int) -> Any:
        measured = self.r.measured[i]
        if isinstance(measured, np.generic):
            measured = measured.item()
        return stable(measured)

    def _with_thresholds(self, values: tuple[Any, ...]) -> dict[str, Any]:
        """The requirement with this item's resolved threshold(s) (already stable) and its wording."""
        req = dict(self.req)
        if self.r.rule.requirement.op == "between":
            req["min"], req["max"] = values
        else:
            req["value"] = values[0]
        req["text"] = self.text(self.r.rule.requirement, req)
        return req

    def _requirement(self, i: int) -> dict[str, Any]:
        if self.arrays is None:
            return self.req
        n = 2 if self.r.rule.requirement.op == "between" else 1
        return self._with_thresholds(tuple(stable(float(a[i])) for a in self.arrays[:n]))

    def _requirement_column(self, idx: np.ndarray) -> list[Any] | dict[str, Any] | None:
        """Per-item requirements of the compact records at ``idx``, vectorised: the text is computed
        once per distinct threshold; None when every item has the rule summary's requirement."""
        n = 2 if self.r.rule.requirement.op == "between" else 1
        cols = []
        for a in self.arrays[:n]:  # type: ignore[index]
            a = np.asarray(a, dtype=np.float64)
            # one threshold for every item (a stride-0 view): one value, not one per item
            v = a[:1] if a.ndim == 1 and a.size and a.strides[0] == 0 and len(idx) else a[idx]
            if len(v) > 1 and bool((v == v[0]).all()):  # one threshold for every item (NaN never equals)
                v = v[:1]
            cols.append(np.where(np.isfinite(v), round_sig(v) + 0.0, np.inf))  # non-finite: null
        rows = max(len(c) for c in cols)  # 1 when every threshold is one value
        stack = np.column_stack([np.broadcast_to(c, (rows,)) for c in cols])
        if len(stack) and bool((stack == stack[0]).all()):
            uniq, inverse = stack[:1], np.zeros(len(idx), dtype=np.int64)
        else:
            uniq, inverse = np.unique(stack, axis=0, return_inverse=True)
        reqs = [self._with_thresholds(tuple(None if math.isinf(x) else x for x in row))
                for row in uniq.tolist()]
        if len(reqs) == 1 and reqs[0] == self.req:
            return None
        if len(reqs) == 1:
            return _column([reqs[0]] * len(idx))
        return [reqs[k] for k in inverse.ravel().tolist()]

    def stored(self, i: int) -> dict[str, Any]:
        """A record in full as qcr.json stores it: only what is particular to the item (its rule's
        text is in the rule summary; :func:`all_records` puts them together)."""
        r, rule = self.r, self.r.rule
        v = int(r.verdict[i])
        item = str(r.items[i])
        measured = self._measured(i)
        req = self._requirement(i)
        note = r.notes[i]
        if v in (PASS, FAIL, WARN) and note is None:
            note = _pass_message(rule.measure, measured, self.shown_unit, req.get("text", ""))
        elif v == WAIVED and r.original is not None:
            w = r.waivers.get(item, {})
            note = (f"{VERDICTS[int(r.original[i])]} waived: {w.get('justification', '')} "
                    f"(approved by {w.get('approver', '?')})")
        elif note is None:
            note = ""
        rec: dict[str, Any] = {"rule": rule.id, "item": item, "verdict": VERDICTS[v], "measured": measured}
        if self.arrays is not None:
            rec["requirement"] = req
        rec["evidence"] = self.ev.records(r.evidence[i])
        rec["message"] = str(note)
        if v == WAIVED:
            rec["waiver"] = r.waivers.get(item)
            if r.original is not None:
                rec["waived_verdict"] = VERDICTS[int(r.original[i])]
        if r.requested.get(item) is not None:
            rec["waiver_requested"] = r.requested.get(item)
        return rec

    def record(self, i: int) -> dict[str, Any]:
        """The record as readers see it (what :func:`all_records` yields)."""
        return _expand_stored(self.summary, self.stored(i))

    def compact(self, idx: np.ndarray) -> dict[str, Any]:
        """The pass / not-applicable records at ``idx`` (item order) as columns (see docs/QCR.md).

        Vectorised over the items: a rule over a million check points costs numpy passes and one
        list per column, no Python object per item beyond the values written."""
        r = self.r
        n = len(idx)
        # a large rule whose every item is compact, in the order given: no copy of its columns
        every = n >= _LARGE and _every(idx, len(r.items))
        ids = np.asarray(r.items, dtype=object)
        items = (ids if every else ids[idx]).tolist()
        if n < _LARGE or not _all_text(items):
            items = list(map(str, items))
        codes = np.asarray(r.verdict) if every else np.asarray(r.verdict)[idx]
        if n > 1 and bool((codes == codes[0]).all()):
            verdict: Any = {"all": VERDICTS[int(codes[0])]}
        else:
            verdict = [VERDICTS[int(c)] for c in codes.tolist()]
        m = np.asarray(r.measured) if every else np.asarray(r.measured)[idx]
        measured = _numeric_column(m) if m.dtype.kind in "fiub" else _column([self._measured(int(i)) for i in idx])
        out: dict[str, Any] = {"items": items, "verdict": verdict, "measured": measured}
        if self.arrays is not None:
            req = self._requirement_column(idx)
            if req is not None:
                out["requirement"] = req
        out["evidence"] = self._evidence_column(idx, every)
        out["message"] = self._message_column(idx, codes, every)
        if r.requested:
            asked = [r.requested.get(item) for item in items]
            if any(a is not None for a in asked):
                out["waiver_requested"] = _column(asked)
        return out

    def _evidence_column(self, idx: np.ndarray, every: bool = False) -> Any:
        """Evidence per item: one row of one file per item (a provider's row evidence) as a row column
        ``{"entry": k, "rows": [...]}``, else indices into the evidence table per item."""
        evs = self.r.evidence
        rows = getattr(evs, "rows", None)
        file, sha = getattr(evs, "file", None), getattr(evs, "sha256", None)
        if isinstance(rows, np.ndarray) and isinstance(file, str) and isinstance(sha, str):
            picked = np.asarray(rows, dtype=np.float64)
            picked = picked if every else picked[idx]
            have = ~np.isnan(picked)
            if not have.any():
                return _column([[] for _ in range(len(idx))])
            ints = np.where(have, picked, 0).astype(np.int64).tolist()
            col = ints if have.all() else [x if h else None for x, h in zip(ints, have.tolist(), strict=True)]
            return {"entry": self.ev.file_id(file, sha), "rows": col}
        return _column([self.ev.ids(evs[int(i)]) for i in idx])

    def _message_column(self, idx: np.ndarray, codes: np.ndarray, every: bool = False) -> Any:
        """None: the default wording (rebuilt on reading) of a pass without a note; "" for a
        not-applicable record without one; else the note."""
        notes = np.asarray(self.r.notes, dtype=object)
        notes = notes if every else notes[idx]
        none = np.equal(notes, None).astype(bool)
        if len(idx) > 1 and none.all():
            if (codes == PASS).all():
                return {"all": None}
            if (codes == NA).all():
                return {"all": ""}
        return _column([None if nn and c == PASS else ("" if nn else str(note))
                        for note, nn, c in zip(notes.tolist(), none.tolist(), codes.tolist(), strict=True)])


#: from this many items on, a column takes the whole-column shortcuts (below, their fixed cost is
#: more than the per-item work they save)
_LARGE = 4096


def _every(idx: np.ndarray, n: int) -> bool:
    """``idx`` is 0..n-1 in order (a rule whose items are all compact and already in natural order)."""
    return len(idx) == n and (n == 0 or (int(idx[0]) == 0 and int(idx[-1]) == n - 1 and
                                         bool((np.diff(idx) == 1).all())))


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


def _expand_stored(rule: Mapping[str, Any], rec: Mapping[str, Any]) -> dict[str, Any]:
    """A stored record in full (version 2) as readers see it."""
    return _full(rule, rec["item"], rec["verdict"], rec.get("measured"),
                 rec.get("requirement") or rule.get("requirement") or {}, rec.get("evidence") or [],
                 rec.get("message", ""), rec.get("waiver"), rec.get("waiver_requested"), rec.get("waived_verdict"))


def _column_values(col: Any, n: int, compact: Mapping[str, Any]) -> list[Any]:
    if isinstance(col, dict):
        if "ref" in col:
            rule_id, name = col["ref"]
            return _column_values(compact[rule_id][name], n, compact)
        return [col.get("all")] * n
    return list(col) if col is not None else [None] * n


def _evidence_values(col: Any, n: int, compact: Mapping[str, Any], table: list[dict[str, Any]]
                     ) -> Iterator[list[dict[str, Any]]]:
    """Each item's evidence entries from a compact ``evidence`` column (any of its forms)."""
    while isinstance(col, dict) and "ref" in col:
        rule_id, name = col["ref"]
        col = compact[rule_id][name]
    if isinstance(col, dict) and "entry" in col:  # one row of one file per item
        base = table[col["entry"]]
        for row in col["rows"]:
            yield [] if row is None else [{**base, "rows": [row]}]
        return
    for ids in _column_values(col, n, compact):
        yield [table[e] for e in (ids or [])]


def block_columns(rule: Mapping[str, Any], block: Mapping[str, Any],
                  compact: Mapping[str, Any]) -> tuple[Sequence[Any], ...]:
    """A compact block's items, verdicts, measured values, requirements and messages, one value
    per item each: the one reading of these columns (records here, the ledger's rows)."""
    items = _column_values(block["items"], 0, compact)
    n = len(items)
    verdicts = _column_values(block.get("verdict"), n, compact)
    measured = _column_values(block.get("measured"), n, compact)
    reqs = (_column_values(block["requirement"], n, compact) if "requirement" in block
            else [rule.get("requirement") or {}] * n)
    msgs = _column_values(block.get("message"), n, compact)
    return items, verdicts, measured, reqs, msgs


def _expand(rule: Mapping[str, Any], block: Mapping[str, Any], evidence: list[dict[str, Any]],
            compact: Mapping[str, Any]) -> Iterator[dict[str, Any]]:
    """The records of one rule's compact block (the same dicts as records in full)."""
    items, verdicts, measured, reqs, msgs = block_columns(rule, block, compact)
    n = len(items)
    evs = _evidence_values(block.get("evidence"), n, compact, evidence)
    asked = _column_values(block.get("waiver_requested"), n, compact)
    shown = _shown_unit(rule.get("unit"))
    measure = rule.get("measure", "")
    for k, ev in zip(range(n), evs, strict=True):
        req = reqs[k]
        msg = msgs[k]
        if msg is None:
            msg = _pass_message(measure, measured[k], shown, req.get("text", ""))
        yield _full(rule, items[k], verdicts[k], measured[k], req, ev, msg, None, asked[k])


def all_records(doc: Mapping[str, Any], *, compact: bool = True) -> Iterator[dict[str, Any]]:
    """Every record of a QCR document, in document order (scope, rule id, item in natural order).

    The one way to read records (INTERFACES item 2). Version 2 documents store each record once,
    without its rule's text: ``doc["records"]`` holds the records whose verdict is not pass or
    not applicable (item, verdict, measured value, evidence, message...), ``doc["compact"]`` the
    others as columns per rule; both are expanded here with the rule summary into the same dicts.
    Version 1 documents (every record in full in ``records``) are read as they are.

    ``compact=False`` leaves out the pass and not-applicable records (what the terminal needs, at
    the cost of the problems only, whatever the size of the delivery).
    """
    records = doc.get("records") or []
    if "compact" not in doc:
        yield from (records if compact else (r for r in records if r.get("verdict") not in COMPACT_VERDICTS))
        return
    blocks = doc["compact"] or {}
    evidence = doc.get("evidence") or []
    for summary, stored, block in record_groups(doc, compact=compact):
        if summary is None:  # records without a rule summary: as stored
            yield from (dict(r) for r in stored)
            continue
        mine = (_expand_stored(summary, rec) for rec in stored)
        if not block:
            yield from mine
        else:
            yield from heapq.merge(mine, _expand(summary, block, evidence, blocks),
                                   key=lambda r: natural_key(r["item"]))


def record_groups(doc: Mapping[str, Any], *, compact: bool = True
                  ) -> Iterator[tuple[Mapping[str, Any] | None, list[Mapping[str, Any]], Mapping[str, Any] | None]]:
    """The walk of a version 2+ document in record order: per rule summary (summary, its records
    stored in full, its compact block or None), then (None, records, None) per rule that has no
    summary. The one walk behind :func:`all_records` and the ledger's rows; the stored records of a
    rule merge with its compact block by :func:`natural_key` of the item, stored first."""
    blocks = (doc["compact"] or {}) if compact else {}
    full: dict[str, list[Mapping[str, Any]]] = {}
    for rec in doc.get("records") or []:
        full.setdefault(rec["rule"], []).append(rec)
    for summary in doc.get("rules") or []:
        rid = summary["rule"]
        yield summary, full.pop(rid, []), blocks.get(rid) or None
    for rest in full.values():
        yield None, rest, None


_DIGITS = re.compile(r"(\d+)")


def natural_key(text: str) -> tuple[Any, ...]:
    """IMG_2 before IMG_10: digits compare as numbers, the rest as text (total order, stable)."""
    return tuple((0, int(p), p) if p.isdecimal() else (1, 0, p) for p in _DIGITS.split(text))


#: digit runs longer than this (leading zeros included) take the exact path (int64 holds 18 digits)
_FAST_DIGITS = 18


def natural_order(items: Any) -> np.ndarray:
    """Indices that sort ``items`` by :func:`natural_key` (ties in item order), vectorised.

    Ids of one length and one digit layout (``P0000001``, ``F01_0101``) sort as bytes
    (:func:`_uniform_order`). Otherwise each id is a head and its trailing ASCII digits
    (``B01_`` + ``17``): the distinct heads (few) are ordered by ``natural_key``, and the ids by
    numpy keys: the head's rank, digits or not, the number, then its count of digits (among equal
    numbers, its leading zeros: what ``natural_key`` compares after the number, ``'0' < '00'`` but
    ``'001' < '01'``). That is the
    natural order when no head's key begins another's (checked; ``B01_`` and ``B01_2x`` would
    not do). An id outside it (a head that begins another, more than 18 trailing digits) takes
    ``natural_key`` and is merged in by binary search. The same order as ``sorted(...,
    key=natural_key)`` (tests/test_qcr_scale.py, tests/test_qcr_fast.py)."""
    listed = items.tolist() if isinstance(items, np.ndarray) else list(items)
    n = len(listed)
    if n < 256:
        return _slow_order(listed if _all_text(listed) else [str(x) for x in listed], np.arange(n))
    uniform = _uniform_order(listed)
    if uniform is not None:
        return uniform
    try:
        strs = listed
        fast, rank, value, digits, has = _head_tail_keys(strs)  # str methods: TypeError unless text
    except TypeError:
        strs = [x if type(x) is str else str(x) for x in listed]
        fast, rank, value, digits, has = _head_tail_keys(strs)
    fi = np.flatnonzero(fast)
    if not len(fi):
        return _slow_order(strs, np.arange(n))
    rank, value, digits, has = rank[fi], value[fi], digits[fi], has[fi]
    if bool((rank == rank[0]).all() & has.all()) and bool((np.diff(value) > 0).all()):
        order = fi  # one head and increasing numbers: already in order (ids in file order)
    else:
        # equal numbers: more digits are more leading zeros, first for a number > 0 ('01' < '1'),
        # last for 0 ('0' < '00')
        tie = np.where(value == 0, digits, -digits)
        keys = [k for k in (tie, value, has, rank) if not bool((k == k[0]).all())]  # a constant key sorts nothing
        order = fi[np.lexsort(keys) if len(keys) > 1 else np.argsort(keys[0], kind="stable") if keys else
                   np.arange(len(fi))]
    if len(fi) == n:
        return order.astype(np.int64)
    slow = _slow_order(strs, np.flatnonzero(~fast))
    fast_keys = _Keys(strs, order)
    at = [bisect.bisect_left(fast_keys, natural_key(strs[i])) for i in slow.tolist()]
    return np.insert(order, at, slow).astype(np.int64)


_ASCII_DIGITS = "0123456789"


def _head_tail_keys(strs: list[str]) -> tuple[np.ndarray, ...]:
    """Per id: whether the head/tail keys order it (``fast``), its head's rank, its trailing number,
    that number's count of digits, and whether it has one. Python work per id is a few calls in C
    (``rstrip``, ``len``, one join); per distinct head one ``natural_key``."""
    n = len(strs)
    heads = list(map(str.rstrip, strs, itertools.repeat(_ASCII_DIGITS, n)))
    lens = np.fromiter(map(len, strs), dtype=np.int64, count=n)
    tail = lens - np.fromiter(map(len, heads), dtype=np.int64, count=n)
    if len(set(heads[::max(1, n // 64)])) == 1 and heads.count(heads[0]) == n:  # one head (P1, P2, ...)
        codes, distinct = np.zeros(n, dtype=np.int64), [heads[0]]
    else:
        codes, distinct = _factorize(heads)
    del heads
    keys = [natural_key(h) for h in distinct]
    by_key = sorted(range(len(distinct)), key=keys.__getitem__)
    usable = np.array([not h or not h[-1].isdecimal() for h in distinct], dtype=bool)  # '٣' + '5' is one run
    for a, b in itertools.pairwise(by_key):
        if keys[b][:len(keys[a])] == keys[a]:  # a's key begins b's (then it begins every key between)
            usable[a] = False
    rank = np.empty(len(distinct), dtype=np.int64)
    rank[by_key] = np.arange(len(distinct))
    fast = usable[codes] & (tail <= _FAST_DIGITS)
    value = np.zeros(n, dtype=np.int64)
    tail = np.where(fast, tail, 0)
    width = int(tail.max()) if n else 0
    if width:
        # the ids' characters as code points, one buffer: id i ends at ends[i]
        chars = np.frombuffer("".join(strs).encode("utf-32-le", "surrogatepass"), dtype=np.uint32)
        last = np.cumsum(lens) - 1
        for p in range(width):  # the digit p places from the end, times 10**p
            on = p < tail
            digit = chars[np.where(on, last - p, 0)].astype(np.int64) - 48
            value += np.where(on, digit, 0) * 10 ** p
    return fast, rank[codes], value, tail, tail > 0


def _factorize(values: list[str]) -> tuple[np.ndarray, list[str]]:
    """Codes (into the distinct values, in order of first appearance) and the distinct values."""
    if "pandas" in sys.modules:
        import pandas as pd

        codes, distinct = pd.factorize(np.array(values, dtype=object))
        return np.asarray(codes, dtype=np.int64), list(distinct)
    index: dict[str, int] = {}
    out = np.fromiter((index.setdefault(v, len(index)) for v in values), dtype=np.int64, count=len(values))
    return out, list(index)


def _uniform_order(strs: list[Any]) -> np.ndarray | None:
    """The natural order of ids of one length, ASCII, without NUL, whose digits stand at the same
    positions in every id (``P0000001``, ``F01_0101``), or None for any other list.

    Such ids split into text and digit runs of the same widths at the same places, so comparing
    their :func:`natural_key` part by part is comparing the ids byte by byte (equal-width digit
    runs compare as their numbers, equal numbers are equal runs): a stable byte sort, over one
    buffer of the ids (no Python object per id), and none at all when they are already in order."""
    if not strs or type(strs[0]) is not str:
        return None
    n, width = len(strs), len(strs[0])
    if {len(x) if type(x) is str else -1 for x in strs[::max(1, n // 64)]} != {width}:
        return None  # a sample of other lengths: no join of every id
    try:
        joined = "\n".join(strs)
    except TypeError:  # not text only
        return None
    if not width or len(joined) != n * (width + 1) - 1 or not joined.isascii() or "\x00" in joined \
            or joined.count("\n") != n - 1:  # no line feed inside an id: the separators are the n - 1
        return None
    rows = np.frombuffer((joined + "\n").encode("ascii"), dtype=np.uint8).reshape(n, width + 1)
    if not bool((rows[:, width] == 10).all()):  # the lengths differ
        return None
    chars = np.ascontiguousarray(rows[:, :width])
    digit = (chars - np.uint8(48)) < 10  # '0'..'9' (below '0' wraps round to large values)
    if not bool((digit == digit[0]).all()):
        return None
    keys = chars.view(f"S{width}").ravel()
    if bool((keys[1:] >= keys[:-1]).all()):
        return np.arange(n, dtype=np.int64)
    # the bytes as big-endian 8-byte words (zero-padded): integer sorts, in the bytes' order
    words = np.zeros((n, -(-width // 8) * 8), dtype=np.uint8)
    words[:, :width] = chars
    w = words.view(">u8")
    if w.shape[1] == 1:
        return np.argsort(w[:, 0], kind="stable").astype(np.int64)
    return np.lexsort(w.T[::-1]).astype(np.int64)


def _all_text(values: list[Any]) -> bool:
    """Every value is a str (checked in C when pandas is loaded, as it is in a check)."""
    if "pandas" not in sys.modules:
        return all(type(x) is str for x in values)
    from pandas.api.types import infer_dtype

    return infer_dtype(values, skipna=False) == "string"


class _Keys:
    """natural_key of the fast-sorted ids, computed only where a binary search looks."""

    def __init__(self, strs: list[str], order: np.ndarray) -> None:
        self.strs, self.order = strs, order

    def __len__(self) -> int:
        return len(self.order)

    def __getitem__(self, k: int) -> tuple[Any, ...]:
        return natural_key(self.strs[int(self.order[k])])


def _slow_order(strs: list[str], idx: np.ndarray) -> np.ndarray:
    """``idx`` sorted by natural_key of its ids (stable)."""
    keys = [natural_key(strs[i]) for i in idx.tolist()]
    return idx[np.array(sorted(range(len(keys)), key=keys.__getitem__), dtype=np.int64)] if len(keys) \
        else idx.astype(np.int64)


def _order(items: np.ndarray, cache: dict[Any, Any]) -> np.ndarray:
    """Natural order of a rule's items; rules over the same items share one sort."""
    key = id(items) if len(items) < 2 else (len(items), str(items[0]), str(items[-1]))
    hit = cache.get(key)
    if hit is not None and (hit[1] is items or np.array_equal(hit[1], items)):
        return hit[0]
    order = natural_order(items)
    cache[key] = (order, items)
    return order


def _sorted_results(ev: Evaluation) -> list[RuleResult]:
    return sorted(ev.results, key=lambda r: (_SCOPE_ORDER.get(r.rule.scope, 99), r.rule.id))


def iter_records(ev: Evaluation) -> Iterable[dict[str, Any]]:
    """Every record in full, sorted by (scope order, rule id, item in natural order)."""
    cache: dict[Any, Any] = {}
    evidence = _Evidence(ev.delivery)
    for r in _sorted_results(ev):
        rb = _RuleRecords(r, evidence)
        for i in _order(r.items, cache):
            yield rb.record(int(i))


def build_document(ev: Evaluation, *, date: str, operator: str | None = None,
                   delivery_path: str | None = None) -> dict[str, Any]:
    """The QCR document (see docs/QCR.md and specs/schema/qcr.schema.json)."""
    d, p = ev.delivery, ev.profile
    summary = {k: 0 for k in VERDICTS}
    rules = []
    records: list[dict[str, Any]] = []
    compact: dict[str, Any] = {}
    evidence = _Evidence(d)
    shared = _Shared()
    cache: dict[Any, Any] = {}
    n_records = 0
    for r in _sorted_results(ev):
        rb = _RuleRecords(r, evidence)
        bad = np.asarray(r.items, dtype=object)[np.isin(r.verdict, (FAIL, WARN, MISSING, ERROR))]
        offending = [str(bad[i]) for i in natural_order(bad).tolist()]
        rules.append(stable({
            "rule": r.rule.id, "title": r.rule.title, "scope": r.rule.scope, "level": r.rule.level,
            "consequence": r.rule.consequence, "clause": r.rule.clause.text(), "clause_ref": r.rule.clause.ref(),
            "verdict": VERDICTS[r.worst], "counts": {k: v for k, v in r.counts().items() if v},
            "offending": offending, "error": r.error, **rb.summary_fields(),
        }))
        order = _order(r.items, cache)
        codes = np.asarray(r.verdict)[order]
        for code, count in zip(*np.unique(codes, return_counts=True), strict=True):
            summary[VERDICTS[int(code)]] += int(count)
        n_records += len(order)
        is_compact = np.isin(codes, _COMPACT_CODES)
        if is_compact.any():
            compact[r.rule.id] = shared.apply(r.rule.id, rb.compact(order[is_compact]))
        records.extend(rb.stored(int(i)) for i in order[~is_compact])
    man = d.manifest
    doc: dict[str, Any] = {
        "schema": SCHEMA_ID,
        "tool": {"name": "orthospec", "version": __version__},
        "date": date,
        # the checker (--operator); the contractor's QA operator stays in delivery.operator
        "operator": operator or None,
        # the checker's file (check --checker): who decided the manual checks and waivers in force
        "checker": ev.checker,
        "profile": {
            "id": p.id, "version": p.version, "title": p.title, "sha256": p.sha256,
            "source": p.source.model_dump(mode="json", exclude_none=True),
            "extends": [{"id": c[0], "version": c[1]} for c in p.chain[1:]],
            "parameters": {k: v.to_dict() for k, v in sorted(ev.parameters.items())},
            # mandatory rules of the standard the tender removed or weakened, with its justification
            **({"weakened": [w.to_dict() for w in p.weakened]} if getattr(p, "weakened", ()) else {}),
        },
        "delivery": {
            "id": d.id,
            "path": delivery_path if delivery_path is not None else d.root.name,
            "manifest_sha256": d.manifest_sha256,
            "project": man.project.model_dump(mode="json", exclude_none=True),
            "contractor": man.contractor.model_dump(mode="json", exclude_none=True),
            "operator": man.operator.model_dump(mode="json", exclude_none=True) if man.operator else None,
            "sensor": man.sensor.model_dump(mode="json", exclude_none=True),
            "dates": {k: str(v) for k, v in sorted(man.dates.items())},
            "files": d.files,
        },
        "verdict": ev.verdict,
        "fail_on": ev.fail_on,
        "summary": {"rules": len(ev.results), "records": n_records, **summary},
        "rollup": {"rejected": ev.rejected, "reasons": ev.reasons,
                   "incomplete": list(getattr(ev, "incomplete", None) or [])},
        "waivers_unused": ev.unused_waivers,
        # checker-file verdicts that judged nothing the delivery lists (red team R15)
        "manual_unused": list(getattr(ev, "manual_unused", None) or []),
        # the contractor's waiver requests (delivery.yaml): evidence, in force only when granted
        "waiver_requests": ev.waiver_requests,
        "rules": [],
        "records": [],
        "compact": {},
        "evidence": [],
        "details": ev.details,
    }
    doc = stable(doc)
    # already JSON-safe, field by field
    doc["rules"] = rules
    doc["records"] = records
    doc["compact"] = compact
    doc["evidence"] = evidence.table
    return doc


def dumps(doc: Mapping[str, Any]) -> str:
    """qcr.json text: readable header, then one record (or one rule's compact block) per line."""
    return "".join(iter_dumps(doc))


#: top-level keys written one element per line (a list's items, a mapping's entries) through the C
#: encoder; the other keys are small and written as ``json.dumps(value, indent=1)`` would
_PER_LINE = ("rules", "records", "compact", "evidence", "details")


def iter_dumps(doc: Mapping[str, Any]) -> Iterator[str]:
    """qcr.json as a stream of pieces (written to the file one by one; same bytes as :func:`dumps`).

    The header keys as ``json.dumps(doc, indent=1)`` would write them; ``rules``, ``records``,
    ``compact``, ``evidence`` and ``details`` one element per line (a rule summary, a record, one
    rule's columns, an evidence entry, one measure's detail), each compact: greppable, diffable,
    no piece larger than one element, and every large value goes through json's C encoder (the
    pure-Python one that ``indent`` needs took most of the time at a million check points)."""
    enc = json.JSONEncoder(ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode
    yield "{"
    for n, (key, value) in enumerate(doc.items()):
        yield ("\n " if n == 0 else ",\n ") + enc(str(key)) + ": "
        if key in _PER_LINE and isinstance(value, list) and value:
            for k, item in enumerate(value):
                yield ("[\n  " if k == 0 else ",\n  ") + enc(item)
            yield "\n ]"
        elif key in _PER_LINE and isinstance(value, dict) and value:
            for k, (name, item) in enumerate(value.items()):
                yield ("{\n  " if k == 0 else ",\n  ") + enc(str(name)) + ": " + _encode_columns(enc, item)
            yield "\n }"
        else:
            yield json.dumps(value, indent=1, ensure_ascii=False, allow_nan=False).replace("\n", "\n ")
    yield "\n}\n"


#: a list of at least this many texts is written by one join when none needs an escape
_JSON_JOIN_MIN = 256


def _encode_columns(enc: Any, value: Any) -> str:
    """``enc(value)``; a mapping's long columns of text (a compact block's item ids) joined at once
    when no text needs a JSON escape (a fifth of the encoder's time for a million ids)."""
    if not isinstance(value, dict) or not all(type(k) is str for k in value) or \
            not any(type(v) is list and len(v) >= _JSON_JOIN_MIN for v in value.values()):
        return str(enc(value))
    parts = []
    for k, v in value.items():
        text = _json_texts(v) if type(v) is list and len(v) >= _JSON_JOIN_MIN else None
        parts.append(enc(k) + ":" + (enc(v) if text is None else text))
    return "{" + ",".join(parts) + "}"


#: what json escapes in a text besides the quote and the backslash (ensure_ascii=False)
_JSON_CONTROL = re.compile("[\x00-\x1f]")
_JSON_CONTROL_ASCII = bytes(range(32))


def _json_texts(values: list[Any]) -> str | None:
    """A list of texts as the JSON encoder writes it (``["a","b"]``), or None when one is not text
    or needs an escape (a quote, a backslash, a control character)."""
    try:
        joined = '","'.join(values)
    except TypeError:
        return None
    if joined.count('"') != 2 * (len(values) - 1) or "\\" in joined:
        return None
    if len(joined) >= _LARGE and joined.isascii():
        b = joined.encode("ascii")
        if len(b.translate(None, _JSON_CONTROL_ASCII)) != len(b):
            return None
    elif _JSON_CONTROL.search(joined):
        return None
    return '["' + joined + '"]'


# --- writers --------------------------------------------------------------------------------

CSV_COLUMNS = ["rule", "clause", "scope", "item", "level", "consequence", "verdict", "measure",
               "measured_value", "measured_unit", "requirement", "evidence", "message"]


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
    from ..provenance import sha256_file

    path = Path(root) / str(entry["file"])
    if sha256_file(path) != entry.get("sha256"):
        raise OrthospecError(f"{entry['file']}: the file has changed since the check (SHA-256 differs)")
    import pandas as pd

    t = pd.read_csv(path, dtype=str, keep_default_na=False, skip_blank_lines=False, encoding="utf-8-sig")
    keep = ~(t.apply(lambda c: c.str.strip() == "").all(axis=1)).to_numpy(bool)
    for col, value in (entry["where"] or {}).items():
        keep &= (t[col].str.strip() == value).to_numpy(bool)
    rows = (np.flatnonzero(keep) + 1).tolist()
    if len(rows) != entry.get("rows_count", len(rows)):
        raise OrthospecError(f"{entry['file']}: the selector gives {len(rows)} rows, the record says "
                             f"{entry.get('rows_count')}")
    return rows


def to_csv(doc: Mapping[str, Any]) -> str:
    """qcr.csv: one row per record (expanded), spreadsheet-safe."""
    return "".join(iter_csv(doc))


def _csv_row(r: Mapping[str, Any]) -> list[Any]:
    """One record's qcr.csv cells (before :func:`csv_safe`)."""
    ev = "; ".join(evidence_text(e) for e in r["evidence"])
    return [r["rule"], _clause_text(r["clause"]), r["scope"], r["item"], r["level"], r["consequence"],
            r["verdict"], r["measure"], "" if r["measured"]["value"] is None else r["measured"]["value"],
            r["measured"]["unit"] or "", r["requirement"].get("text", ""), ev, r["message"]]


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


#: compact items written per piece by the block writers (bounds the strings held at once)
BLOCK_CHUNK = 50_000


def _resolve(col: Any, compact: Mapping[str, Any]) -> Any:
    """A compact column with its ``{"ref": ...}`` followed to the column written."""
    while isinstance(col, dict) and "ref" in col:
        rule_id, name = col["ref"]
        col = compact[rule_id][name]
    return col


class _Col:
    """A compact column as a list (per item) or one value for every item, as :func:`_column_values`
    reads it, without building a list of n equal values."""

    def __init__(self, col: Any, compact: Mapping[str, Any]) -> None:
        col = _resolve(col, compact)
        self.values: list[Any] | None = col if isinstance(col, list) else None
        self.const: Any = col.get("all") if isinstance(col, dict) else None

    def part(self, a: int, b: int) -> list[Any] | None:
        """Items a..b-1 as a list, or None when the column is one value."""
        return None if self.values is None else self.values[a:b]

    def get(self, a: int, b: int) -> Iterable[Any]:
        return itertools.repeat(self.const, b - a) if self.values is None else self.values[a:b]


class _Block:
    """One rule's compact block for the csv/junit writers: its columns resolved once, its rows
    built per slice of items with list operations (what :func:`_expand` yields as dicts, without
    a dict per item)."""

    def __init__(self, rule: Mapping[str, Any], block: Mapping[str, Any], evidence: list[dict[str, Any]],
                 compact: Mapping[str, Any]) -> None:
        self.rule = rule
        items = _resolve(block["items"], compact)
        self.items: list[Any] = list(items) if isinstance(items, list) else []  # as _expand: n = len(items)
        self.n = len(self.items)
        self.verdict = _Col(block.get("verdict"), compact)
        self.measured = _Col(block.get("measured"), compact)
        self.req = _Col(block["requirement"], compact) if "requirement" in block else None
        self.req_const = rule.get("requirement") or {}
        self.message = _Col(block.get("message"), compact)
        self.evidence = _resolve(block.get("evidence"), compact)
        self.table = evidence
        self.compact = compact
        self.shown = _shown_unit(rule.get("unit"))
        self.measure = rule.get("measure", "")
        self._etext: dict[int, str] = {}
        self._plain: dict[str, bool] = {}

    def items_plain_csv(self) -> bool:
        """Every id is a qcr.csv cell as it is (checked once for the block, not per slice)."""
        hit = self._plain.get("csv")
        if hit is None:
            hit = self._plain["csv"] = _plain_cells(self.items)
        return hit

    def items_plain_xml(self) -> bool:
        """Every id is text that junit.xml writes as it is (:data:`_XML_SPECIAL`), checked once."""
        hit = self._plain.get("xml")
        if hit is None:
            try:
                joined = "".join(self.items)  # text only (else TypeError)
            except TypeError:
                hit = False
            else:
                hit = not _xml_special(joined)
            self._plain["xml"] = hit
        return hit

    def req_texts(self, a: int, b: int) -> Iterable[str]:
        if self.req is None:
            return itertools.repeat(self.req_const.get("text", ""), b - a)
        part = self.req.part(a, b)
        if part is None:
            return itertools.repeat(self.req.const.get("text", ""), b - a)
        return [q.get("text", "") for q in part]

    def messages(self, a: int, b: int) -> list[str] | str:
        """Each item's message: the column's, or the default wording (:func:`_pass_message`) for None;
        one text when it is the same for every item (one measured value and one requirement)."""
        if self.message.values is None and (self.req is None or self.req.values is None) and \
                self.measured.values is None:
            text = self.req_texts(a, b)
            msg = self.message.const
            return _pass_message(self.measure, self.measured.const, self.shown, next(iter(text), "")) \
                if msg is None else msg
        msgs = list(self.message.get(a, b))
        todo = [k for k, m in enumerate(msgs) if m is None]
        if not todo:
            return msgs
        head, tail = f"{self.measure} = ", f"{self.shown}; required "
        measured = list(self.measured.get(a, b))
        texts = self.req_texts(a, b)
        texts = texts if isinstance(texts, list) else list(texts)
        if len(todo) == len(msgs):
            return [f"{head}{f'{v:.6g}' if type(v) is float else _fmt(v)}{tail}{t}"
                    for v, t in zip(measured, texts, strict=True)]
        for k in todo:
            msgs[k] = f"{head}{_fmt(measured[k])}{tail}{texts[k]}"
        return msgs

    def evidence_texts(self, a: int, b: int) -> Iterable[str]:
        """Each item's evidence as qcr.csv writes it (``"; "``-joined :func:`evidence_text`)."""
        col = self.evidence
        if isinstance(col, dict) and "entry" in col:  # one row of one file per item
            base = self.table[col["entry"]]
            head = str(base.get("file", "")) + "#rows="
            tail = f"#{base['path']}" if base.get("path") else ""
            rows = col["rows"][a:b]
            plain = not _CSV_SPECIAL.search(head + tail)  # the row numbers are digits: the cells as they are
            if plain and csv_safe(head) == head and None not in rows:
                return _Parts((head, list(map(str, rows)), tail))  # the head and tail merged into the line
            cells = ["" if r is None else f"{head}{r}{tail}" for r in rows]
            if plain:
                return _Cells(cells) if csv_safe(head) == head else _Cells(map(csv_safe, cells))
            return cells
        ids = _Col(col, self.compact)
        if ids.values is None:
            return itertools.repeat(self._ids_text(ids.const), b - a)
        return [self._ids_text(x) for x in ids.values[a:b]]

    def _ids_text(self, ids: Any) -> str:
        out = []
        for e in ids or []:
            t = self._etext.get(e)
            if t is None:
                t = self._etext[e] = evidence_text(self.table[e])
            out.append(t)
        return "; ".join(out)

    def csv_text(self, a: int, b: int) -> str:
        """qcr.csv lines of items a..b-1: every cell through :func:`csv_safe` and encoded as
        ``csv.writer`` writes it (:func:`_csv_cells`), constants once, lines joined in C."""
        rule = self.rule
        measured = self.measured.part(a, b)
        verdict = self.verdict.part(a, b)
        req = self.req_texts(a, b)
        ev = self.evidence_texts(a, b)
        items = self.items[a:b]
        cols: list[Any] = [
            rule["rule"], _clause_text(rule.get("citation") or {}), rule.get("scope", ""),
            items if self.items_plain_csv() else _csv_cells(items), rule.get("level"), rule.get("consequence"),
            self.verdict.const if verdict is None else _csv_cells(verdict), self.measure,
            ("" if self.measured.const is None else self.measured.const) if measured is None else
            [repr(v) if type(v) is float else _csv_cell(v) for v in measured],
            rule.get("unit") or "", _csv_cells(req) if isinstance(req, list) else next(iter(req), ""),
            ev if isinstance(ev, _Cells | _Parts) else _csv_cells(ev) if isinstance(ev, list) else next(iter(ev), ""),
            _csv_cells(msgs) if isinstance(msgs := self.messages(a, b), list) else msgs]
        return _lines(cols, len(items))


class _Cells(list):
    """Cells already as qcr.csv writes them (checked for the whole column at once)."""


class _Parts(tuple):
    """A column whose every cell is ``head + value + tail``: ``(head, values, tail)``, each already as
    qcr.csv writes it, so the head and tail join the line's constant text (no string per cell)."""


def _lines(cols: list[Any], n: int) -> str:
    """``n`` csv lines from encoded columns (a list of cells, or one value for every line): the
    separators and constant cells merged into pieces, the pieces of every line interleaved into one
    list by slice assignment and joined once (a tenth of the time of a join per line)."""
    pieces: list[Any] = []
    for j, c in enumerate(cols):
        sep = "," if j else ""
        seq = [sep + c[0], c[1], c[2]] if isinstance(c, _Parts) else ([sep, c] if sep else [c]) \
            if isinstance(c, list) else [sep + _csv_cell(c)]
        for x in seq:
            if isinstance(x, str) and pieces and isinstance(pieces[-1], str):
                pieces[-1] += x
            else:
                pieces.append(x)
    if isinstance(pieces[-1], str):
        pieces[-1] += "\n"
    else:
        pieces.append("\n")
    w = len(pieces)
    flat: list[str] = [""] * (n * w)
    for j, x in enumerate(pieces):
        if isinstance(x, list) and len(x) != n:
            raise ValueError(f"a compact column holds {len(x)} values for {n} items")
        flat[j::w] = x if isinstance(x, list) else [x] * n
    return "".join(flat)


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


def _rule_parts(doc: Mapping[str, Any]) -> Iterator[tuple[Mapping[str, Any] | None, list[Mapping[str, Any]],
                                                         _Block | None]]:
    """Per rule summary, in document order: the rule, its stored full records, its compact block;
    then the records without a rule summary (rule None) - what :func:`all_records` expands."""
    blocks = doc["compact"] or {}
    full: dict[str, list[Mapping[str, Any]]] = {}
    for rec in doc.get("records") or []:
        full.setdefault(rec["rule"], []).append(rec)
    evidence = doc.get("evidence") or []
    for summary in doc.get("rules") or []:
        rid = summary["rule"]
        block = blocks.get(rid)
        yield summary, full.pop(rid, []), (_Block(summary, block, evidence, blocks) if block else None)
    for rest in full.values():
        yield None, rest, None


def _merged(summary: Mapping[str, Any], full: list[Mapping[str, Any]], block: _Block | None
            ) -> Iterator[tuple[int, int] | dict[str, Any]]:
    """A rule's records in :func:`all_records` order: expanded full records (dicts) and slices
    ``(a, b)`` of the compact items between them. The order ``heapq.merge`` gives on the natural
    key (a full record before a compact item of the same key), found by binary search."""
    n = block.n if block is not None else 0
    at = 0
    for rec in full:
        pos = bisect.bisect_left(block.items, natural_key(rec["item"]), lo=at, key=natural_key) if n else 0
        for a in range(at, pos, BLOCK_CHUNK):
            yield a, min(pos, a + BLOCK_CHUNK)
        at = pos
        yield _expand_stored(summary, rec)
    for a in range(at, n, BLOCK_CHUNK):
        yield a, min(n, a + BLOCK_CHUNK)


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


#: the columns of qcr.parquet, in order (docs/QCR.md "Parquet table"); one row per record
PARQUET_COLUMNS: tuple[tuple[str, str], ...] = (
    ("rule", "string"), ("title", "string"), ("clause", "string"), ("scope", "string"), ("item", "string"),
    ("level", "string"), ("consequence", "string"), ("manual", "bool"), ("verdict", "string"),
    ("measure", "string"), ("measured_value", "float64"), ("measured_text", "string"),
    ("measured_unit", "string"), ("requirement_op", "string"), ("requirement_value", "float64"),
    ("requirement_min", "float64"), ("requirement_max", "float64"), ("requirement_unit", "string"),
    ("requirement_text", "string"), ("message", "string"), ("evidence", "string"),
    ("waiver", "string"), ("waiver_requested", "string"), ("waived_verdict", "string"),
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
    return None if v is None else json.dumps(v, ensure_ascii=False, sort_keys=True, separators=(",", ":"))


def _clause_text(c: Mapping[str, Any]) -> str:
    return ", ".join(str(c[k]) for k in ("document", "section", "table", "row") if c.get(k))


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

    schema = pa.schema([pa.field(name, pa.bool_() if t == "bool" else pa.float64() if t == "float64"
                                 else pa.string()) for name, t in PARQUET_COLUMNS],
                       metadata={"orthospec.qcr.schema": str(doc.get("schema")),
                                 "orthospec.qcr.date": str(doc.get("date")),
                                 "orthospec.delivery": str((doc.get("delivery") or {}).get("id"))})
    buf = pa.BufferOutputStream()
    cols: dict[str, list[Any]] = {name: [] for name, _ in PARQUET_COLUMNS}

    def flush(writer: Any) -> None:
        """One row group per PARQUET_ROWS records: Python objects held for one group only."""
        writer.write_table(pa.table({name: pa.array(values, type=schema.field(name).type)
                                     for name, values in cols.items()}, schema=schema))
        for values in cols.values():
            values.clear()

    n = 0
    with pq.ParquetWriter(buf, schema, compression="zstd", store_schema=True) as writer:
        for n, r in enumerate(all_records(doc), start=1):
            req = r.get("requirement") or {}
            value = r["measured"].get("value")
            row = {
                "rule": r["rule"], "title": r.get("title"), "clause": _clause_text(r.get("clause") or {}),
                "scope": r.get("scope"), "item": r["item"], "level": r.get("level"),
                "consequence": r.get("consequence"), "manual": bool(r.get("manual", False)),
                "verdict": r["verdict"], "measure": r.get("measure"), "measured_value": _number(value),
                "measured_text": _text(value), "measured_unit": r["measured"].get("unit"),
                "requirement_op": req.get("op"), "requirement_value": _number(req.get("value")),
                "requirement_min": _number(req.get("min")), "requirement_max": _number(req.get("max")),
                "requirement_unit": req.get("unit"), "requirement_text": req.get("text"),
                "message": r.get("message"), "evidence": _json_or_none(r.get("evidence") or []),
                "waiver": _json_or_none(r.get("waiver")), "waiver_requested": _json_or_none(r.get("waiver_requested")),
                "waived_verdict": r.get("waived_verdict"),
            }
            for name, values in cols.items():
                values.append(row[name])
            if n % PARQUET_ROWS == 0:
                flush(writer)
        if cols["rule"] or n == 0:
            flush(writer)
    return buf.getvalue().to_pybytes()


def to_junit(doc: Mapping[str, Any]) -> str:
    """junit.xml: one testsuite per rule, one testcase per item (CI systems render it natively)."""
    return "".join(iter_junit(doc))


def _junit_head(doc: Mapping[str, Any]) -> str:
    s = doc["summary"]
    return "\n".join(['<?xml version="1.0" encoding="UTF-8"?>',
           f'<testsuites name={_xml_attr("orthospec " + doc["profile"]["id"])} tests="{s["records"]}" '
           f'failures="{s[V.FAIL] + s[V.MISSING] + (s[V.WARN] if doc["fail_on"] == V.WARN else 0)}" '
           f'errors="{s[V.ERROR]}" skipped="{s[V.NOT_APPLICABLE] + s[V.WAIVED]}">']) + "\n"


def _xml_attr(v: Any) -> str:
    return _quoteattr(xml_text(v))


def _junit_suite(rid: str, tests: int, fails: int, errs: int, skipped: int) -> str:
    return (f'  <testsuite name={_xml_attr(rid)} tests="{tests}" failures="{fails}" '
            f'errors="{errs}" skipped="{skipped}">')


def _junit_case(rid: str, r: Mapping[str, Any], fail_on: str) -> str:
    """One record's testcase."""
    name = _xml_attr(f"{rid}[{r['item']}]")
    cls = _xml_attr(f"{r['scope']}.{rid}")
    v = r["verdict"]
    if v in (V.FAIL, V.MISSING) or (v == V.WARN and fail_on == V.WARN):
        body = _escape(xml_text(f"{r['title']} — {r['requirement'].get('text', '')}"))
        # the checker's own open work (consequence incomplete, an unsigned manual check) is told
        # apart from a failure of the contractor's products
        kind = V.INCOMPLETE if r.get("consequence") == V.INCOMPLETE or (r.get("manual") and v == V.MISSING) else v
        return (f'    <testcase name={name} classname={cls}><failure message={_xml_attr(r["message"])} '
                f'type="{kind}">{body}</failure></testcase>')
    if v == V.ERROR:
        body = _escape(xml_text(f"{r['title']} — {r['requirement'].get('text', '')}"))
        return (f'    <testcase name={name} classname={cls}><error message={_xml_attr(r["message"])} '
                f'type="error">{body}</error></testcase>')
    if v in V.NEUTRAL:
        return f'    <testcase name={name} classname={cls}><skipped message={_xml_attr(r["message"])}/></testcase>'
    return f'    <testcase name={name} classname={cls}/>'


def _counts(verdicts: Iterable[str] | _Counter[str]) -> tuple[int, int, int]:
    """(failures, errors, skipped) of a testsuite, as JUnit counts them (from the verdicts, or
    their counts)."""
    fails = errs = skipped = 0
    for v, k in (verdicts if isinstance(verdicts, _Counter) else _Counter(verdicts)).items():
        fails += k if v in (V.FAIL, V.MISSING) else 0
        errs += k if v == V.ERROR else 0
        skipped += k if v in V.NEUTRAL else 0
    return fails, errs, skipped


#: characters quoteattr/escape or xml_text would change: text without them is written as it is
_XML_SPECIAL = re.compile("[&<>\"'\n\r\t\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x84\x86-\x9f\ud800-\udfff\ufffe\uffff]")
#: the ASCII characters :data:`_XML_SPECIAL` matches (bytes.translate deletes them in one C pass)
_XML_SPECIAL_ASCII = bytes(i for i in range(128) if _XML_SPECIAL.match(chr(i)))


def _xml_special(text: str) -> bool:
    """``_XML_SPECIAL.search(text)``; ASCII text by deleting those bytes (a tenth of the regex's time)."""
    if len(text) < _LARGE or not text.isascii():
        return bool(_XML_SPECIAL.search(text))
    b = text.encode("ascii")
    return len(b.translate(None, _XML_SPECIAL_ASCII)) != len(b)


def _junit_block_cases(rid: str, block: _Block, a: int, b: int, fail_on: str, plain: bool) -> list[str] | str:
    """Testcases of compact items a..b-1: passes as one string operation per item when the rule id
    and the ids need no escaping (``plain``; every item a pass: the lines as one text, by slice
    assignment), any other verdict through :func:`_junit_case`."""
    rule = block.rule
    items = block.items[a:b]
    verdicts = block.verdict.part(a, b)
    cls = _xml_attr(f"{rule.get('scope', '')}.{rid}")
    if plain and verdicts is None and block.verdict.const == V.PASS:
        n = len(items)
        flat: list[str] = [""] * (3 * n)
        flat[0::3] = [f'    <testcase name="{rid}['] * n
        flat[1::3] = items
        flat[2::3] = [f']" classname={cls}/>\n'] * n
        return "".join(flat)
    vs = list(block.verdict.get(a, b))
    need = [k for k, v in enumerate(vs) if v != V.PASS or not plain]
    msgs: dict[int, str] = {}
    if need:
        allm = block.messages(a, b)
        reqs = list(block.req_texts(a, b))
        msgs = {k: allm[k] if isinstance(allm, list) else allm for k in need}
    out = []
    for k, (it, v) in enumerate(zip(items, vs, strict=True)):
        if v == V.PASS and plain:
            out.append(f'    <testcase name="{rid}[{it}]" classname={cls}/>')
        else:
            r = {"item": it, "scope": rule.get("scope", ""), "verdict": v, "message": msgs[k],
                 "title": rule.get("title", ""), "requirement": {"text": reqs[k]}}
            out.append(_junit_case(rid, r, fail_on))
    return out


def _iter_junit_records(doc: Mapping[str, Any]) -> Iterator[str]:
    """junit.xml record by record through :func:`all_records`: the reference :func:`iter_junit`
    matches byte for byte, and the path for version 1 documents."""
    yield _junit_head(doc)
    for rid, group in itertools.groupby(all_records(doc), key=lambda r: r["rule"]):
        recs = list(group)
        fails, errs, skipped = _counts(r["verdict"] for r in recs)
        out = [_junit_suite(rid, len(recs), fails, errs, skipped)]
        out.extend(_junit_case(rid, r, doc["fail_on"]) for r in recs)
        out.append("  </testsuite>")
        yield "\n".join(out) + "\n"
    yield "</testsuites>\n"


def iter_junit(doc: Mapping[str, Any]) -> Iterator[str]:
    """junit.xml as a stream of pieces: one testsuite per rule, its counts from the stored records'
    verdicts and the compact verdict column, its testcases a slice of items at a time (no list of
    a rule's records; the same bytes as :func:`_iter_junit_records`).

    Every text passes :func:`xml_text`, so control characters in delivery ids keep it well-formed."""
    rids = [r["rule"] for r in doc.get("rules") or []]
    if "compact" not in doc or len(set(rids)) != len(rids):
        yield from _iter_junit_records(doc)
        return
    fail_on = doc["fail_on"]
    yield _junit_head(doc)
    rest: list[Mapping[str, Any]] = []
    for summary, full, block in _rule_parts(doc):
        if summary is None:
            rest.extend(full)
            continue
        rid = summary["rule"]
        n = block.n if block is not None else 0
        if not full and not n:
            continue
        verdicts = [r["verdict"] for r in full]
        if block is not None:
            col = block.verdict.part(0, n)
            verdicts.extend(col if col is not None else [block.verdict.const])  # one stands for n
        counted = _Counter(verdicts)
        if block is not None and block.verdict.values is None:
            counted[block.verdict.const] += n - 1
        fails, errs, skipped = _counts(counted)
        del verdicts, counted
        out = [_junit_suite(rid, len(full) + n, fails, errs, skipped)]
        plain = block is not None and not _XML_SPECIAL.search(rid) and block.items_plain_xml()
        for part in _merged(summary, full, block):
            if isinstance(part, dict):
                out.append(_junit_case(rid, part, fail_on))
            else:
                assert block is not None
                cases = _junit_block_cases(rid, block, *part, fail_on, plain)
                if isinstance(cases, str):  # whole lines already
                    if out:
                        yield "\n".join(out) + "\n"
                    yield cases
                else:
                    out.extend(cases)
                    yield "\n".join(out) + "\n"
                out = []
        out.append("  </testsuite>")
        yield "\n".join(out) + "\n"
    if rest:
        for rid, group in itertools.groupby((dict(r) for r in rest), key=lambda r: r["rule"]):
            recs = list(group)
            fails, errs, skipped = _counts(r["verdict"] for r in recs)
            out = [_junit_suite(rid, len(recs), fails, errs, skipped)]
            out.extend(_junit_case(rid, r, fail_on) for r in recs)
            out.append("  </testsuite>")
            yield "\n".join(out) + "\n"
    yield "</testsuites>\n"


Output = str | bytes | Iterable[str]


def render_all(doc: dict[str, Any], formats: Iterable[str]) -> dict[str, Output]:
    """Every requested machine output, written by ``api.write_outputs`` all or none.

    qcr.json, qcr.csv and junit.xml are streams of pieces (:func:`iter_dumps`, :func:`iter_csv`,
    :func:`iter_junit`), written to their temporary files piece by piece; the others are rendered
    in memory first."""
    out: dict[str, Output] = {}
    fmts = set(formats)
    if "json" in fmts:
        out["qcr.json"] = iter_dumps(doc)
    if "csv" in fmts:
        out["qcr.csv"] = iter_csv(doc)
    if "junit" in fmts:
        out["junit.xml"] = iter_junit(doc)
    if "parquet" in fmts:
        out["qcr.parquet"] = to_parquet(doc)
    own = {"json", "csv", "junit", "parquet", "terminal", "html", "pdf"}
    for name in sorted(fmts - own):
        from .. import plugins  # lazy: only when a format a plugin adds is asked for

        fmt = plugins.output_format(name)
        if fmt is None:
            raise OrthospecError(f"unknown output format {name!r}: neither orthospec's nor a plugin's "
                                 "(orthospec.formats entry point)")
        out[f"qcr{fmt.suffix}"] = fmt.render(doc)
    return out
