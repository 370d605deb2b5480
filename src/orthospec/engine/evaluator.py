"""Apply every rule of a resolved profile to every item in its scope.

One vectorised comparison per rule (numpy over the scope's items), never a Python loop per item
for the decision itself. Failures are results: a rule that crashes yields `error` records and the
other rules still run. Roll-up (JRC §12.3, §12.7, §12.8) runs as a second phase over the item
verdicts of the first, through the one implementation in :mod:`orthospec.measures.acceptance`.

Nothing that was not measured passes: a value that does not convert (px without a GSD), a
threshold that cannot be computed or names an unset parameter is ``missing``; a non-finite
threshold is ``error``; a `when` that reads a fact the delivery does not give is ``missing``
unless the condition is decided whatever that fact is, or the `when` tests it for null. A
finding for a whole scope (item ``*``) returns the delivery; only a *mandatory* roll-up rule
replaces the default "any rejected image/block returns the delivery"; a failing mandatory rule
always changes the verdict. The engine's own rules (engine/builtin.py) record who set each
threshold.
"""

from __future__ import annotations

import ast
import itertools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ..delivery.checker import Checker
from ..delivery.convention import table_specs
from ..delivery.reader import Delivery
from ..errors import ExpressionError, OrthospecError, UnitError
from ..measures.acceptance import (
    DeliveryVerdict,
    ProjectVerdict,
    image_delivery_verdict,
    project_verdict,
)
from ..provenance import Evidence
from ..spec import expr
from ..spec.loader import ResolvedProfile
from ..spec.models import Requirement, Rule
from ..spec.wording import requirement_text
from ..units import NON_NUMERIC, Q_, canonical, convert, parse_unit, ureg
from . import waivers
from .builtin import BUILTIN_RULES, ITT_DECLARED, parameter_findings
from .params import ParamValue
from .registry import ROLLUP, MeasureCache, Measured, ProviderContext, measure_info

PASS, FAIL, WARN, NA, MISSING, ERROR, WAIVED = range(7)
VERDICTS = ("pass", "fail", "warn", "not_applicable", "missing", "error", "waived")
#: worst first, for a rule's overall verdict
SEVERITY = (ERROR, FAIL, MISSING, WARN, WAIVED, PASS, NA)


@dataclass
class RuleResult:
    """The columnar outcome of one rule over its items."""

    rule: Rule
    items: np.ndarray
    verdict: np.ndarray
    measured: np.ndarray
    unit: str
    threshold: dict[str, Any]
    evidence: list[tuple[Evidence, ...]]
    notes: np.ndarray
    original: np.ndarray | None = None
    waivers: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: item -> the contractor's waiver request (delivery.yaml): evidence, never in force
    requested: dict[str, dict[str, Any]] = field(default_factory=dict)
    error: str | None = None

    @property
    def worst(self) -> int:
        present = set(self.verdict.tolist())
        for v in SEVERITY:
            if v in present:
                return v
        return NA

    def counts(self) -> dict[str, int]:
        bc = np.bincount(self.verdict.astype(np.int64), minlength=len(VERDICTS))
        return {VERDICTS[i]: int(bc[i]) for i in range(len(VERDICTS))}


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


# --- helpers --------------------------------------------------------------------------------

_STRING_LITERAL = re.compile(r"'([^']*)'|\"([^\"]*)\"")
_NUMBER_LITERAL = re.compile(r"(?<![\w.])(-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?)(?![\w.])")


def _null_tested(when: str) -> set[str]:
    """Names a `when` compares with null: their absence is part of the condition, not missing evidence."""
    out: set[str] = set()
    try:
        tree = ast.parse(when, mode="eval")
    except SyntaxError:
        return out
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(_is_null(x) for x in sides):
                out.update(d for x in sides if (d := _dotted_name(x)) is not None)
    return out


def _is_null(node: ast.AST) -> bool:
    return (isinstance(node, ast.Constant) and node.value is None) or (
        isinstance(node, ast.Name) and node.id in ("null", "None"))


def _dotted_name(node: ast.AST) -> str | None:
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name) and node.id not in ("null", "None", "true", "false"):
        return ".".join([node.id, *reversed(parts)])
    return None


def _unknown_note(rule: Rule, absent: list[str]) -> str:
    shown = ", ".join(a[len("manifest."):] + " (delivery.yaml)" if a.startswith("manifest.") else a
                      for a in absent)
    return (f"applicability unknown: no value for {shown}; the rule applies when {rule.when} - "
            "declare the fact (or deliver the data) so the rule can be decided")

def _is_missing(v: Any) -> bool:
    if v is None:
        return True
    if isinstance(v, float) and math.isnan(v):
        return True
    return bool(isinstance(v, str) and not v.strip())


def _missing_mask(values: np.ndarray) -> np.ndarray:
    if values.dtype.kind == "f":
        return np.isnan(values)
    if values.dtype.kind in "iub":
        return np.zeros(len(values), dtype=bool)
    return np.fromiter((_is_missing(v) for v in values), dtype=bool, count=len(values))


def universe(scope: str, d: Delivery) -> tuple[list[str] | None, str | None]:
    """The items a rule at ``scope`` must judge; None = take the measure's own items."""
    if scope == "delivery":
        return [d.id], None
    if scope == "project":
        return [d.project_id], None
    if scope == "block":
        ids = d.block_ids
        return ids, None if ids else "the delivery declares no blocks"
    if scope == "edge":
        return [e.id for e in d.manifest.edge_targets], "the manifest lists no edge_targets"
    table = {"image": "images", "checkpoint": "checkpoints", "gcp": "gcps", "flight": "flights",
             "camera": "cameras"}.get(scope)
    if table is None:
        return None, None
    t = d.table(table)
    if t is None:
        return [], f"the manifest declares no '{table}' table"
    return t.ids.tolist(), None


def item_gsd(scope: str, items: list[str], d: Delivery, cache: MeasureCache) -> np.ndarray | None:
    """GSD in metres per item, to convert px thresholds (image rows first, else the product GSD)."""
    base = d.gsd_m
    out = np.full(len(items), np.nan if base is None else base, dtype=float)
    if scope == "image" and d.table("images") is not None:
        try:
            m = cache.get("images.gsd")
            vals = pd.to_numeric(m.values.reindex(items), errors="coerce").to_numpy(dtype=float)
            vals = convert(vals, m.unit, "m")
            out = np.where(np.isnan(vals), out, vals)
        except (KeyError, OrthospecError):
            pass
    return None if np.isnan(out).all() else out


class _Names(Mapping[str, Any]):
    """Names an expression may use: parameters, manifest paths, measures of the rule's scope."""

    def __init__(self, params: dict[str, ParamValue], manifest: dict[str, Any], cache: MeasureCache,
                 scope: str, items: list[str], *, scalar: bool = False) -> None:
        self.params, self.manifest, self.cache = params, manifest, cache
        self.scope, self.items, self.scalar = scope, items, scalar
        #: name -> value substituted where that fact or measure is missing (applicability probing)
        self.fill: dict[str, Any] = {}

    def __getitem__(self, key: str) -> Any:
        if key in self.params:
            q = self.params[key].quantity()  # None when unset: `param != null` tests that
            if q is None and key in self.fill:
                return self.fill[key]
            return q
        if key.startswith("param."):
            return self[key[6:]]
        if key.startswith("manifest."):
            v = self.manifest.get(key)
            if _is_missing(v) and key in self.fill:
                return self.fill[key]
            if isinstance(v, dict) and set(v) == {"value", "unit"}:
                return Q_(float(v["value"]), parse_unit(v["unit"]))
            return v
        info = measure_info(key)
        if info is None:
            raise KeyError(key)
        m = self.cache.get(key)
        if key in self.fill:
            return self._filled(key, m, info)
        if info[0] in ("delivery", "project") and (self.scalar or self.scope != info[0]):
            # one value for the whole delivery: every item of any scope sees it
            one = m.values.iloc[0] if len(m.values) else None
            if self.scalar:
                if _is_missing(one):
                    return None
                if m.unit in NON_NUMERIC or m.unit == "any":
                    return one
                return Q_(float(one), parse_unit(m.unit))
            vals = pd.Series([one] * len(self.items), index=self.items, dtype=object)
        else:
            vals = m.values.reindex(self.items)
        if m.unit in NON_NUMERIC or m.unit == "any":
            return vals.to_numpy(dtype=object)
        arr = pd.to_numeric(vals, errors="coerce").to_numpy(dtype=float)
        return Q_(arr, parse_unit(m.unit))

    def _filled(self, key: str, m: Measured, info: tuple[str, str]) -> Any:
        """The measure with its missing entries replaced by the probe value ``fill[key]``."""
        if info[0] in ("delivery", "project") and (self.scalar or self.scope != info[0]):
            one = m.values.iloc[0] if len(m.values) else None
            vals = pd.Series([one] * max(len(self.items), 1), dtype=object)
        else:
            vals = m.values.reindex(self.items)
        raw = vals.to_numpy(dtype=object).copy()
        miss = _missing_mask(raw)
        raw[miss] = self.fill[key]
        if m.unit in NON_NUMERIC or m.unit == "any":
            return raw[0] if self.scalar else raw
        arr = pd.to_numeric(pd.Series(raw), errors="coerce").to_numpy(dtype=float)
        q = Q_(arr, parse_unit(m.unit))
        return q[0] if self.scalar else q

    def __contains__(self, key: object) -> bool:
        if not isinstance(key, str):
            return False
        return (key in self.params or key.startswith("manifest.") or key.startswith("param.")
                or measure_info(key) is not None)

    def __iter__(self):  # pragma: no cover - Mapping protocol; never enumerated
        return iter(self.params)

    def __len__(self) -> int:  # pragma: no cover
        return len(self.params)


def _magnitudes(v: Any, unit: str | None, n: int, gsd: np.ndarray | None, what: str) -> np.ndarray:
    """A threshold as float magnitudes in ``unit`` (broadcast to n items)."""
    if hasattr(v, "units"):
        mag = np.asarray(v.magnitude, dtype=float)
        src = str(v.units)
        if unit is None:
            raise UnitError(f"{what}: the expression has unit {canonical(src)!r}; give the requirement a unit")
        if v.units == ureg.dimensionless:
            # a pure number (e.g. "0.1 * 256") means "in the requirement's unit"
            return np.broadcast_to(mag, (n,)).astype(float)
        return np.broadcast_to(convert(mag, src, unit, gsd_m=gsd, what=what), (n,)).astype(float)
    if v is None:
        raise _Undecidable(f"{what}: the threshold has no value (a fact or parameter it names is not given)")
    if isinstance(v, bool):
        raise UnitError(f"{what}: expected a number, got {v!r}")
    return np.broadcast_to(np.asarray(v, dtype=float), (n,)).astype(float)


def _threshold_value(v: Any, names: _Names) -> Any:
    if isinstance(v, str):
        return expr.parse(v).evaluate(names)
    return v


class _Undecidable(OrthospecError):
    """A rule's requirement needs a value nobody gave (an unset parameter): verdict `missing`."""


# --- the evaluator ---------------------------------------------------------------------------

class Evaluator:
    def __init__(self, profile: ResolvedProfile, delivery: Delivery, parameters: dict[str, ParamValue],
                 *, fail_on: str = "fail", options: Mapping[str, Any] | None = None,
                 checker: Checker | None = None) -> None:
        self.profile, self.d, self.params = profile, delivery, parameters
        self.checker = checker
        self._granted = waivers.granted(profile, checker)
        self.fail_on = fail_on
        self.options = dict(options or {})
        ctx = ProviderContext(delivery, {k: v.quantity() for k, v in parameters.items()}, dict(options or {}),
                              classes=dict(getattr(profile, "classes", {}) or {}))
        self.cache = MeasureCache(ctx)
        self.manifest = delivery.flat_manifest()
        self._manual = self._manual_table()

    # phase 1 + 2
    def run(self) -> Evaluation:
        first = [r for r in self.profile.rules if not r.measure.startswith("rollup.")]
        second = [r for r in self.profile.rules if r.measure.startswith("rollup.")]
        results = [self._safe(r) for r in first] + self._builtin()
        used = waivers.apply_granted(results, self._granted)
        rejected, reasons = self._rollup_items(results)
        self._rollup_values = self._rollup_measures(rejected)
        later = [self._safe(r) for r in second]
        used |= waivers.apply_granted(later, self._granted)
        results += later
        waived_unused = waivers.unused(self._granted, used)
        requests = waivers.mark_requested(results, waivers.requested(self.d))
        # only a MANDATORY roll-up rule replaces the default "any rejected item returns the delivery":
        # a recommended one cannot change the verdict, so it must not switch the default off
        verdict, reasons2 = self._overall(results, rejected, has_block_rollup=any(
            r.measure in ("rollup.block_rejected_share", "rollup.blocks_rejected") and r.level == "mandatory"
            for r in second),
            has_image_rollup=any(r.measure in ("rollup.image_rejected_share", "rollup.images_rejected")
                                 and r.level == "mandatory" for r in second))
        details = self.cache.details()
        return Evaluation(self.profile, self.d, self.params, results, rejected, reasons + reasons2,
                          verdict, self.fail_on, details, waived_unused, requests,
                          self.checker.summary() if self.checker is not None else None)

    def _builtin(self) -> list[RuleResult]:
        """The engine's own rules every profile gets (engine/builtin.py: parameter authority)."""
        code = {0: PASS, 1: FAIL, 2: WARN, 3: NA}
        out = []
        rows_by_rule = parameter_findings(self.params, self.d)
        for rule in BUILTIN_RULES:
            rows = rows_by_rule[rule.id]
            n = len(rows)
            ev = (self.d.manifest_evidence("tender.parameters"),)
            out.append(RuleResult(
                rule, np.array([r[0] for r in rows], dtype=object),
                np.array([code[r[3]] for r in rows], dtype=np.int8),
                np.array([r[1] or None for r in rows], dtype=object), "text",
                {"op": rule.requirement.op, "unit": None, "text": (
                    "declared value = value in force" if rule.id == ITT_DECLARED.id
                    else "set by a tender profile, --param or the standard")},
                [ev] * n, np.array([r[2] for r in rows], dtype=object)))
        return out

    def _safe(self, rule: Rule) -> RuleResult:
        try:
            return self._evaluate(rule)
        except _Undecidable as exc:
            return self._all(rule, MISSING, str(exc), items=self._items_or_none(rule))
        except OrthospecError as exc:
            return self._all(rule, ERROR, str(exc), items=self._items_or_none(rule))
        except Exception as exc:  # a crashing rule is `error`, never `fail`, and never stops the run
            return self._all(rule, ERROR, f"internal error in rule: {type(exc).__name__}: {exc}",
                             items=self._items_or_none(rule))

    def _items_or_none(self, rule: Rule) -> list[str] | None:
        """The rule's items when they are known, so a broken rule still judges each one (not `*`)."""
        try:
            items, _ = universe(rule.scope, self.d)
        except Exception:
            return None
        return items or None

    def _all(self, rule: Rule, verdict: int, note: str, items: list[str] | None = None,
             evidence: tuple[Evidence, ...] = ()) -> RuleResult:
        its = items if items else ["*"]
        n = len(its)
        return RuleResult(rule, np.array(its, dtype=object), np.full(n, verdict, dtype=np.int8),
                          np.full(n, None, dtype=object), "", self._req_dict(rule.requirement, None),
                          [evidence] * n, np.full(n, note, dtype=object),
                          error=note if verdict == ERROR else None)

    # --- one rule: applicability
    def _global(self, name: str) -> bool:
        """A name with one value for the whole delivery (parameter, manifest fact, delivery measure)."""
        if name in self.params or name.startswith(("manifest.", "param.")):
            return True
        info = measure_info(name)
        return info is not None and info[0] in ("delivery", "project")

    def _missing_of(self, name: str, names: _Names, n: int) -> np.ndarray:
        """Per item: the fact or measure ``name`` has no value (so a `when` over it cannot be decided)."""
        key = name[6:] if name.startswith("param.") else name
        if key in self.params:
            return np.full(n, self.params[key].value is None)
        if key.startswith("manifest."):
            return np.full(n, _is_missing(self.manifest.get(key)))
        info = measure_info(key)
        try:
            m = self.cache.get(key)
        except OrthospecError:
            return np.ones(n, dtype=bool)
        if info is not None and info[0] in ("delivery", "project") and (
                names.scalar or names.scope != info[0]):
            one = m.values.iloc[0] if len(m.values) else None
            return np.full(n, _is_missing(one))
        return _missing_mask(m.values.reindex(names.items).to_numpy(dtype=object))

    def _probes(self, name: str, when: str) -> list[Any]:
        """Values that stand in for a missing ``name`` to see whether the `when` depends on it."""
        strings = [a or b for a, b in _STRING_LITERAL.findall(when)]
        numbers = [float(x) for x in _NUMBER_LITERAL.findall(when)]
        key = name[6:] if name.startswith("param.") else name
        if key in self.params:
            p = self.params[key]
            if p.unit in NON_NUMERIC:
                return [True, False] if p.unit == "bool" else [*strings, "\x00absent"]
            return [Q_(v, parse_unit(p.unit)) for v in (-1e12, 0.0, *numbers, 1e12)]
        info = measure_info(key)
        unit = info[1] if info else "any"
        if unit == "bool":
            return [True, False]
        if unit in NON_NUMERIC:
            return [*strings, "\x00absent"]
        if unit == "any":
            return [True, False, 0.0, *numbers, *strings, "\x00absent"]
        return [-1e12, 0.0, *numbers, 1e12]

    @staticmethod
    def _truth(v: Any, n: int) -> np.ndarray:
        v = getattr(v, "magnitude", v)
        if v is None:
            return np.zeros(n, dtype=bool)
        if np.ndim(v) == 0:
            return np.full(n, bool(v), dtype=bool)
        return np.array([bool(c) if not _is_missing(c) else False for c in np.asarray(v, dtype=object)],
                        dtype=bool)

    def _when(self, rule: Rule, items: list[str], *, scalar: bool = False
              ) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """(applies, unknown, absent names) per item of a rule's `when`.

        A fact the `when` reads but the delivery does not give makes the rule's applicability
        unknown - evidence missing, never a silent `not_applicable` - unless the condition is
        decided whatever that fact is (``type == 'satellite' and digital == false`` on an aerial
        delivery), or the `when` itself tests the name for null.
        """
        n = 1 if scalar else len(items)
        e = expr.parse(rule.when or "true")
        names = _Names(self.params, self.manifest, self.cache, rule.scope, items, scalar=scalar)
        base = self._truth(e.evaluate(names), n)
        nulls = _null_tested(rule.when or "")
        missing = {k: self._missing_of(k, names, n) for k in sorted(e.names) if k not in nulls}
        probe = [k for k, mk in missing.items() if mk.any()]
        none = np.zeros(n, dtype=bool)
        if not probe:
            return base, none, []
        has_missing = np.logical_or.reduce([missing[k] for k in probe])
        cands = [self._probes(k, rule.when or "") for k in probe]
        total = math.prod(len(c) for c in cands)
        first: np.ndarray | None = None
        unknown = none.copy()
        if total <= 512:
            for combo in itertools.product(*cands):
                names.fill = dict(zip(probe, combo, strict=True))
                try:
                    v = self._truth(e.evaluate(names), n)
                except (OrthospecError, TypeError, ValueError):
                    continue
                if first is None:
                    first = v
                else:
                    unknown |= v != first
        if first is None:
            return base & ~has_missing, has_missing, probe
        unknown &= has_missing
        return first & ~unknown, unknown, probe

    def _applicable(self, rule: Rule, items: list[str]) -> tuple[np.ndarray, np.ndarray, str | None]:
        """Per-item applicability from `when`: (applies, unknown, note for the unknown items)."""
        n = len(items)
        if not rule.when:
            return np.ones(n, dtype=bool), np.zeros(n, dtype=bool), None
        applies, unknown, absent = self._when(rule, items)
        return applies, unknown, _unknown_note(rule, absent) if unknown.any() else None

    def _scalar_condition(self, rule: Rule) -> tuple[bool | None, str | None]:
        """A `when` over delivery-wide facts only, decided once: (True/False, None), (None, why
        unknown), or (None, None) when it reads per-item measures."""
        if not rule.when:
            return None, None
        e = expr.parse(rule.when)
        if any(not self._global(n) for n in e.names):
            return None, None
        applies, unknown, absent = self._when(rule, [], scalar=True)
        if unknown[0]:
            return None, _unknown_note(rule, absent)
        return bool(applies[0]), None

    def _evaluate(self, rule: Rule) -> RuleResult:
        cond, unknown_why = self._scalar_condition(rule)
        if cond is False:
            items0, _ = universe(rule.scope, self.d)
            return self._all(rule, NA, f"not applicable: {rule.when} is false for this delivery",
                             items=items0 or None, evidence=(self.d.manifest_evidence("(when)"),))
        items, why = universe(rule.scope, self.d)
        if unknown_why is not None:
            return self._all(rule, MISSING, unknown_why, items=items or None,
                             evidence=(self.d.manifest_evidence("(when)"),))
        if rule.manual:
            return self._manual_rule(rule, items if items is not None else [self.d.id])
        if rule.measure.startswith("rollup."):
            m = self._rollup_values[rule.measure]
        else:
            m = self.cache.get(rule.measure)
        if items is None:
            items = sorted(map(str, m.values.index))
            if not items and m.notes is not None and len(m.notes):
                why = str(m.notes.iloc[0])
        if not items:
            return self._all(rule, MISSING, f"no items to check at scope {rule.scope}: {why or 'none delivered'}",
                             evidence=(self.d.manifest_evidence("tables"),))
        n = len(items)
        verdict = np.full(n, PASS, dtype=np.int8)
        notes = np.full(n, None, dtype=object)
        names = _Names(self.params, self.manifest, self.cache, rule.scope, items)
        applicable, unknown, unknown_note = self._applicable(rule, items)
        sampled = self._sample_mask(rule.scope, items)
        if sampled is not None:
            for i in np.flatnonzero(applicable & ~sampled):
                notes[i] = f"not in the external QC sample ({rule.scope})"
            applicable &= sampled
        values = m.values.reindex(items)
        evidence_list = m.evidence_for(items)
        raw = values.to_numpy()
        missing = _missing_mask(raw) & (rule.requirement.op != "present") | (
            ~values.index.isin(m.values.index))
        if m.notes is not None:
            nn = m.notes.reindex(items)
            notes = np.where(nn.notna().to_numpy(), nn.to_numpy(dtype=object), notes)
            if "*" in m.notes.index and not len(m.values):
                notes[:] = m.notes["*"]
        errs = np.zeros(n, dtype=bool)
        if m.errors is not None and len(m.errors):
            ee = m.errors.reindex(items)
            errs = ee.notna().to_numpy() & ee.astype(object).map(bool).to_numpy()
            notes = np.where(errs, ee.to_numpy(dtype=object), notes)
        if m.na is not None and len(m.na):
            nav = m.na.reindex(items)
            na_mask = nav.notna().to_numpy()
            applicable &= ~na_mask
            notes = np.where(na_mask, nav.to_numpy(dtype=object), notes)
        req = rule.requirement
        try:
            ok, measured, thr, unit, undecided = self._compare(rule, req, raw, m.unit, missing | errs, names,
                                                               items)
        except _Undecidable as exc:
            # an unset parameter the threshold needs: `missing` only where the rule applies (a `when`
            # such as `tolerance_ce90 != null` makes the rule not applicable instead)
            ok, measured, thr, unit = np.ones(n, dtype=bool), raw, self._req_dict(req, None), m.unit
            undecided = [(MISSING, np.ones(n, dtype=bool), str(exc))]
        verdict[~ok] = FAIL if rule.level == "mandatory" else WARN
        verdict[missing] = MISSING
        for code, mask, why in undecided:
            mask = mask & ~missing & ~errs
            verdict[mask] = code
            notes[mask] = why
        for i in np.flatnonzero(missing):
            if notes[i] is None:
                notes[i] = f"no value for {rule.measure}" + (
                    f" in {evidence_list[i][0].file} row {evidence_list[i][0].rows[0]}"
                    if evidence_list[i] and evidence_list[i][0].rows else "")
        verdict[errs] = ERROR
        verdict[~applicable] = NA
        if unknown.any():
            in_sample = unknown if sampled is None else unknown & sampled
            verdict[in_sample] = MISSING
            notes[in_sample] = unknown_note
        return RuleResult(rule, np.array(items, dtype=object), verdict, measured, unit, thr,
                          evidence_list, notes)

    def _compare(self, rule: Rule, req: Requirement, raw: np.ndarray, munit: str, skip: np.ndarray,
                 names: _Names, items: list[str]
                 ) -> tuple[np.ndarray, np.ndarray, dict[str, Any], str, list[tuple[int, np.ndarray, str]]]:
        """Vectorised comparison: (ok, measured, threshold, unit, undecided).

        ``undecided`` lists (verdict, mask, note) for items the comparison could not decide: a
        value that does not convert (px without a GSD) or a threshold that cannot be computed is
        `missing`; a non-finite threshold is `error`. Neither is ever `pass`.
        """
        n = len(raw)
        op = req.op
        ok = np.ones(n, dtype=bool)
        thr = self._req_dict(req, None)
        undecided: list[tuple[int, np.ndarray, str]] = []
        if op == "present":
            ok = ~_missing_mask(raw)
            return ok, raw, thr, munit, undecided
        if op in ("true", "false"):
            want = op == "true"
            vals = np.array([v is want or (isinstance(v, np.bool_) and bool(v) is want) for v in raw])
            ok = vals | skip
            return ok, raw, thr, munit, undecided
        numeric_ops = ("<", "<=", ">", ">=", "between")
        textual = munit in NON_NUMERIC or munit == "any"
        literal_text = op in ("==", "!=", "in") and (
            textual or any(isinstance(v, str) and not self._is_expr(v) for v in (req.value, *(req.values or []))))
        if literal_text:
            vals = np.array([None if _is_missing(v) else str(v) for v in raw], dtype=object)
            if op == "in":
                allowed = {str(v) for v in req.values or []}
                ok = np.array([v in allowed for v in vals]) | skip
            else:
                target = (str(_threshold_value(req.value, names)) if isinstance(req.value, str)
                          and self._is_expr(req.value) else str(req.value))
                eq = np.array([v == target for v in vals])
                ok = (eq if op == "==" else ~eq) | skip
            return ok, vals, thr, munit, undecided
        if textual:
            raise UnitError(f"measure {rule.measure} is {munit}, the requirement {op} needs a number")
        values = raw.astype(float) if raw.dtype.kind in "fiu" else \
            pd.to_numeric(pd.Series(raw), errors="coerce").to_numpy(dtype=float)
        target_unit = canonical(req.unit) if req.unit else munit
        gsd = item_gsd(rule.scope, items, self.d, self.cache) if (
            "px" in (canonical(munit), target_unit)) else None
        before = np.isnan(values)
        if canonical(munit) != target_unit:
            values = convert(values, munit, target_unit, gsd_m=gsd, what=f"measure {rule.measure}")
        lost = np.isnan(values) & ~before & ~skip
        if lost.any():
            undecided.append((MISSING, lost, f"{rule.measure} in {canonical(munit)} cannot be converted to "
                              f"{target_unit}: no GSD for this item (give images.gsd or product.gsd)"))
        what = f"rule {rule.id} requirement"
        self._need_params(rule, req)
        if op in numeric_ops or op in ("==", "!="):
            with np.errstate(invalid="ignore"):
                if op == "between":
                    lo = _magnitudes(_threshold_value(req.min, names), req.unit, n, gsd, what) \
                        if req.min is not None else np.full(n, -np.inf)
                    hi = _magnitudes(_threshold_value(req.max, names), req.unit, n, gsd, what) \
                        if req.max is not None else np.full(n, np.inf)
                    a = values >= lo if req.min_inclusive else values > lo
                    b = values <= hi if req.max_inclusive else values < hi
                    ok = a & b
                    thr = self._req_dict(req, (lo, hi))
                    # an open side is written as no bound (-inf/+inf): only a given bound must be finite
                    bounds = [x for x, given in ((lo, req.min is not None), (hi, req.max is not None)) if given]
                else:
                    t = _magnitudes(_threshold_value(req.value, names), req.unit, n, gsd, what)
                    cmp = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal,
                           "==": np.isclose, "!=": lambda a, b: ~np.isclose(a, b)}[op]
                    ok = cmp(values, t)
                    thr = self._req_dict(req, (t,))
                    bounds = [t]
            for b_ in bounds:
                nan_t = np.isnan(b_) & ~skip
                if nan_t.any():
                    undecided.append((MISSING, nan_t, f"the threshold of {rule.id} cannot be computed for "
                                      "this item (a px threshold without a GSD, or a measure it uses is missing)"))
                inf_t = np.isinf(b_) & ~skip
                if inf_t.any():
                    undecided.append((ERROR, inf_t, f"the threshold of {rule.id} is not a finite number "
                                      f"({thr.get('text', '')}): a requirement must be a finite value"))
        elif op == "in":
            allowed = np.array([float(_threshold_value(v, names)) for v in req.values or []])
            ok = np.isin(values, allowed)
        nan_v = np.isnan(values) & ~skip & ~lost
        if nan_v.any():
            undecided.append((MISSING, nan_v, f"no numeric value for {rule.measure}"))
        ok = ok | skip | np.isnan(values)
        return ok, values, thr, target_unit, undecided

    def _need_params(self, rule: Rule, req: Requirement) -> None:
        """A threshold naming an unset parameter cannot be decided: raise so the rule is `missing`."""
        for spec in (req.value, req.min, req.max, *(req.values or [])):
            if not isinstance(spec, str) or not self._is_expr(spec):
                continue
            unset = sorted(n for n in expr.parse(spec).names
                           if (n[6:] if n.startswith("param.") else n) in self.params
                           and self.params[n[6:] if n.startswith("param.") else n].value is None)
            if unset and not _null_tested(spec):
                raise _Undecidable(f"parameter {', '.join(unset)} is not set, so {rule.id} cannot be decided: "
                                   "set it in a tender profile or with --param NAME=VALUE")

    def _is_expr(self, v: str) -> bool:
        """A string value is an expression only if it parses and names a parameter or manifest fact."""
        try:
            e = expr.parse(v)
        except ExpressionError:
            return False
        return bool(e.names) and all(n in self.params or n.startswith(("manifest.", "param."))
                                     for n in e.names)

    def _req_dict(self, req: Requirement, resolved: tuple[np.ndarray, ...] | None) -> dict[str, Any]:
        unit = canonical(req.unit) if req.unit and req.unit not in NON_NUMERIC else req.unit
        out: dict[str, Any] = {"op": req.op, "unit": unit}

        def one(spec: Any, arr: np.ndarray | None) -> Any:
            if arr is None:
                return spec
            uniq = np.unique(arr[~np.isnan(arr)]) if arr.dtype.kind == "f" else arr
            if len(uniq) == 1:
                return float(uniq[0])
            return None  # varies per item; see the record's own threshold

        if req.op == "between":
            out["min"] = one(req.min, resolved[0] if resolved else None)
            out["max"] = one(req.max, resolved[1] if resolved else None)
            if isinstance(req.min, str):
                out["min_expr"] = req.min
            if isinstance(req.max, str):
                out["max_expr"] = req.max
            out["min_inclusive"], out["max_inclusive"] = req.min_inclusive, req.max_inclusive
        elif req.op == "in":
            out["values"] = list(req.values or [])
        elif req.op in ("present", "true", "false"):
            pass
        else:
            out["value"] = one(req.value, resolved[0] if resolved else None)
            if isinstance(req.value, str) and resolved is not None:
                out["expr"] = req.value
        if resolved is not None:
            out["_arrays"] = resolved
        out["text"] = requirement_text(req, out)
        return out

    def _sample_mask(self, scope: str, items: list[str]) -> np.ndarray | None:
        """With `check --sample`, items of the sampled scope outside the sample are not checked."""
        sample = self.options.get("sample")
        if not sample or sample[0] != scope:
            return None
        return np.isin(np.asarray(items, dtype=object), list(sample[1]))

    # --- manual rules
    def _manual_table(self) -> pd.DataFrame | None:
        t = self.d.table("manual_checks")
        return None if t is None else t.df.assign(_file=t.file, _sha=t.sha256)

    def _signed(self, rule_id: str) -> dict[str, tuple[int, Any]]:
        """item -> (entry index, entry) of the checker file's verdicts on ``rule_id``."""
        if self.checker is None:
            return {}
        return {m.item: (i, m) for i, m in enumerate(self.checker.model.manual_checks) if m.check == rule_id}

    def _stated(self, rule_id: str) -> dict[str, tuple[str, Evidence]]:
        """item -> (quoted statement, evidence) of the contractor's manual_checks rows on ``rule_id``."""
        df = self._manual
        if df is None:
            return {}
        out: dict[str, tuple[str, Evidence]] = {}
        for _, h in df[df["check"] == rule_id].iterrows():
            row = int(h["_row"])
            extra = h.get("note")
            text = (f"the contractor's internal QC statement (evidence, not a verdict): "
                    f"{str(h['verdict']).strip()!r} by {h['inspector']} on {h['date']} "
                    f"({h['_file']} row {row})" + (f": {extra}" if not _is_missing(extra) else ""))
            out[str(h["item"])] = (text, Evidence(str(h["_file"]), str(h["_sha"]), (row,)))
        return out

    def _manual_rule(self, rule: Rule, items: list[str]) -> RuleResult:
        """A human verdict: the checker file's ``manual_checks`` decide; the delivery's own
        manual_checks table is the contractor's internal-QC statement (JRC §2), quoted as evidence."""
        if not items:
            items = [self.d.id]
        n = len(items)
        verdict = np.full(n, MISSING, dtype=np.int8)
        measured = np.full(n, None, dtype=object)
        notes = np.full(n, None, dtype=object)
        evidence: list[tuple[Evidence, ...]] = [()] * n
        signed = self._signed(rule.id)
        stated = self._stated(rule.id)
        for i, item in enumerate(items):
            k = signed.get(item, signed.get("*"))
            c = stated.get(item, stated.get("*"))
            ev: list[Evidence] = []
            if k is None:
                note = ("manual check: no recorded verdict from the checker (check --checker FILE, "
                        "manual_checks: check, item, date, verdict)")
            else:
                idx, entry = k
                ev.append(self.checker.evidence("manual_checks", idx))  # type: ignore[union-attr]
                measured[i] = entry.verdict
                who = entry.inspector or self.checker.who()  # type: ignore[union-attr]
                if entry.verdict == "pass":
                    verdict[i] = PASS
                    note = f"signed by {who} on {entry.date}"
                else:
                    verdict[i] = FAIL if rule.level == "mandatory" else WARN
                    note = f"judged failing by {who} on {entry.date}"
                note += f" (checker file {self.checker.name})" + (  # type: ignore[union-attr]
                    f": {entry.note}" if entry.note else "")
            if c is not None:
                ev.insert(0, c[1])
                note += f"; {c[0]}"
            notes[i] = note
            evidence[i] = tuple(ev)
        if rule.when:
            applicable, unknown, unknown_note = self._applicable(rule, items)
            na = ~applicable & ~unknown
            verdict[na] = NA
            notes[na] = f"not applicable: {rule.when} is false"
            if unknown.any():
                unsigned = unknown & (verdict == MISSING)
                notes[unsigned] = unknown_note
        return RuleResult(rule, np.array(items, dtype=object), verdict, measured, "text",
                          self._req_dict(rule.requirement, None), evidence, notes)

    # --- roll-up
    def _blocking(self, r: RuleResult) -> np.ndarray:
        bad = (FAIL, MISSING, ERROR) + ((WARN,) if self.fail_on == "warn" else ())
        if r.rule.level == "recommended" and self.fail_on != "warn":
            return np.zeros(len(r.verdict), dtype=bool)
        return np.isin(r.verdict, bad)

    def _blocks_of(self, scope: str) -> dict[str, set[str]] | None:
        """item -> blocks it belongs to / serves, from the scope's table `block` column
        (';'-separated for an item serving several blocks, e.g. a DEM; a DEM without one is placed
        by its file's footprint, derived.dem_blocks); None when unknown."""
        if scope == "dem":
            try:
                m = self.cache.get("derived.dem_blocks")
            except OrthospecError:
                return None
            return {str(k): {x for x in str(v).split(";") if x} for k, v in m.values.items() if not _is_missing(v)}
        table = next((name for name, spec in table_specs().items()
                      if spec.scope == scope and spec.id is not None), None)
        t = self.d.table(table) if table else None
        if t is None or "block" not in t.df:
            return None
        out: dict[str, set[str]] = {}
        for item, b in zip(t.ids.astype(str).tolist(), t.df["block"].tolist(), strict=True):
            if not _is_missing(b):
                out[item] = {x.strip() for x in str(b).split(";") if x.strip()}
        return out

    def _rollup_items(self, results: list[RuleResult]) -> tuple[dict[str, list[str]], list[str]]:
        rejected: dict[str, set[str]] = {}
        reasons: list[str] = []
        self._scope_wide: list[str] = []  # findings that could not be tied to items: return the delivery
        for r in results:
            mask = self._blocking(r)
            if not mask.any():
                continue
            items = [str(i) for i in r.items[mask]]
            c = r.rule.consequence
            if "*" in items and c in ("reject_item", "reject_block"):  # return_delivery is reported anyway
                v = VERDICTS[int(r.verdict[mask][0])]
                note = next((str(x) for x in r.notes[mask] if x), "")
                self._scope_wide.append(f"{r.rule.id} ({r.rule.clause.text()}): {v} for the whole {r.rule.scope} "
                                        f"scope, not for named items ({note[:160]}): the delivery is returned")
                items = [i for i in items if i != "*"]
                if not items:
                    continue
            if c == "reject_item":
                rejected.setdefault(r.rule.scope, set()).update(items)
            elif c == "reject_block":
                if r.rule.scope == "block":
                    blocks = set(items)
                    unmapped: list[str] = []
                else:
                    bmap = self._blocks_of(r.rule.scope)
                    blocks = set().union(*(bmap.get(i, set()) for i in items)) if bmap else set()
                    unmapped = [i for i in items if not bmap or not bmap.get(i)]
                    if unmapped:
                        self._scope_wide.append(
                            f"{r.rule.id} ({r.rule.clause.text()}) rejects {r.rule.scope} item(s) "
                            f"{', '.join(unmapped[:5])} but the blocks they serve are unknown (no `block` "
                            f"column value for them): the finding stands at delivery level and the "
                            "delivery is returned")
                if blocks:
                    rejected.setdefault("block", set()).update(blocks)
                    reasons.append(f"{r.rule.id} ({r.rule.clause.text()}) rejects block(s) "
                                   + ", ".join(sorted(blocks)))
        return {k: sorted(v) for k, v in sorted(rejected.items())}, reasons

    def _param_number(self, name: str, default: float) -> float:
        p = self.params.get(name)
        v = getattr(p, "value", None)
        return float(v) if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) \
            else default

    def _rollup_measures(self, rejected: dict[str, list[str]]) -> dict[str, Measured]:
        """Roll-up measures through the one implementation of JRC §12.3 / §12.8 (measures/acceptance)."""
        d = self.d
        out: dict[str, Measured] = {}
        max_share = self._param_number("fail_share_max", 5.0) / 100.0
        imgs = d.table("images")
        ev_img = imgs.evidence(imgs.df["_row"]) if imgs is not None else (d.manifest_evidence("tables"),)
        share = samp = None
        rej: set[str] = set()
        self._image_verdict: DeliveryVerdict | None = None
        if imgs is not None:
            all_imgs = imgs.ids.astype(str).tolist()
            sampled = all_imgs
            given = self.options.get("sample")
            if given and given[0] == "image":
                sampled = [i for i in all_imgs if i in given[1]]
            elif "sample" in imgs.df and imgs.df["sample"].map(lambda v: v is True).any():
                # the `sample` column travels with the delivery: an image the rules checked and
                # rejected counts as tested whether or not it is marked, so marking only good
                # images cannot shrink the failure share (issue 17, fail-open by the contractor)
                marked = set(imgs.ids[imgs.df["sample"].map(lambda v: v is True)].astype(str).tolist())
                failed = set(rejected.get("image", []))
                sampled = [i for i in all_imgs if i in marked or i in failed]
            rej = set(rejected.get("image", [])) & set(sampled)
            samp = 100.0 * len(sampled) / len(all_imgs) if all_imgs else None
            if sampled:
                action = getattr(self.params.get("image_fail_share_action"), "value", None)
                self._image_verdict = image_delivery_verdict(
                    len(all_imgs), [i in rej for i in sampled], sampled_ids=sampled,
                    max_failed_fraction=max_share, returns=action != "keep")
                share = 100.0 * self._image_verdict.failed_fraction
        blocks = d.block_ids
        cps = d.table("checkpoints")
        with_points = set(cps.df["block"].astype(str)) & set(blocks) if cps is not None else set()
        brej = set(rejected.get("block", [])) & set(blocks)
        # a declared block without check points is missing evidence, never dropped from the share:
        # the blocks subjected to external QC are those with points plus those a rule rejected
        checked = sorted(with_points | brej)
        given = self.options.get("sample")
        if given and given[0] == "block":
            checked = [b for b in checked if b in given[1]]
        self._block_verdict: ProjectVerdict | None = None
        bshare = None
        if blocks and checked:
            self._block_verdict = project_verdict(
                len(blocks), [b not in brej for b in checked], checked_ids=checked,
                max_failed_fraction=max_share, space_resection=self._space_resection())
            bshare = 100.0 * self._block_verdict.failed_fraction
        elif blocks:
            bshare = 0.0 if not brej else 100.0
        bchecked = 100.0 * len(with_points) / len(blocks) if blocks else None
        ev_blk = (cps.evidence(cps.df["_row"]) if cps is not None else (d.manifest_evidence("blocks"),))
        vals = {
            "rollup.image_rejected_share": (share, ev_img), "rollup.images_sampled_share": (samp, ev_img),
            "rollup.images_rejected": (float(len(rej)) if imgs is not None else None, ev_img),
            "rollup.block_rejected_share": (bshare, ev_blk), "rollup.blocks_checked_share": (bchecked, ev_blk),
            "rollup.blocks_rejected": (float(len(brej)), ev_blk),
        }
        for name, (v, ev) in vals.items():
            scope, unit = ROLLUP[name]
            item = d.id if scope == "delivery" else d.project_id
            out[name] = Measured(name, scope, unit, pd.Series({item: v}, dtype=object),
                                 pd.Series({item: ev}, dtype=object))
        return out

    def _space_resection(self) -> bool:
        """JRC §12.8 footnote 6 applies: the orthophotos were produced by space resection."""
        try:
            m = self.cache.get("derived.orthorectification")
        except OrthospecError:
            return False
        return bool(len(m.values)) and m.values.iloc[0] == "space_resection"

    def _overall(self, results: list[RuleResult], rejected: dict[str, list[str]], *,
                 has_block_rollup: bool, has_image_rollup: bool) -> tuple[str, list[str]]:
        reasons: list[str] = list(getattr(self, "_scope_wide", []))
        for r in results:
            mask = self._blocking(r)
            if not mask.any():
                continue
            if r.rule.consequence == "warn" and r.rule.level == "mandatory":
                # every mandatory rule can change the verdict: `warn` cannot make a failing
                # mandatory requirement acceptable (issue 12); the finding returns the delivery
                items = ", ".join(str(i) for i in r.items[mask][:5])
                reasons.append(f"{r.rule.id} ({r.rule.clause.text()}): mandatory rule "
                               f"{VERDICTS[int(r.verdict[mask][0])]} for {items}; its consequence 'warn' "
                               "cannot accept a failing mandatory requirement")
            elif r.rule.consequence == "return_delivery" or (
                    r.rule.consequence == "reject_block" and r.rule.scope in ("delivery", "project")):
                items = ", ".join(str(i) for i in r.items[mask][:5])
                reasons.append(f"{r.rule.id} ({r.rule.clause.text()}): {VERDICTS[int(r.verdict[mask][0])]} "
                               f"for {items}")
        if self.fail_on == "warn":
            warned = [r.rule.id for r in results if (r.verdict == WARN).any()]
            if warned:
                reasons.append(f"--fail-on warn: recommended-level rule(s) not met: {', '.join(warned[:10])}"
                               + (f" (+{len(warned) - 10} more)" if len(warned) > 10 else ""))
        if rejected.get("block") and not has_block_rollup:
            bv = getattr(self, "_block_verdict", None)
            reasons.append("block(s) " + ", ".join(rejected["block"]) + " rejected and the profile has no "
                           "mandatory project-level roll-up rule: any rejected block returns the delivery"
                           + (f" (JRC §12.8: {bv.reason})" if bv is not None else ""))
        if rejected.get("image") and not has_image_rollup:
            iv = getattr(self, "_image_verdict", None)
            reasons.append("image(s) rejected and the profile has no mandatory delivery-level roll-up rule: "
                           "any rejected image returns the delivery"
                           + (f" (JRC §12.3: {iv.reason})" if iv is not None else ""))
        for scope, items in rejected.items():
            if scope in ("image", "block") or not items:
                continue  # these two have the JRC §12.3 / §12.8 roll-up rules above
            shown = ", ".join(items[:5]) + (f" (+{len(items) - 5} more)" if len(items) > 5 else "")
            reasons.append(f"{scope} item(s) {shown} rejected and no roll-up rule covers the {scope} scope: "
                           "a rejected item returns the delivery")
        return ("rejected" if reasons else "accepted"), reasons
