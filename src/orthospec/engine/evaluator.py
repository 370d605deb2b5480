"""Apply every rule of a resolved profile to every item in its scope, then roll up.

Phase 1 judges each rule over its items (engine/rules.py: applicability, comparison through the
requirement operators of profile/operators.py; manual rules in engine/manual.py) plus the engine's
own rules (engine/builtin.py: who set each threshold). Waivers in force - the tender profile's
and the checker's file's, never the contractor's (engine/waivers.py) - turn findings into
``waived``. Phase 2 (engine/rollup.py) derives the rejected items, the JRC §12.3/§12.8 roll-up
measures through :mod:`orthospec.measures.acceptance`, runs the profile's ``rollup.*`` rules on
them and decides the delivery's verdict.

Nothing that was not measured passes: a value that does not convert (px without a GSD), a
threshold that cannot be computed or names an unset parameter is ``missing``; a non-finite
threshold is ``error``; a `when` that reads a fact the delivery does not give is ``missing``
unless the condition is decided whatever that fact is, or the `when` tests it for null. A
finding for a whole scope (item ``*``) returns the delivery; only a *mandatory* roll-up rule
replaces the default "any rejected image/block returns the delivery"; a failing mandatory rule
always changes the verdict.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..delivery.checker import Checker
from ..delivery.draft import todo_citations
from ..delivery.reader import Delivery
from ..profile.loader import ResolvedProfile
from . import manual, waivers
from .context import (  # re-exported: the QCR writer reads the codes and the result type from here
    ERROR,
    FAIL,
    MISSING,
    NA,
    PASS,
    SEVERITY,
    VERDICTS,
    WAIVED,
    WARN,
    Context,
    RuleResult,
)
from .params import ParamValue
from .registry import EngineOptions
from .rollup import Rollup
from .rules import builtin, safe

__all__ = [
    "ERROR",
    "FAIL",
    "MISSING",
    "NA",
    "PASS",
    "SEVERITY",
    "VERDICTS",
    "WAIVED",
    "WARN",
    "Evaluation",
    "Evaluator",
    "RuleResult",
]


@dataclass
class Evaluation:
    profile: ResolvedProfile
    delivery: Delivery
    parameters: dict[str, ParamValue]
    results: list[RuleResult]
    rejected: dict[str, list[str]]
    reasons: list[str]
    verdict: str
    fail_on: str
    details: dict[str, Any]
    unused_waivers: list[dict[str, Any]]
    #: the contractor's waiver requests, each with the items it matched and whether it was granted
    waiver_requests: list[dict[str, Any]] = field(default_factory=list)
    #: who checked (the checker file's party, file name and hash), None without a checker file
    checker: dict[str, Any] | None = None
    #: checker entries that judged nothing the delivery lists (unknown rule, or an item it no longer lists)
    manual_unused: list[dict[str, Any]] = field(default_factory=list)
    #: what the checker must still add or do (findings with consequence ``incomplete``, unsigned
    #: manual checks): the verdict is ``incomplete`` when these are open and nothing rejects
    incomplete: list[str] = field(default_factory=list)


class Evaluator:
    """One evaluation of a delivery against a resolved profile with the parameters in force.

    ``checker`` is the checker's file (delivery/checker.py): the manual verdicts and the waivers
    in force besides the tender profile's. ``debug`` keeps the traceback of a crashing rule in its
    records (default: ``ORTHOSPEC_DEBUG=1``, which ``orthospec --debug`` sets).
    """

    def __init__(
        self,
        profile: ResolvedProfile,
        delivery: Delivery,
        parameters: dict[str, ParamValue],
        *,
        fail_on: str = "fail",
        options: EngineOptions | Mapping[str, Any] | None = None,
        checker: Checker | None = None,
        debug: bool | None = None,
    ) -> None:
        self.ctx = Context.build(
            profile,
            delivery,
            parameters,
            fail_on=fail_on,
            options=options,
            checker=checker,
            debug=debug,
        )
        self.granted = waivers.granted(profile, checker)

    def run(self) -> Evaluation:
        ctx = self.ctx
        first = [r for r in ctx.profile.rules if not r.measure.startswith("rollup.")]
        second = [r for r in ctx.profile.rules if r.measure.startswith("rollup.")]
        results = [safe(ctx, r) for r in first] + builtin(ctx)
        used = waivers.apply_granted(results, self.granted)
        roll = Rollup(ctx)
        rejected, reasons = roll.rejected_items(results)
        measures = roll.measures(rejected, results)
        later = [safe(ctx, r, measures) for r in second]
        used |= waivers.apply_granted(later, self.granted)
        results += later
        requests = waivers.mark_requested(results, waivers.requested(ctx.d))
        verdict, more, todo = roll.overall(results, rejected, second)
        details = ctx.cache.details()
        cite_todo(ctx.d, results)
        crashed = {r.rule.id: r.traceback for r in results if r.traceback}
        if crashed:
            details["tracebacks"] = dict(sorted(crashed.items()))
        return Evaluation(
            ctx.profile,
            ctx.d,
            ctx.params,
            results,
            rejected,
            reasons + more,
            verdict,
            ctx.fail_on,
            details,
            waivers.unused(self.granted, used),
            requests,
            ctx.checker.summary() if ctx.checker is not None else None,
            manual.unused(ctx, results),
            todo,
        )


def cite_todo(d: Delivery, results: list[RuleResult]) -> None:
    """In a draft (``init --from``), every ``missing`` record names the TODO.md line whose value
    would decide it (delivery/draft.py), and so does a ``present`` rule failing on a value the
    draft left empty; the ``*`` entry of the map covers rules it does not name."""
    cites = todo_citations(d.path, d.manifest.draft)
    if not cites:
        return
    for r in results:
        mask = r.verdict == MISSING
        if r.rule.requirement.op == "present" and r.rule.id in cites:
            mask = mask | (r.verdict == FAIL) | (r.verdict == WARN)
        cite = cites.get(r.rule.id, cites.get("*"))
        if cite and mask.any():
            r.notes = r.notes.copy()
            r.notes[mask] = [f"{n}; see {cite}" if n else f"see {cite}" for n in r.notes[mask]]
