"""Reading a QCR document back: compact blocks expanded into records in full.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from .columns import COMPACT_VERDICTS, _full, _pass_message, _shown_unit
from .order import natural_key


def _expand_stored(rule: Mapping[str, Any], rec: Mapping[str, Any]) -> dict[str, Any]:
    """A stored record in full (version 2) as readers see it."""
    return _full(
        rule,
        rec["item"],
        rec["verdict"],
        rec.get("measured"),
        rec.get("requirement") or rule.get("requirement") or {},
        rec.get("evidence") or [],
        rec.get("message", ""),
        rec.get("waiver"),
        rec.get("waiver_requested"),
        rec.get("waived_verdict"),
        rec.get("reason"),
    )


def _column_values(col: Any, n: int, compact: Mapping[str, Any]) -> list[Any]:
    if isinstance(col, dict):
        if "ref" in col:
            rule_id, name = col["ref"]
            return _column_values(compact[rule_id][name], n, compact)
        return [col.get("all")] * n
    return list(col) if col is not None else [None] * n


def _evidence_values(
    col: Any, n: int, compact: Mapping[str, Any], table: list[dict[str, Any]]
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


def block_columns(
    rule: Mapping[str, Any], block: Mapping[str, Any], compact: Mapping[str, Any]
) -> tuple[Sequence[Any], ...]:
    """A compact block's items, verdicts, measured values, requirements and messages, one value
    per item each: the one reading of these columns (records here, the ledger's rows)."""
    items = _column_values(block["items"], 0, compact)
    n = len(items)
    verdicts = _column_values(block.get("verdict"), n, compact)
    measured = _column_values(block.get("measured"), n, compact)
    reqs = (
        _column_values(block["requirement"], n, compact)
        if "requirement" in block
        else [rule.get("requirement") or {}] * n
    )
    msgs = _column_values(block.get("message"), n, compact)
    return items, verdicts, measured, reqs, msgs


def _expand(
    rule: Mapping[str, Any],
    block: Mapping[str, Any],
    evidence: list[dict[str, Any]],
    compact: Mapping[str, Any],
) -> Iterator[dict[str, Any]]:
    """The records of one rule's compact block (the same dicts as records in full)."""
    items, verdicts, measured, reqs, msgs = block_columns(rule, block, compact)
    n = len(items)
    evs = _evidence_values(block.get("evidence"), n, compact, evidence)
    asked = _column_values(block.get("waiver_requested"), n, compact)
    why = _column_values(block.get("reason"), n, compact)
    shown = _shown_unit(rule.get("unit"))
    measure = rule.get("measure", "")
    for k, ev in zip(range(n), evs, strict=True):
        req = reqs[k]
        msg = msgs[k]
        if msg is None:
            msg = _pass_message(measure, measured[k], shown, req.get("text", ""))
        yield _full(
            rule, items[k], verdicts[k], measured[k], req, ev, msg, None, asked[k], None, why[k]
        )


def all_records(doc: Mapping[str, Any], *, compact: bool = True) -> Iterator[dict[str, Any]]:
    """Every record of a QCR document, in document order (scope, rule id, item in natural order).

    The one way to read records (docs/QCR.md). Version 2 documents store each record once,
    without its rule's text: ``doc["records"]`` holds the records whose verdict is not pass or
    not applicable (item, verdict, measured value, evidence, message...), ``doc["compact"]`` the
    others as columns per rule; both are expanded here with the rule summary into the same dicts.
    Version 1 documents (every record in full in ``records``) are read as they are.

    ``compact=False`` leaves out the pass and not-applicable records (what the terminal needs, at
    the cost of the problems only, whatever the size of the delivery).
    """
    records = doc.get("records") or []
    if "compact" not in doc:
        yield from (
            records if compact else (r for r in records if r.get("verdict") not in COMPACT_VERDICTS)
        )
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
            yield from heapq.merge(
                mine,
                _expand(summary, block, evidence, blocks),
                key=lambda r: natural_key(r["item"]),
            )


def record_groups(
    doc: Mapping[str, Any], *, compact: bool = True
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
