"""A rule's compact block read column by column: the slices the block writers (qcr.csv,
junit.xml) write without a dict per record.
"""

from __future__ import annotations

import bisect
import itertools
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from .. import verdicts as V
from ..present import cite, fmt_value
from .cells import (
    _CSV_SPECIAL,
    _csv_cell,
    _csv_cells,
    _plain_cells,
    _xml_special,
    csv_safe,
    evidence_text,
)
from .columns import _pass_message, _shown_unit
from .order import natural_key
from .records import _expand_stored

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

    def __init__(
        self,
        rule: Mapping[str, Any],
        block: Mapping[str, Any],
        evidence: list[dict[str, Any]],
        compact: Mapping[str, Any],
    ) -> None:
        self.rule = rule
        items = _resolve(block["items"], compact)
        self.items: list[Any] = (
            list(items) if isinstance(items, list) else []
        )  # as _expand: n = len(items)
        self.n = len(self.items)
        self.verdict = _Col(block.get("verdict"), compact)
        self.measured = _Col(block.get("measured"), compact)
        self.req = _Col(block["requirement"], compact) if "requirement" in block else None
        self.req_const = rule.get("requirement") or {}
        self.message = _Col(block.get("message"), compact)
        self.reason = _Col(block["reason"], compact) if "reason" in block else None
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
        if (
            self.message.values is None
            and (self.req is None or self.req.values is None)
            and self.measured.values is None
        ):
            text = self.req_texts(a, b)
            msg = self.message.const
            return (
                _pass_message(self.measure, self.measured.const, self.shown, next(iter(text), ""))
                if msg is None
                else msg
            )
        msgs = list(self.message.get(a, b))
        todo = [k for k, m in enumerate(msgs) if m is None]
        if not todo:
            return msgs
        head, tail = f"{self.measure} = ", f"{self.shown}; required "
        measured = list(self.measured.get(a, b))
        texts = self.req_texts(a, b)
        texts = texts if isinstance(texts, list) else list(texts)
        if len(todo) == len(msgs):
            return [
                f"{head}{f'{v:.6g}' if type(v) is float and v == v else fmt_value(v)}{tail}{t}"
                for v, t in zip(measured, texts, strict=True)
            ]
        for k in todo:
            msgs[k] = f"{head}{fmt_value(measured[k])}{tail}{texts[k]}"
        return msgs

    def reasons(self, a: int, b: int) -> list[str] | str:
        """Each item's reason code as qcr.csv writes it ("" for a pass): the block's column, else
        the verdict's default (what :func:`_expand` gives)."""
        if self.reason is not None:
            part = self.reason.part(a, b)
            if part is None:
                return V.reason_of(str(self.verdict.const), self.reason.const) or ""
            return [
                V.reason_of(v, x) or "" for v, x in zip(self.verdict.get(a, b), part, strict=True)
            ]
        verdicts = self.verdict.part(a, b)
        if verdicts is None:
            return V.reason_of(str(self.verdict.const)) or ""
        return [V.reason_of(v) or "" for v in verdicts]

    def evidence_texts(self, a: int, b: int) -> Iterable[str]:
        """Each item's evidence as qcr.csv writes it (``"; "``-joined :func:`evidence_text`)."""
        col = self.evidence
        if isinstance(col, dict) and "entry" in col:  # one row of one file per item
            base = self.table[col["entry"]]
            head = str(base.get("file", "")) + "#rows="
            tail = f"#{base['path']}" if base.get("path") else ""
            rows = col["rows"][a:b]
            plain = not _CSV_SPECIAL.search(
                head + tail
            )  # the row numbers are digits: the cells as they are
            if plain and csv_safe(head) == head and None not in rows:
                return _Parts(
                    (head, list(map(str, rows)), tail)
                )  # the head and tail merged into the line
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
            rule["rule"],
            cite(rule.get("citation"), "columns"),
            rule.get("scope", ""),
            items if self.items_plain_csv() else _csv_cells(items),
            rule.get("level"),
            rule.get("consequence"),
            self.verdict.const if verdict is None else _csv_cells(verdict),
            self.measure,
            ("" if self.measured.const is None else self.measured.const)
            if measured is None
            else [repr(v) if type(v) is float else _csv_cell(v) for v in measured],
            rule.get("unit") or "",
            _csv_cells(req) if isinstance(req, list) else next(iter(req), ""),
            ev
            if isinstance(ev, _Cells | _Parts)
            else _csv_cells(ev)
            if isinstance(ev, list)
            else next(iter(ev), ""),
            _csv_cells(msgs) if isinstance(msgs := self.messages(a, b), list) else msgs,
            _csv_cells(why) if isinstance(why := self.reasons(a, b), list) else why,
        ]
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
        seq = (
            [sep + c[0], c[1], c[2]]
            if isinstance(c, _Parts)
            else ([sep, c] if sep else [c])
            if isinstance(c, list)
            else [sep + _csv_cell(c)]
        )
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


def _rule_parts(
    doc: Mapping[str, Any],
) -> Iterator[tuple[Mapping[str, Any] | None, list[Mapping[str, Any]], _Block | None]]:
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
        yield (
            summary,
            full.pop(rid, []),
            (_Block(summary, block, evidence, blocks) if block else None),
        )
    for rest in full.values():
        yield None, rest, None


def _merged(
    summary: Mapping[str, Any], full: list[Mapping[str, Any]], block: _Block | None
) -> Iterator[tuple[int, int] | dict[str, Any]]:
    """A rule's records in :func:`all_records` order: expanded full records (dicts) and slices
    ``(a, b)`` of the compact items between them. The order ``heapq.merge`` gives on the natural
    key (a full record before a compact item of the same key), found by binary search."""
    n = block.n if block is not None else 0
    items = block.items if block is not None else []
    at = 0
    for rec in full:
        pos = (
            bisect.bisect_left(items, natural_key(rec["item"]), lo=at, key=natural_key)
            if n
            else 0
        )
        for a in range(at, pos, BLOCK_CHUNK):
            yield a, min(pos, a + BLOCK_CHUNK)
        at = pos
        yield _expand_stored(summary, rec)
    for a in range(at, n, BLOCK_CHUNK):
        yield a, min(n, a + BLOCK_CHUNK)
