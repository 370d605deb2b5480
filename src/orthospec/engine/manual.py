"""Manual rules (``manual: true``): a human verdict, from the checker's side only.

JRC §2 separates the contractor's internal quality control from the external quality control. The
verdict of a manual rule comes from the checker's file (``check --checker FILE``,
``manual_checks:``); the delivery's own ``manual_checks`` table is the contractor's internal-QC
statement, quoted in the record's message and listed as evidence, never a verdict. Without the
checker's entry the rule is ``missing`` ("still to be signed"). The record names who signed
(the checker file's inspector or party) and, separately, who stated what for the contractor.

A checker verdict on an item the delivery no longer lists (the contractor deleted the row after
the checker judged it) never vanishes: the rule's record keeps that item with the checker's
verdict, the roll-up returns the delivery naming it (engine/rollup.py), and ``unused`` lists
the checker entries that judged nothing delivered (red team R15; JRC §2.4, §12.3).

A verdict is bound to what was judged (issue 29 item 4). For an item that is a delivered file (an
image), the checker's entry records that file and its SHA-256 (``file``, ``sha256``: `orthospec
checker init` writes them); an entry whose item's file now has other content (changed, or another
file swapped in), or that records none, is ``missing`` with the reason, never carried over to other
pixels (the same content renamed is the same image). An entry
without a verdict is still to be judged (the skeleton). The checker's marked inspection grid
(inspection/grid.py) gives image verdicts of the rules specs/inspection.yaml names: the marked
cells (ids, defect classes, comment) are the evidence; where the grid and an entry of the checker's
file disagree, the failing one stands and the record names both.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..delivery.convention import table_of_scope
from ..profile.models import Rule
from ..profile.operators import is_missing
from ..provenance import Evidence
from ..verdicts import Reason
from .applicability import applicable
from .compare import req_dict
from .context import FAIL, MISSING, NA, PASS, WARN, Context, RuleResult

UNSIGNED = (
    "manual check: no recorded verdict from the checker (check --checker FILE, manual_checks:)"
)


def gone_reason(item: str) -> str:
    """Why a checker verdict on an item missing from the delivery is a finding (one wording)."""
    return f"the checker's verdict on {item} refers to an item the delivery no longer lists"


def vanished(ctx: Context, rule: Rule, items: list[str]) -> list[str]:
    """The items the checker judged on ``rule`` (its file's entries, its inspection grid's images) that are
    not among the delivery's ``items``."""
    have = set(map(str, items))
    grid = ctx.cache.ctx.inspection if rule.scope == "image" else None
    judged = set(signed(ctx, rule.id)) | (grid.answers(rule.id) if grid is not None else set())
    return sorted(i for i in judged if i != "*" and i not in have)


def vanished_in(ctx: Context, r: RuleResult) -> list[str]:
    """The items of a manual rule's record the checker judged but the delivery no longer lists."""
    if not r.rule.manual or ctx.checker is None:
        return []
    listed, _ = ctx.universe(r.rule.scope)
    if listed is None:
        listed = [ctx.d.id]
    return vanished(ctx, r.rule, listed)


def unused(ctx: Context, results: list[RuleResult]) -> list[dict[str, Any]]:
    """Checker entries that judged nothing the delivery lists (like ``waivers.unused``), each with why.

    An entry is unused when the profile has no manual rule of its ``check``, or its item is not
    listed by the delivery (the record still carries it, see ``vanished``).
    """
    if ctx.checker is None:
        return []
    manual = {r.rule.id: r for r in results if r.rule.manual}
    out = []
    for i, m in enumerate(ctx.checker.model.manual_checks):
        r = manual.get(m.check)
        if r is None:
            why = f"the profile {ctx.profile.id} has no manual rule {m.check}"
        elif m.item != "*" and m.item in vanished_in(ctx, r):
            why = gone_reason(m.item)
        else:
            continue
        out.append(
            {
                **m.model_dump(mode="json", exclude_none=True),
                "entry": i + 1,
                "checker_file": ctx.checker.name,
                "reason": why,
            }
        )
    return out


def signed(ctx: Context, rule_id: str) -> dict[str, tuple[int, Any]]:
    """item -> (entry index, entry) of the checker file's verdicts on ``rule_id`` (entries still to be
    judged, without a verdict, are left out)."""
    if ctx.checker is None:
        return {}
    return {
        m.item: (i, m)
        for i, m in enumerate(ctx.checker.model.manual_checks)
        if m.check == rule_id and m.verdict is not None
    }


def item_files(ctx: Context, scope: str) -> dict[str, str]:
    """item -> the file the delivery gives it now (the ``file`` column of the scope's table, e.g. an
    image's), for binding the checker's verdicts to content; {} for scopes without files."""
    name = table_of_scope(scope)
    t = ctx.d.table(name) if name is not None else None
    if t is None or "file" not in t.df:
        return {}
    cells = t.df["file"]
    have = cells.notna().to_numpy()
    return dict(zip(t.ids[have].tolist(), cells[have].astype(str).tolist(), strict=True))


def unbound_reason(ctx: Context, entry: Any, item: str, now: str | None) -> str | None:
    """Why the checker's ``entry`` on ``item`` (whose file is ``now``) is not bound to what the delivery
    holds now, or None when it is (or when the item has no file to bind to)."""
    if now is None:
        return None
    sha = ctx.file_sha256(now)
    if entry.file is None:
        if sha is None:  # the item's file is not delivered: no content to bind the verdict to
            return None
        return (
            f"the checker's verdict on {item} records no file and SHA-256 of what was judged ({now} now): "
            "`orthospec checker init` writes them; a verdict is never carried over to unknown content"
        )
    if sha is not None and sha.lower() == entry.sha256.lower():
        return None  # the content judged, whatever the file is named now (a rename is not a change)
    if sha is None:
        return f"the checker's verdict on {item} was given on {entry.file}, which the delivery no longer holds"
    if entry.file != now:
        return (
            f"the checker's verdict on {item} was given on {entry.file} (SHA-256 {entry.sha256.lower()[:12]}…); "
            f"the delivery now gives {now} ({sha[:12]}…): judge it again"
        )
    return (
        f"the checker's verdict on {item} was given on {entry.file} with SHA-256 {entry.sha256.lower()[:12]}…; "
        f"the delivered file is {sha[:12]}… (changed or swapped since): judge it again"
    )


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
        full = (
            f"the contractor's internal QC statement (evidence, not a verdict): {said!r}, {h['inspector']}, "
            f"{h['date']} ({where})" + (f": {extra}" if not is_missing(extra) else "")
        )
        out[str(h["item"])] = Statement(
            full,
            f"contractor's internal QC: {said!r} ({where})",
            said.lower(),
            Evidence(t.file, t.sha256, (row,)),
        )
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


def _grid_evidence(grid: Any, g: Any) -> Evidence:
    """The grid file (name and hash) and the cells behind a grid verdict (ids, defect classes, comment)."""
    cells = "; ".join(
        f"{c['cell_id']}: {', '.join(c['defects'])}"
        + (f' "{c["comment"]}"' if c.get("comment") else "")
        for c in g.cells[:20]
    )
    more = f"; and {len(g.cells) - 20} more" if len(g.cells) > 20 else ""
    return Evidence(
        f"checker:{grid.path.name}", grid.sha256, (), f"cells: {cells}{more}" if cells else "cells"
    )


def manual_rule(ctx: Context, rule: Rule, items: list[str]) -> RuleResult:
    """Judge a manual rule per item from the checker's verdicts; quote the contractor's statements."""
    items = items or [ctx.d.id]
    gone = vanished(ctx, rule, items)
    items = list(items) + gone
    n = len(items)
    verdict = np.full(n, MISSING, dtype=np.int8)
    measured = np.full(n, None, dtype=object)
    notes = np.full(n, None, dtype=object)
    # a manual record is missing because nobody signed it (for this content), unless said otherwise
    reasons = np.full(n, Reason.UNSIGNED, dtype=object)
    evidence: list[tuple[Evidence, ...]] = [()] * n
    by_checker, by_contractor = signed(ctx, rule.id), stated(ctx, rule.id)
    files = item_files(ctx, rule.scope)
    grid = ctx.cache.ctx.inspection if rule.scope == "image" else None
    for i, item in enumerate(items):
        k = by_checker.get(item, by_checker.get("*"))
        c = by_contractor.get(item, by_contractor.get("*"))
        g = grid.verdict(rule.id, item, gone=item in gone) if grid is not None else None
        ev: list[Evidence] = [] if c is None else [c.evidence]
        unbound = (
            unbound_reason(ctx, k[1], item, files.get(item))
            if k is not None and item not in gone
            else None
        )
        if unbound is not None:
            assert (
                k is not None and ctx.checker is not None
            )  # a verdict was signed in the checker's file
            ev.append(ctx.checker.evidence("manual_checks", k[0]))
            k = None
        if g is not None:
            ev.append(_grid_evidence(grid, g))
        if k is None and g is None:  # unsigned: the contractor's statement is quoted in full
            notes[i] = unbound or (UNSIGNED if c is None else f"{UNSIGNED}; {c.full}")
            if unbound is not None and c is not None:
                notes[i] = f"{unbound}; {c.short}"
        elif k is None:  # the grid alone
            assert g is not None
            verdict[i] = {"pass": PASS, "fail": FAIL if rule.level == "mandatory" else WARN}.get(
                g.verdict, MISSING
            )
            measured[i] = g.verdict if g.verdict != "missing" else None
            notes[i] = g.note if unbound is None else f"{g.note}; {unbound}"
            if c is not None and g.verdict != "missing" and c.said != g.verdict:
                notes[i] = f"{notes[i]}; {c.short}"
            if item in gone:
                notes[i] = f"{gone_reason(item)} ({notes[i]}); the delivery is returned"
        else:
            verdict[i], note, kev = _signed_note(ctx, rule, *k)
            measured[i] = k[1].verdict
            ev.append(kev)
            if g is not None and g.verdict == "fail" and k[1].verdict == "pass":
                verdict[i] = FAIL if rule.level == "mandatory" else WARN
                measured[i] = "fail"
                note = f"{g.note} (the checker's file signs it pass: the marked grid stands)"
            elif g is not None and g.verdict != k[1].verdict:
                note = f"{note}; {g.note}"
            # the contractor's statement stays in the evidence; the message names it where it disagrees
            differs = c is not None and c.said != measured[i]
            notes[i] = f"{note}; {c.short}" if c is not None and differs else note
            if item in gone:
                notes[i] = f"{gone_reason(item)} ({notes[i]}); the delivery is returned"
        evidence[i] = tuple(ev)
    listed = n - len(
        gone
    )  # a vanished item has no facts for `when`: it keeps the checker's verdict
    if rule.when and listed:
        ok, unknown, unknown_note = applicable(ctx, rule, items[:listed])
        na = np.zeros(n, dtype=bool)
        na[:listed] = ~ok & ~unknown
        verdict[na] = NA
        notes[na] = f"not applicable: {rule.when} is false"
        reasons[na] = Reason.CONDITION_FALSE
        if unknown.any():
            unk = np.zeros(n, dtype=bool)
            unk[:listed] = unknown
            notes[unk & (verdict == MISSING)] = unknown_note
            reasons[unk & (verdict == MISSING)] = Reason.UNKNOWN_FACT
    reasons[(verdict == FAIL) | (verdict == WARN)] = Reason.NOT_MET
    return RuleResult(
        rule,
        np.array(items, dtype=object),
        verdict,
        measured,
        "text",
        req_dict(rule.requirement, None),
        evidence,
        notes,
        reasons=reasons,
    )
