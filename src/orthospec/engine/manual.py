"""Manual rules (``manual: true``): a human verdict, from the checker's side only.

JRC §2 separates the contractor's internal quality control from the external quality control. The
verdict of a manual rule comes from the checker's file (``check --checker FILE``,
``manual_checks:``); the delivery's own ``manual_checks`` table is the contractor's internal-QC
statement, quoted in the record's message and listed as evidence, never a verdict. Without the
checker's entry the rule is ``missing`` ("still to be signed"). The record names who signed
(the checker file's inspector or party) and, separately, who stated what for the contractor.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..provenance import Evidence
from ..spec.models import Rule
from ..spec.operators import is_missing
from .applicability import applicable
from .compare import req_dict
from .context import FAIL, MISSING, NA, PASS, WARN, Context, RuleResult

UNSIGNED = ("manual check: no recorded verdict from the checker (check --checker FILE, "
            "manual_checks: check, item, date, verdict)")


def signed(ctx: Context, rule_id: str) -> dict[str, tuple[int, Any]]:
    """item -> (entry index, entry) of the checker file's verdicts on ``rule_id``."""
    if ctx.checker is None:
        return {}
    return {m.item: (i, m) for i, m in enumerate(ctx.checker.model.manual_checks) if m.check == rule_id}


def stated(ctx: Context, rule_id: str) -> dict[str, tuple[str, Evidence]]:
    """item -> (quoted statement, evidence) of the contractor's manual_checks rows on ``rule_id``."""
    t = ctx.d.table("manual_checks")
    if t is None:
        return {}
    df = t.df
    out: dict[str, tuple[str, Evidence]] = {}
    for _, h in df[df["check"] == rule_id].iterrows():
        row = int(h["_row"])
        extra = h.get("note")
        text = (f"the contractor's internal QC statement (evidence, not a verdict): "
                f"{str(h['verdict']).strip()!r} by {h['inspector']} on {h['date']} "
                f"({t.file} row {row})" + (f": {extra}" if not is_missing(extra) else ""))
        out[str(h["item"])] = (text, Evidence(t.file, t.sha256, (row,)))
    return out


def _signed_note(ctx: Context, rule: Rule, idx: int, entry: Any) -> tuple[int, str, Evidence]:
    """(verdict code, note, evidence) of one checker entry."""
    chk = ctx.checker
    assert chk is not None  # signed() found the entry in it
    who = entry.inspector or chk.who()
    if entry.verdict == "pass":
        code, note = PASS, f"signed by {who} on {entry.date}"
    else:
        code, note = (FAIL if rule.level == "mandatory" else WARN), f"judged failing by {who} on {entry.date}"
    note += f" (checker file {chk.name})" + (f": {entry.note}" if entry.note else "")
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
        ev: list[Evidence] = [] if c is None else [c[1]]
        note = UNSIGNED
        if k is not None:
            verdict[i], note, kev = _signed_note(ctx, rule, *k)
            measured[i] = k[1].verdict
            ev.append(kev)
        notes[i] = note if c is None else f"{note}; {c[0]}"
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
