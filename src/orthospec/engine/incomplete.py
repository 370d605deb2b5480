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
from typing import Any

import numpy as np

from .. import verdicts as V
from .context import ERROR, MISSING, RuleResult

#: lines listed per rule; the rest are counted ("+N more")
MAX_LINES = 20

#: what one unit of a count measure is, for "6 more check points" (singular, plural)
NOUNS: dict[str, tuple[str, str]] = {
    "checkpoints.n": ("check point", "check points"),
    "checkpoints.count": ("check point", "check points"),
    "scenes.checkpoint_count": ("check point", "check points"),
    "checkpoints.duplicate_locations": ("duplicated check point", "duplicated check points"),
    "checkpoints.blunders_unjustified": ("blunder kept without a decision", "blunders kept without a decision"),
    "checkpoints.near_gcp": ("check point at a GCP", "check points at a GCP"),
    "checkpoints.zero_residuals": ("check point with a zero residual", "check points with a zero residual"),
    "checkpoints.block_cells_bad": ("check point with an unclear block", "check points with an unclear block"),
    "checkpoints.outside_block": ("check point outside its block", "check points outside their block"),
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
}


def checker_mask(r: RuleResult, blocking: np.ndarray) -> np.ndarray:
    """The blocking items that are the checker's to fix: every one of a rule whose consequence is
    ``incomplete``; of a manual rule, those without the checker's verdict (``missing``)."""
    if r.rule.consequence == V.INCOMPLETE:
        return blocking
    if r.rule.manual:
        return blocking & (r.verdict == MISSING)
    return np.zeros(len(blocking), dtype=bool)


def _plural(n: int, noun: tuple[str, str]) -> str:
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


def _fmt(v: float) -> str:
    return str(int(v)) if v == int(v) and abs(v) < 1e15 else f"{v:.3g}"


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
        return f"{rule.measure} not measured ({note[:160] or 'no evidence'}): measure it"
    measured = _number(r.measured[i])
    need = _threshold(r, i)
    op = rule.requirement.op
    unit = "" if r.unit in ("1", "", None) else f" {r.unit}"
    said = (f"{_fmt(measured)}{unit}, required {r.threshold.get('text', '')}".rstrip(", ")
            if measured is not None else (note[:160] or "failed"))
    if measured is not None and need is not None and rule.measure in SHARES and totals.get(rule.measure):
        one, many, purpose = SHARES[rule.measure]
        n = totals[rule.measure]
        have = round(measured / 100.0 * n)
        more = max(1, math.ceil(need / 100.0 * n - 1e-9) - have)
        return f"{more} more {one if more == 1 else many} {purpose} ({said})"
    if measured is not None and need is not None and op in (">=", ">"):
        more = _shortfall(op, measured, need)
        noun = NOUNS.get(rule.measure)
        if more is not None and noun is not None:
            return f"{more} more {noun[0] if more == 1 else noun[1]} ({said})"
    if measured is not None and rule.measure in NOUNS and op in ("==", "<=", "<") and measured == int(measured):
        return f"{_plural(int(measured), NOUNS[rule.measure])} to drop or replace ({said})"
    remedy = REMEDY.get(rule.measure, "re-measure it or replace it")
    return f"{said}: {remedy}"


def todo(r: RuleResult, mask: np.ndarray, totals: dict[str, int]) -> list[str]:
    """One line per item of ``r`` the checker must complete (at most :data:`MAX_LINES`)."""
    idx = np.flatnonzero(mask)
    clause = r.rule.clause.text()
    if r.rule.manual and bool((r.verdict[idx] == MISSING).all()):
        items = [str(r.items[i]) for i in idx]
        shown = ", ".join(items[:8]) + (f" (+{len(items) - 8} more)" if len(items) > 8 else "")
        return [f"{r.rule.id} ({clause}): sign the manual check for {shown} in the checker's file (manual_checks)"]
    lines = [f"{r.items[i]}: {_what(r, int(i), totals)} ({r.rule.id}, {clause})" for i in idx[:MAX_LINES]]
    if len(idx) > MAX_LINES:
        lines.append(f"{r.rule.id} ({clause}): +{len(idx) - MAX_LINES} more item(s) the checker must complete")
    return lines
