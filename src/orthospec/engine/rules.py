"""One rule over every item of its scope: applicability, measured values, the comparison.

One vectorised comparison per rule (numpy over the scope's items), never a Python loop per item
for the decision itself. Failures are results: a rule that crashes yields ``error`` records (with
its traceback under ``--debug``) and the other rules still run. Nothing that was not measured
passes (engine/compare.py); a `when` over a fact the delivery does not give is ``missing``
(engine/applicability.py); manual rules are judged in engine/manual.py.
"""

from __future__ import annotations

import traceback
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from .. import verdicts as V
from ..errors import ExpressionError, OrthospecError, UnitError
from ..profile.models import Rule
from ..provenance import Evidence
from ..verdicts import Reason
from .applicability import applicable, scalar_condition
from .builtin import BUILTIN_RULES, ITT_DECLARED, parameter_findings
from .compare import Comparison, Undecidable, req_dict
from .context import ERROR, FAIL, MISSING, NA, PASS, WARN, Context, RuleResult
from .manual import manual_rule
from .names import Names, missing_mask
from .registry import Measured, RowEvidence, _LazyEvidence


def _constant(n: int, value: object) -> np.ndarray:
    """An object column holding ``value`` n times: one object, n references. (``np.full`` of a
    text goes through a unicode array and stores a fresh copy per item: at jrc-v3 about 38 copies
    of a not-applicable note per image, 24 KB of memory an image.)"""
    out = np.empty(n, dtype=object)
    out.fill(value)
    return out


def all_items(
    ctx: Context,
    rule: Rule,
    verdict: int,
    note: str,
    reason: Reason,
    items: list[str] | None = None,
    evidence: tuple[Evidence, ...] = (),
    tb: str | None = None,
) -> RuleResult:
    """One verdict (for one reason) for every item of the rule (``*`` when the items are unknown)."""
    its = items if items else ["*"]
    n = len(its)
    return RuleResult(
        rule,
        np.array(its, dtype=object),
        np.full(n, verdict, dtype=np.int8),
        np.full(n, None, dtype=object),
        "",
        req_dict(rule.requirement, None),
        [evidence] * n,
        _constant(n, note),
        error=note if verdict == ERROR else None,
        traceback=tb,
        reasons=_constant(n, reason),
    )


def _items_or_none(ctx: Context, rule: Rule) -> list[str] | None:
    """The rule's items when they are known, so a broken rule still judges each one (not `*`)."""
    try:
        items, _ = ctx.universe(rule.scope)
    except OrthospecError:  # the table naming the items is itself unreadable: judge `*`
        return None
    return items or None


def safe(ctx: Context, rule: Rule, rollup: dict[str, Measured] | None = None) -> RuleResult:
    """Evaluate ``rule``; a failure is a result (``missing``/``error``), never a stopped run."""
    try:
        return evaluate(ctx, rule, rollup)
    except Undecidable as exc:
        return all_items(
            ctx, rule, MISSING, str(exc), Reason.UNSET_PARAMETER, items=_items_or_none(ctx, rule)
        )
    except (UnitError, ExpressionError) as exc:
        return all_items(
            ctx, rule, ERROR, str(exc), Reason.REQUIREMENT_ERROR, items=_items_or_none(ctx, rule)
        )
    except OrthospecError as exc:
        return all_items(
            ctx, rule, ERROR, str(exc), Reason.PROVIDER_ERROR, items=_items_or_none(ctx, rule)
        )
    except Exception as exc:  # documented broad catch, never swallowing: a crashing
        # rule (a bug, or input no check anticipated) is `error` - which rejects - never `fail` or
        # `pass`, its message is in every record, and under --debug its traceback is kept too
        tb = "".join(traceback.format_exception(exc)) if ctx.debug else None
        note = f"internal error in rule: {type(exc).__name__}: {exc}" + (
            "" if tb else " (run with --debug to keep the traceback)"
        )
        return all_items(
            ctx, rule, ERROR, note, Reason.INTERNAL_ERROR, items=_items_or_none(ctx, rule), tb=tb
        )


def builtin(ctx: Context) -> list[RuleResult]:
    """The engine's own rules every profile gets (engine/builtin.py: parameter authority)."""
    out = []
    rows_by_rule = parameter_findings(ctx.params, ctx.d)
    ev = (ctx.d.manifest_evidence("tender.parameters"),)
    for rule in BUILTIN_RULES:
        rows = rows_by_rule[rule.id]
        text = (
            "declared value = value in force"
            if rule.id == ITT_DECLARED.id
            else "set by a tender profile, --param or the standard"
        )
        out.append(
            RuleResult(
                rule,
                np.array([r[0] for r in rows], dtype=object),
                np.array([V.CODE[r[3]] for r in rows], dtype=np.int8),
                np.array([r[1] or None for r in rows], dtype=object),
                "text",
                {"op": rule.requirement.op, "unit": None, "text": text},
                [ev] * len(rows),
                np.array([r[2] for r in rows], dtype=object),
            )
        )
    return out


def evaluate(ctx: Context, rule: Rule, rollup: dict[str, Measured] | None = None) -> RuleResult:
    cond, unknown_why = scalar_condition(ctx, rule)
    when_ev = (ctx.d.manifest_evidence("(when)"),)
    if cond is False:
        items0, _ = ctx.universe(rule.scope)
        return all_items(
            ctx,
            rule,
            NA,
            f"not applicable: {rule.when} is false for this delivery",
            Reason.CONDITION_FALSE,
            items=items0 or None,
            evidence=when_ev,
        )
    items, why = ctx.universe(rule.scope)
    if unknown_why is not None:
        return all_items(
            ctx,
            rule,
            MISSING,
            unknown_why,
            Reason.UNKNOWN_FACT,
            items=items or None,
            evidence=when_ev,
        )
    if rule.manual:
        return manual_rule(ctx, rule, items if items is not None else [ctx.d.id])
    m = (
        rollup[rule.measure]
        if rule.measure.startswith("rollup.") and rollup
        else ctx.cache.get(rule.measure)
    )
    if items is None:
        items = sorted(map(str, m.values.index))
        if not items and m.notes is not None and len(m.notes):
            why = str(m.notes.iloc[0])
    if not items:
        return all_items(
            ctx,
            rule,
            MISSING,
            f"no items to check at scope {rule.scope}: {why or 'none delivered'}",
            Reason.NO_ITEMS,
            evidence=(ctx.d.manifest_evidence("tables"),),
        )
    return _judge(ctx, rule, m, items)


class _Column:
    """The measure's column for the rule's items, with the provider's notes, errors and n/a."""

    def __init__(
        self, rule: Rule, m: Measured, items: list[str], applies: np.ndarray, notes: np.ndarray
    ) -> None:
        n = len(items)
        # items the measure has no value for: one hashed lookup of the items (isin is per-object
        # Python for string ids at 1M points); a duplicate label is refused, as reindex refuses it
        # (on a transient object index: pandas would keep the lookup's hash table and a Python
        # string per id on the measure's own index for the whole run - 65 MB at a million ids)
        labels = m.values.index.to_numpy(dtype=object)
        keys = pd.Index(labels, dtype=object, copy=False)
        if not keys.is_unique:
            raise ValueError(f"measure {m.name} gives two values for one item")
        if len(labels) == n and n and bool((labels == np.asarray(items, dtype=object)).all()):
            pos = np.arange(
                n
            )  # the items in the measure's own order (a point table): no hashed lookup
        else:
            pos = keys.get_indexer(items)
        del keys, labels
        absent = pos < 0
        self.raw = (
            m.values.to_numpy()[pos] if not absent.any() else m.values.reindex(items).to_numpy()
        )  # reindex: NaN (and its dtype) where absent
        self.missing = missing_mask(self.raw) & (rule.requirement.op != "present") | absent
        self.evidence = _evidence_at(m, items, pos)
        self.notes = notes
        self.applies = applies
        #: items the provider says the rule does not apply to
        self.provider_na = np.zeros(n, dtype=bool)
        if m.notes is not None:
            nn = m.notes.reindex(items)
            self.notes = np.where(nn.notna().to_numpy(), nn.to_numpy(dtype=object), self.notes)
            if "*" in m.notes.index and not len(m.values):
                self.notes[:] = m.notes["*"]
        self.errs = np.zeros(n, dtype=bool)
        if m.errors is not None and len(m.errors):
            ee = m.errors.reindex(items)
            self.errs = ee.notna().to_numpy() & ee.astype(object).map(bool).to_numpy()
            self.notes = np.where(self.errs, ee.to_numpy(dtype=object), self.notes)
        if m.na is not None and len(m.na):
            nav = m.na.reindex(items)
            na_mask = nav.notna().to_numpy()
            self.applies = self.applies & ~na_mask
            self.provider_na = na_mask & applies
            self.notes = np.where(na_mask, nav.to_numpy(dtype=object), self.notes)


def _evidence_at(m: Measured, items: list[str], pos: np.ndarray) -> Sequence[tuple[Evidence, ...]]:
    """The items' evidence; row evidence over the values' own index reuses their positions (no
    second hashed lookup of a million ids)."""
    ev = m.evidence
    if isinstance(ev, RowEvidence) and ev.rows.index.equals(m.values.index):
        rows = ev.rows.to_numpy(dtype=float)
        picked = (
            np.where(pos >= 0, rows[np.maximum(pos, 0)], np.nan)
            if len(rows)
            else np.full(len(pos), np.nan)
        )
        return _LazyEvidence(ev.file, ev.sha256, picked)  # what RowEvidence.take(items) builds
    return m.evidence_for(items)


def _sampled(
    ctx: Context, rule: Rule, items: list[str], applies: np.ndarray, notes: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None]:
    """With `check --sample`: items outside the external QC sample are not checked (noted)."""
    sampled = ctx.sample_mask(rule.scope, items)
    if sampled is None:
        return applies, None
    for i in np.flatnonzero(applies & ~sampled):
        notes[i] = f"not in the external QC sample ({rule.scope})"
    return applies & sampled, sampled


def _judge(ctx: Context, rule: Rule, m: Measured, items: list[str]) -> RuleResult:
    """Compare the measure with the requirement per item and apply the missing/error/n-a policy."""
    n = len(items)
    applies, unknown, unknown_note = applicable(ctx, rule, items)
    applies_before_sample = applies
    applies, sampled = _sampled(ctx, rule, items, applies, notes := np.full(n, None, dtype=object))
    col = _Column(rule, m, items, applies, notes)
    notes = col.notes
    names = Names(ctx.params, ctx.manifest, ctx.cache, rule.scope, items)
    try:
        ok, measured, thr, unit, undecided = Comparison(
            ctx, rule, col.raw, m.unit, col.missing | col.errs, names, items
        ).run()
    except Undecidable as exc:
        # an unset parameter the threshold needs: `missing` only where the rule applies (a `when`
        # such as `tolerance_ce90 != null` makes the rule not applicable instead)
        ok, measured, thr, unit = (
            np.ones(n, dtype=bool),
            col.raw,
            req_dict(rule.requirement, None),
            m.unit,
        )
        undecided = [(MISSING, np.ones(n, dtype=bool), str(exc), Reason.UNSET_PARAMETER)]
    verdict = np.full(n, PASS, dtype=np.int8)
    reasons = np.full(n, None, dtype=object)
    verdict[~ok] = FAIL if rule.level == "mandatory" else WARN
    reasons[~ok] = Reason.NOT_MET
    verdict[col.missing] = MISSING
    reasons[col.missing] = Reason.NO_VALUE
    for code, mask, why, reason in undecided:
        mask = (
            mask & ~col.missing & ~col.errs & col.applies
        )  # a not-applicable item keeps its `when` reason
        verdict[mask] = code
        notes[mask] = why
        reasons[mask] = reason
    _note_missing(rule, col, notes)
    verdict[col.errs] = ERROR
    reasons[col.errs] = Reason.PROVIDER_ERROR
    verdict[~col.applies] = NA
    reasons[~col.applies] = Reason.CONDITION_FALSE
    reasons[col.provider_na] = Reason.PROVIDER_NOT_APPLICABLE
    if sampled is not None:
        reasons[applies_before_sample & ~sampled & ~col.provider_na] = Reason.OUTSIDE_SAMPLE
    if unknown.any():
        in_sample = unknown if sampled is None else unknown & sampled
        verdict[in_sample] = MISSING
        notes[in_sample] = unknown_note
        reasons[in_sample] = Reason.UNKNOWN_FACT
    return RuleResult(
        rule,
        np.array(items, dtype=object),
        verdict,
        measured,
        unit,
        thr,
        col.evidence,
        notes,
        reasons=reasons,
    )


def _note_missing(rule: Rule, col: _Column, notes: np.ndarray) -> None:
    """A missing value without a provider note says which file and row lacks it."""
    for i in np.flatnonzero(col.missing):
        if notes[i] is None:
            ev: Any = col.evidence[int(i)]
            notes[i] = f"no value for {rule.measure}" + (
                f" in {ev[0].file} row {ev[0].rows[0]}" if ev and ev[0].rows else ""
            )
