"""Normal / Tightened audit state per project and QCR family (JRC §2.3, §12.7, Tables 6 and 10).

JRC §2.3: Tightened audits "follow an audit trail for suspect products or regions and will be
introduced if ... results from QC do not meet the specifications"; §12.7 asks for follow-up
when a result is "marginal (just below or above the tolerance)". orthospec reads that as a
state machine over the ledger's runs, per project and family (the rule's ``audit.family``, else
its clause section):

* a run whose records of the family include a failure (fail, missing, error), a warning, or a
  pass within ``margin`` of its threshold switches the family to **tightened**;
* a later run whose records of the family all pass clearly switches it back to **normal**;
* runs without applicable records of the family leave the state as it was.

The state is derived from the chained QCRs, never stored apart from them, so it cannot drift
from the evidence. This module is pure: it works on plain record dicts.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from .. import verdicts as V
from ..present import cite
from ..profile.operators import OPERATORS

NORMAL, TIGHTENED = "normal", "tightened"
#: default relative distance to a threshold under which a pass counts as marginal
MARGIN = 0.05
FAILING = V.FAILING
#: verdicts that say nothing about the family's performance
NEUTRAL = V.NEUTRAL


@dataclass(frozen=True)
class FamilyState:
    """Where a family stands after the runs so far, and why."""

    family: str
    state: str
    since_run: int | None
    last_run: int | None
    reason: str
    suspect_items: tuple[str, ...] = field(default=())
    #: the last run's findings of the family by reason code (orthospec.verdicts.Reason; a pass
    #: near its threshold is ``marginal``), most records first: (code, records, rules)
    by_reason: tuple[tuple[str, int, tuple[str, ...]], ...] = field(default=())


def family_of(record: Mapping[str, Any]) -> str:
    """The audit family of a QCR record: ``audit.family``, else its clause section, else its rule."""
    audit = record.get("audit") or {}
    if audit.get("family"):
        return str(audit["family"])
    return cite(record.get("clause"), "section") or str(record["rule"])


def _num(x: Any) -> float | None:
    if isinstance(x, bool) or not isinstance(x, int | float):
        return None
    f = float(x)
    return f if math.isfinite(f) else None


def is_marginal(measured: Any, requirement: Mapping[str, Any], *, margin: float = MARGIN) -> bool:
    """True when a numeric measure lies within ``margin`` (relative) of a threshold it is held to."""
    v = _num(measured)
    if v is None:
        return False
    op = OPERATORS.get(str(requirement.get("op")))
    bounds = [_num(requirement.get(k)) for k in (op.bounds if op is not None else ())]
    for t in bounds:
        if t is None:
            continue
        scale = abs(t) if t != 0 else 1.0
        if abs(v - t) <= margin * scale:
            return True
    return False


def outcome(
    verdict: str, measured: Any, requirement: Mapping[str, Any], *, margin: float = MARGIN
) -> str | None:
    """``fail``, ``marginal``, ``pass`` or None (the record says nothing) for one record."""
    if verdict in NEUTRAL:
        return None
    if verdict in FAILING:
        return V.FAIL
    if verdict == V.WARN:
        return "marginal"
    if verdict == V.PASS:
        return "marginal" if is_marginal(measured, requirement, margin=margin) else V.PASS
    return None


@dataclass(frozen=True)
class RunRecords:
    """One run's QCR rows as the state machine needs them."""

    run_id: int
    records: Sequence[Mapping[str, Any]]  # keys: rule, item, verdict, family, measured, requirement
    manual: Mapping[str, str] = field(default_factory=dict)  # sign-off verdicts by rule
    #: the run's reason codes by (rule, item), read only for a run with findings (a record's own
    #: ``reason`` key wins; without either, the verdict's default reason)
    reasons: Callable[[], Mapping[tuple[str, str], str]] | None = None


#: the group of a pass within the margin of its threshold (it tightens, yet carries no reason code)
MARGINAL = "marginal"


def _by_reason(
    bad: Sequence[tuple[str, str, str, str]],
) -> tuple[tuple[str, int, tuple[str, ...]], ...]:
    groups: dict[str, list[str]] = {}
    for _, rule, _, why in bad:
        groups.setdefault(why, []).append(rule)
    return tuple(
        (why, len(rules), tuple(sorted(set(rules))))
        for why, rules in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0]))
    )


_LEVEL = re.compile(r"(normal|tightened)\s*\(\s*(\d+(?:\.\d+)?)\s*%\s*\)", re.IGNORECASE)


def inspection_fractions(text: str | None) -> dict[str, float]:
    """Sample shares a profile's ``audit.inspection`` text states, e.g. Table 6 row 12
    "Normal (10%) Tightened (100%)" -> {"normal": 0.1, "tightened": 1.0}; levels given as
    "(once)", "(first few)" or "(trail)" state no share and are left out."""
    return {m.group(1).lower(): float(m.group(2)) / 100.0 for m in _LEVEL.finditer(text or "")}


def _decode(x: Any) -> Any:
    return json.loads(x) if isinstance(x, str) else x


def audit_states(runs: Iterable[RunRecords], *, margin: float = MARGIN) -> dict[str, FamilyState]:
    """Replay runs (oldest first) and return the state of every family seen."""
    states: dict[str, FamilyState] = {}
    for run in runs:
        per_family: dict[str, list[tuple[str, str, str, str]]] = {}
        stored: Mapping[tuple[str, str], str] | None = None
        for rec in run.records:
            verdict = run.manual.get(rec["rule"], rec["verdict"])
            req = _decode(rec["requirement"]) or {}
            measured = _decode(rec["measured"])
            out = outcome(verdict, measured, req, margin=margin)
            if out is None:
                continue
            why = ""
            if out != V.PASS:
                given = rec.get("reason")
                if given is None and run.reasons is not None:
                    if stored is None:
                        stored = run.reasons()
                    given = stored.get((rec["rule"], rec["item"]))
                why = (V.reason_of(verdict, given) or MARGINAL) if verdict != V.PASS else MARGINAL
            per_family.setdefault(rec["family"], []).append((out, rec["rule"], rec["item"], why))
        for fam, outs in sorted(per_family.items()):
            bad = [(o, r, i, w) for o, r, i, w in outs if o != V.PASS]
            prev = states.get(fam)
            if bad:
                n_fail = sum(o == V.FAIL for o, _, _, _ in bad)
                n_marg = len(bad) - n_fail
                rules = sorted({r for _, r, _, _ in bad})
                what = ", ".join(
                    p
                    for p in (
                        f"{n_fail} failing" if n_fail else "",
                        f"{n_marg} marginal" if n_marg else "",
                    )
                    if p
                )
                since = (
                    prev.since_run if prev is not None and prev.state == TIGHTENED else run.run_id
                )
                states[fam] = FamilyState(
                    fam,
                    TIGHTENED,
                    since,
                    run.run_id,
                    f"run {run.run_id}: {what} ({', '.join(rules)})",
                    tuple(sorted({i for _, _, i, _ in bad})),
                    _by_reason(bad),
                )
            else:
                reason = f"run {run.run_id}: all {len(outs)} passed clearly" + (
                    " (back from tightened)" if prev is not None and prev.state == TIGHTENED else ""
                )
                since = prev.since_run if prev is not None and prev.state == NORMAL else run.run_id
                states[fam] = FamilyState(fam, NORMAL, since, run.run_id, reason)
    return states
