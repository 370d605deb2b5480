"""The ledger's QCR rows of a qcr.json document, generated one at a time from its compact columns.

``rows_with_text(doc)`` yields, in document order, exactly the rows ``qcr_row(i, rec)`` gives for
``enumerate(all_records(doc))`` (the one way to read records, docs/QCR.md), as value tuples
with each row's canonical text (what the chain hash is fed), without building the full record of
each pass / not-applicable item or its evidence (which the ledger does not store): a rule over a
million check points is a million small tuples and texts made and dropped a batch at a time, the
texts assembled from the rule's constant parts encoded once. ``canonical_texts`` is the same text
for rows read back from the database (``verify``).
"""

from __future__ import annotations

import heapq
import math
import operator
from collections.abc import Iterator, Mapping, Sequence
from json.encoder import encode_basestring
from typing import Any, cast

from .audit import family_of
from .chain import canonical

#: the QCR columns of a row, sorted (the order canonical JSON writes them in); ``run_id`` is not part
QCR_COLUMNS = (
    "clause_document",
    "clause_row",
    "clause_section",
    "clause_table",
    "consequence",
    "family",
    "item",
    "level",
    "manual",
    "measure",
    "measured",
    "message",
    "ordinal",
    "requirement",
    "requirement_text",
    "rule",
    "scope",
    "unit",
    "verdict",
)


def _s(x: Any) -> str | None:
    return None if x is None else str(x)


def qcr_row(i: int, rec: Mapping[str, Any]) -> dict[str, Any]:
    """The ledger row of one QCR record as ``all_records`` yields it (``ordinal`` = its position)."""
    clause = rec.get("clause") or {}
    measured = rec.get("measured") or {}
    req = rec.get("requirement") or {}
    return {
        "clause_document": _s(clause.get("document")),
        "clause_row": _s(clause.get("row")),
        "clause_section": _s(clause.get("section")),
        "clause_table": _s(clause.get("table")),
        "consequence": rec.get("consequence"),
        "family": family_of(rec),
        "item": str(rec["item"]),
        "level": rec.get("level"),
        "manual": bool(rec.get("manual", False)),
        "measure": rec.get("measure"),
        "measured": canonical(measured.get("value")),
        "message": rec.get("message"),
        "ordinal": i,
        "requirement": canonical(req),
        "requirement_text": req.get("text"),
        "rule": str(rec["rule"]),
        "scope": str(rec["scope"]),
        "unit": measured.get("unit"),
        "verdict": str(rec["verdict"]),
    }


def json_value(v: Any) -> str:
    """``canonical(v)``; a number, text or null without going through the encoder object."""
    t = type(v)
    if t is bool:
        return "true" if v else "false"
    if t is float:
        return (
            float.__repr__(v) if math.isfinite(v) else canonical(v)
        )  # non-finite: the encoder's error
    if t is int:
        return int.__repr__(v)
    if v is None:
        return "null"
    if t is str:
        return str(encode_basestring(v))
    return canonical(v)


#: position of the item in a row's values
_ITEM = QCR_COLUMNS.index("item")
#: a row dict's values in QCR_COLUMNS order
row_values = operator.itemgetter(*QCR_COLUMNS)

#: (a row's values in QCR_COLUMNS order, its canonical text: ``canonical(dict(zip(QCR_COLUMNS, values)))``)
Row = tuple[tuple[Any, ...], str]
#: a compact block's row before it is numbered (text None: its ordinal is not known yet)
_Draft = tuple[tuple[Any, ...], str | None]


class _Encoded(dict[Any, str]):
    """value -> its canonical text, made on first use (one column of a batch: a text repeated down
    the rows is escaped once). Keys compare by value (1 == 1.0 == True), so only for the columns
    the schema types as text: SQLite's text affinity turns a number written there into text, and
    PostgreSQL keeps the type, so their values are texts or nulls (a blob fails, as it did before)."""

    def __missing__(self, v: Any) -> str:
        t = self[v] = json_value(v)
        return t


#: columns typed as numbers or flags (never through :class:`_Encoded`)
_NUMERIC = frozenset(QCR_COLUMNS.index(c) for c in ("manual", "ordinal"))


def _column_texts(k: int, col: Sequence[Any], texts_only: bool) -> Iterator[str]:
    """The canonical texts of one column of a batch: numbers and flags one by one; a column whose
    first values repeat through a cache; other text columns by the C escaper alone when
    ``texts_only`` (a null there raises TypeError and the caller takes the general path)."""
    if k in _NUMERIC:
        return map(json_value, col)
    head = col[:64]
    if len(set(head)) * 4 <= len(head):
        return map(_Encoded().__getitem__, col)
    return map(encode_basestring if texts_only else json_value, col)


def _texts(rows: Sequence[Sequence[Any]], texts_only: bool) -> list[str]:
    cols = [_column_texts(k, col, texts_only) for k, col in enumerate(zip(*rows, strict=True))]
    if len(cols) != len(QCR_COLUMNS):
        raise ValueError(f"a QCR row has {len(cols)} values, expected {len(QCR_COLUMNS)}")
    return [
        f'{{"clause_document":{a},"clause_row":{b},"clause_section":{c},"clause_table":{d},'
        f'"consequence":{e},"family":{f},"item":{g},"level":{h},"manual":{i},"measure":{j},'
        f'"measured":{k},"message":{l_},"ordinal":{m},"requirement":{n},"requirement_text":{o},'
        f'"rule":{p},"scope":{q},"unit":{r},"verdict":{s}}}'
        for a, b, c, d, e, f, g, h, i, j, k, l_, m, n, o, p, q, r, s in zip(*cols, strict=True)
    ]


def canonical_texts(rows: Sequence[Sequence[Any]]) -> list[str]:
    """``canonical(dict(zip(QCR_COLUMNS, values)))`` of each row's values (what ``verify`` hashes),
    written column by column (each column of the batch mapped to its texts in C where it can be),
    then each row's text assembled in one format."""
    if not rows:
        return []
    try:
        return _texts(rows, texts_only=True)
    except TypeError:  # a null in a column of varied texts: each value by its type
        return _texts(rows, texts_only=False)


def _with_text(row: dict[str, Any]) -> Row:
    return row_values(row), canonical(row)


def _compact_rows(
    rule: Mapping[str, Any], block: Mapping[str, Any], compact: Mapping[str, Any], start: int | None
) -> Iterator[_Draft]:
    """Rows of one rule's compact block, read as ``qcr._expand`` reads it: rule constants once, per
    item only what varies. With ``start`` (the first ordinal) each row comes with its canonical
    text, built from the rule's constant parts already encoded (the same text :func:`canonical`
    gives, tests/test_ledger_scale.py); without, ordinal 0 and no text (the caller merges them)."""
    from ..qcr import _full, _pass_message, _shown_unit, block_columns

    items, verdicts, measured, reqs, msgs = block_columns(rule, block, compact)
    n = len(items)
    const = qcr_row(
        0, _full(rule, "", "", None, {}, [], "")
    )  # what every record of the rule shares
    cd, crow, csec, ctab = (
        const["clause_document"],
        const["clause_row"],
        const["clause_section"],
        const["clause_table"],
    )
    consequence, family, level, manual = (
        const["consequence"],
        const["family"],
        const["level"],
        const["manual"],
    )
    measure, rule_id, scope, unit = const["measure"], const["rule"], const["scope"], const["unit"]
    jv = json_value
    head = (
        f'{{"clause_document":{jv(cd)},"clause_row":{jv(crow)},"clause_section":{jv(csec)},'
        f'"clause_table":{jv(ctab)},"consequence":{jv(consequence)},"family":{jv(family)},"item":'
    )
    mid = f',"level":{jv(level)},"manual":{jv(manual)},"measure":{jv(measure)},"measured":'
    tail = f',"rule":{jv(rule_id)},"scope":{jv(scope)},"unit":{jv(unit)},"verdict":'
    shown = _shown_unit(rule.get("unit"))
    measure_text = rule.get("measure", "")
    # the previous item's value and its texts: a constant column ({"all": v}) is one object, so
    # its texts are made once; a column of distinct values costs one comparison per item more
    none: Any = object()
    last_v = last_req = last_msg = last_verdict = none
    v_text = v_json = req_text = req_json = msg_json = verdict = verdict_json = pass_msg = ""
    req_words: str | None = None
    pass_key: tuple[Any, Any] = (none, none)
    for k in range(n):
        v, req, msg = measured[k], reqs[k], msgs[k]
        if v is not last_v:
            last_v, v_text = v, jv(v)
            v_json = str(encode_basestring(v_text))
        if req is not last_req:
            last_req = req
            r = req or {}
            req_text, req_words = canonical(r), r.get("text")
            req_json = (
                f',"requirement":{encode_basestring(req_text)},"requirement_text":{jv(req_words)}'
            )
        if msg is None:
            if pass_key[0] is not v or pass_key[1] is not req:
                pass_key, pass_msg = (
                    (v, req),
                    _pass_message(measure_text, v, shown, req.get("text", "")),
                )
            msg = pass_msg
        if msg is not last_msg:
            last_msg, msg_json = msg, jv(msg)
        if verdicts[k] is not last_verdict:
            last_verdict = verdicts[k]
            verdict = str(last_verdict)
            verdict_json = jv(verdict)
        item = str(items[k])
        values = (
            cd,
            crow,
            csec,
            ctab,
            consequence,
            family,
            item,
            level,
            manual,
            measure,
            v_text,
            msg,
            0 if start is None else start + k,
            req_text,
            req_words,
            rule_id,
            scope,
            unit,
            verdict,
        )
        if start is None:
            yield values, None
        else:
            yield (
                values,
                (
                    f'{head}{encode_basestring(item)}{mid}{v_json},"message":{msg_json},'
                    f'"ordinal":{start + k}{req_json}{tail}{verdict_json}}}'
                ),
            )


def rows_with_text(doc: Mapping[str, Any]) -> Iterator[Row]:
    """(values in QCR_COLUMNS order, canonical text) of every record's row, ordinal 0, 1, ... in
    document order (``qcr.record_groups``, the walk ``all_records`` takes)."""
    from ..qcr import _expand_stored, all_records, natural_key, record_groups

    n = 0
    if "compact" not in doc:  # version 1: every record in full
        for rec in all_records(doc):
            yield _with_text(qcr_row(n, rec))
            n += 1
        return
    blocks = doc["compact"] or {}
    for summary, stored, block in record_groups(doc):
        if summary is None:  # records without a rule summary: as stored
            for kept in stored:
                yield _with_text(qcr_row(n, dict(kept)))
                n += 1
        elif not block:
            for kept in stored:
                yield _with_text(qcr_row(n, _expand_stored(summary, kept)))
                n += 1
        elif not stored:
            for row in cast(
                Iterator[Row], _compact_rows(summary, block, blocks, n)
            ):  # numbered: with text
                yield row
                n += 1
        else:
            mine = ((row_values(qcr_row(0, _expand_stored(summary, rec))), None) for rec in stored)
            for values, _ in heapq.merge(
                mine,
                _compact_rows(summary, block, blocks, None),
                key=lambda r: natural_key(r[0][_ITEM]),
            ):
                merged = dict(zip(QCR_COLUMNS, values, strict=True))
                merged["ordinal"] = n
                yield _with_text(merged)
                n += 1
