"""Manual rules (``manual: true``): a human verdict, from the checker's side only.

JRC §2 separates the contractor's internal quality control from the external quality control. The
verdict of a manual rule comes from the checker's file (``check --checker FILE``,
``manual_checks:``); the delivery's own ``manual_checks`` table is the contractor's internal-QC
statement, quoted in the record's message and listed as evidence, never a verdict. Without the
checker's entry the rule is ``missing`` ("still to be signed"). The record names who signed
(the checker file's inspector or party) and, separately, who stated what for the contractor.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..provenance import Evidence
from ..spec.models import Rule
from ..spec.operators import is_missing
from .applicability import applicable
from .compare import req_dict
from .context import FAIL, MISSING, NA, PASS, WARN, Context, RuleResult

UNSIGNED = "manual check: no recorded verdict from the checker (check --checker FILE, manual_checks:)"


def signed(ctx: Context, rule_id: str) -> dict[str, tuple[int, Any]]:
    """item -> (entry index, entry) of the checker file's verdicts on ``rule_id``."""
    if ctx.checker is None:
        return {}
    return {m.item: (i, m) for i, m in enumerate(ctx.checker.model.manual_checks) if m.check == rule_id}


class Statement(NamedTuple):
    """One row of the contractor's manual_checks table, as evidence."""

    full: str  # quoted in full where no checker verdict exists
    short: str  # "contractor's internal QC: '<verdict>' (<file> row <n>)"
    said: str  # the contractor's verdict word, lower case
    evidence: Evidence


def stated(ctx: Context, rule_id: str) -> dict[str, Statement]:
    """item -> the contractor's statement (manual_checks row) on ``rule_id``."""
    t = ctx.d.table("manual_checks")
    if t is None:
        return {}
    df = t.df
    out: dict[str, Statement] = {}
    for _, h in df[df["check"] == rule_id].iterrows():
        row = int(h["_row"])
        said, where = str(h["verdict"]).strip(), f"{t.file} row {row}"
        extra = h.get("note")
        full = (f"the contractor's internal QC statement (evidence, not a verdict): {said!r}, {h['inspector']}, "
                f"{h['date']} ({where})" + (f": {extra}" if not is_missing(extra) else ""))
        out[str(h["item"])] = Statement(full, f"contractor's internal QC: {said!r} ({where})", said.lower(),
                                        Evidence(t.file, t.sha256, (row,)))
    return out


def _signed_note(ctx: Context, rule: Rule, idx: int, entry: Any) -> tuple[int, str, Evidence]:
    """(verdict code, note, evidence) of one checker entry; a failing verdict carries its reason."""
    chk = ctx.checker
    assert chk is not None  # signed() found the entry in it
    who = entry.inspector or ", ".join(x for x in (chk.party.name, chk.party.role) if x)
    if entry.verdict == "pass":
        return PASS, f"signed by {who} on {entry.date}", chk.evidence("manual_checks", idx)
    code = FAIL if rule.level == "mandatory" else WARN
    note = f"judged failing by {who} on {entry.date}" + (f": {entry.note}" if entry.note else "")
    return code, note, chk.evidence("manual_checks", idx)


def manual_rule(ctx: Context, rule: Rule, items: list[str]) -> RuleResult:
    """Judge a manual rule per item from the checker's verdicts; quote the contractor's statements."""
    items = items or [ctx.d.id]
    n = len(items)
    verdict = np.full(n, MISSING, dtype=np.int8)
    measured = np.full(n, None, dtype=object)
    notes = np.full(n, None, dtype=object)
    evidence: list[tuple[Evidence, ...]] = [()] * n
    by_checker, by_contractor = signed(ctx, rule.id), stated(ctx, rule.id)
    for i, item in enumerate(items):
        k = by_checker.get(item, by_checker.get("*"))
        c = by_contractor.get(item, by_contractor.get("*"))
        ev: list[Evidence] = [] if c is None else [c.evidence]
        if k is None:  # unsigned: the contractor's statement is quoted in full
            notes[i] = UNSIGNED if c is None else f"{UNSIGNED}; {c.full}"
        else:
            verdict[i], note, kev = _signed_note(ctx, rule, *k)
            measured[i] = k[1].verdict
            ev.append(kev)
            # the contractor's statement stays in the evidence; the message names it where it disagrees
            differs = c is not None and c.said != k[1].verdict
            notes[i] = f"{note}; {c.short}" if differs else note
        evidence[i] = tuple(ev)
    if rule.when:
        ok, unknown, unknown_note = applicable(ctx, rule, items)
        na = ~ok & ~unknown
        verdict[na] = NA
        notes[na] = f"not applicable: {rule.when} is false"
        if unknown.any():
            notes[unknown & (verdict == MISSING)] = unknown_note
    return RuleResult(rule, np.array(items, dtype=object), verdict, measured, "text",
                      req_dict(rule.requirement, None), evidence, notes)
