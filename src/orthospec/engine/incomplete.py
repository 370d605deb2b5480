"""What the checker must still do: findings that leave the check incomplete, as instructions.

JRC chapter 12 makes the external check the checker's work: bad or too few check points are
dropped, relocated or completed by the checker (§12.5 "relocated", §12.6 blunders "removed from the
sample", §12.7 "acquisition of further points"), and "The Commission will check" the sample of
images and blocks (§12.3, §12.8). Such a finding is never the contractor's fault, so it rejects
nothing: a rule with consequence ``incomplete`` (and a manual check the checker has not signed)
keeps the check open - overall verdict ``incomplete``, never ACCEPTED - with one line per item that
says what to add ("B03: 6 more check points"). A real failure elsewhere still rejects.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import verdicts as V
from ..present import fmt_number

if TYPE_CHECKING:
    from .context import RuleResult

#: the evaluator's integer codes (engine/context.py uses the same: ``VERDICTS[code]``); imported
#: from the vocabulary so that ledger/signed.py can use this module without the engine
MISSING, ERROR = V.CODE[V.MISSING], V.CODE[V.ERROR]

#: lines listed per rule; the rest are counted ("+N more")
MAX_LINES = 20

#: what one unit of a count measure is (singular, plural) and what the checker does with it
NOUNS: dict[str, tuple[str, str, str]] = {
    "checkpoints.n": ("check point", "check points", ""),
    "checkpoints.count": ("check point", "check points", ""),
    "checkpoints.duplicate_locations": (
        "check point repeating another",
        "check points repeating another",
        "to replace by independent points",
    ),
    "checkpoints.blunders_unjustified": (
        "exclusion request",
        "exclusion requests",
        "to justify as §12.6 asks or to withdraw",
    ),
    "checkpoints.near_gcp": (
        "check point at a GCP",
        "check points at a GCP",
        "to replace by points independent of the GCPs",
    ),
    "checkpoints.zero_residuals": (
        "check point with a zero residual",
        "check points with a zero residual",
        "to measure on the image",
    ),
    "checkpoints.block_cells_bad": (
        "check point naming no single block",
        "check points naming no single block",
        "to assign to one block",
    ),
    "checkpoints.outside_block": (
        "check point outside the block",
        "check points outside the block",
        "to assign to their block or replace",
    ),
    "checkpoints.imprecise": (
        "check point with an imprecise reference",
        "check points with an imprecise reference",
        "to re-survey or replace",
    ),
}
#: roll-up shares whose remedy is a number of items to add to the checker's sample
SHARES: dict[str, tuple[str, str, str]] = {
    "rollup.images_sampled_share": ("image", "images", "to inspect in the sample"),
    "rollup.blocks_checked_share": ("block", "blocks", "to check with check points"),
}
#: what the checker does with an item of a measure that is not a count
REMEDY: dict[str, str] = {
    "checkpoints.precision_xy": "re-survey it or replace it with a more precise point",
    "checkpoints.min_gcp_distance": "replace the check points that coincide with GCPs by independent ones",
    "sample.strata_missed": "add to the sample an image of each block, tag, problem batch or high view angle "
    "the record of JRC-12.4-SELECTION names (orthospec sample draws them)",
}


#: measures computed from the external check's own measurements (the check points, the sample):
#: a value they cannot give (no points for a block, too few to compute, a point table that does not
#: parse) is a missing checker measurement, the checker's to add - never a rejection of the products
CHECKER_MEASURES = (
    "checkpoints.",
    "checkpoint.",
    "rollup.images_sampled_share",
    "rollup.blocks_checked_share",
)
#: ...except the contractor's own figures compared with them (JRC §9.5 QCR values)
CONTRACTOR_MEASURES = ("checkpoints.reported_diff_",)


def checker_measure(measure: str) -> bool:
    """The measure is computed from the checker's measurements (:data:`CHECKER_MEASURES`)."""
    return measure.startswith(CHECKER_MEASURES) and not measure.startswith(CONTRACTOR_MEASURES)


def checker_mask(r: RuleResult, blocking: np.ndarray) -> np.ndarray:
    """The blocking items that are the checker's to fix: every one of a rule whose consequence is
    ``incomplete``; of a manual rule, those without the checker's verdict (``missing``); of a rule
    over the checker's measurements, those the measurements cannot give (``missing``)."""
    if r.rule.consequence == V.INCOMPLETE:
        return blocking
    mine = np.zeros(len(blocking), dtype=bool)
    if r.rule.manual:
        mine |= blocking & (r.verdict == MISSING)
    if checker_measure(r.rule.measure):
        # an error (a crash, a broken outline) is not the checker's omission, nor is a finding for the
        # whole scope (item `*`: no items to measure at all): they keep their consequence
        mine |= blocking & (r.verdict == MISSING) & (r.items.astype(str) != "*")
    return mine


def _plural(n: int, noun: tuple[str, str, str]) -> str:
    return f"{n} {noun[0] if n == 1 else noun[1]}"


def _number(v: Any) -> float | None:
    if isinstance(v, bool) or v is None:
        return None
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _threshold(r: RuleResult, i: int) -> float | None:
    """The item's threshold of a one-sided comparison (per item when it varies)."""
    arrays = r.threshold.get("_arrays")
    if arrays:
        return _number(arrays[0][i])
    return _number(r.threshold.get("value"))


def _shortfall(op: str, measured: float, need: float) -> int | None:
    """How many more units make ``measured op need`` true (>= / > only)."""
    if op == ">=":
        return max(1, math.ceil(need - measured - 1e-9))
    if op == ">":
        return max(1, math.floor(need - measured + 1e-9) + 1)
    return None


def _what(r: RuleResult, i: int, totals: dict[str, int]) -> str:
    """What the checker must do for item ``i`` of ``r``."""
    rule = r.rule
    v = int(r.verdict[i])
    note = str(r.notes[i]) if r.notes[i] else ""
    if rule.manual and v == MISSING:
        return f"sign the manual check {rule.id} in the checker's file (manual_checks)"
    if v in (MISSING, ERROR):
        return f"not measured: {note[:160] or 'no evidence'}"
    measured = _number(r.measured[i])
    need = _threshold(r, i)
    op = rule.requirement.op
    unit = "" if r.unit in ("1", "", None) else f" {r.unit}"
    said = (
        f"{fmt_number(measured)}{unit}, required {r.threshold.get('text', '')}".rstrip(", ")
        if measured is not None
        else (note[:160] or "failed")
    )
    if (
        measured is not None
        and need is not None
        and rule.measure in SHARES
        and totals.get(rule.measure)
    ):
        one, many, purpose = SHARES[rule.measure]
        n = totals[rule.measure]
        have = round(measured / 100.0 * n)
        more = max(1, math.ceil(need / 100.0 * n - 1e-9) - have)
        return f"{more} more {one if more == 1 else many} {purpose} ({said})"
    if measured is not None and need is not None and op in (">=", ">"):
        short = _shortfall(op, measured, need)
        noun = NOUNS.get(rule.measure)
        if short is not None and noun is not None:
            return f"{short} more {noun[0] if short == 1 else noun[1]} ({said})"
    if (
        measured is not None
        and rule.measure in NOUNS
        and op in ("==", "<=", "<")
        and measured == int(measured)
    ):
        noun = NOUNS[rule.measure]
        listed = f": {note[:200]}" if note else ""
        return f"{_plural(int(measured), noun)} {noun[2]} ({said}){listed}"
    remedy = REMEDY.get(rule.measure, "re-measure it or replace it")
    return f"{said}: {remedy}"


#: one thing the checker must do: (what it concerns, what to do, the rule and clause that ask it)
Entry = tuple[str, str, str]


def todo(r: RuleResult, mask: np.ndarray, totals: dict[str, int]) -> list[Entry]:
    """What the checker must complete for the items of ``r`` (at most :data:`MAX_LINES` items)."""
    idx = np.flatnonzero(mask)
    ref = f"{r.rule.id}, {r.rule.clause.text()}"
    if r.rule.manual and bool((r.verdict[idx] == MISSING).all()):
        items = [str(r.items[i]) for i in idx]
        shown = ", ".join(items[:8]) + (f" (+{len(items) - 8} more)" if len(items) > 8 else "")
        return [
            (
                r.rule.id,
                f"sign the manual check for {shown} in the checker's file (manual_checks)",
                r.rule.clause.text(),
            )
        ]
    out = [(str(r.items[i]), _what(r, int(i), totals), ref) for i in idx[:MAX_LINES]]
    if len(idx) > MAX_LINES:
        out.append(
            (
                r.rule.id,
                f"+{len(idx) - MAX_LINES} more item(s) the checker must complete",
                r.rule.clause.text(),
            )
        )
    return out


def lines(entries: list[Entry]) -> list[str]:
    """The entries as lines, one per (item, what): several rules asking the same of one item (a
    block without check points) are one line naming them all, in first-seen order."""
    merged: dict[tuple[str, str], list[str]] = {}
    for item, what, ref in entries:
        refs = merged.setdefault((item, what), [])
        if ref not in refs:
            refs.append(ref)
    return [f"{item}: {what} ({'; '.join(refs)})" for (item, what), refs in merged.items()]
