"""Whether a rule applies, per item, from its `when` - and when that cannot be known.

A fact the `when` reads but the delivery does not give makes the rule's applicability unknown -
evidence missing, never a silent `not_applicable` - unless the condition is decided whatever that
fact is (``type == 'satellite' and digital == false`` on an aerial delivery), or the `when` itself
tests the name for null. Decided by probing: the missing fact is replaced by stand-in values (the
literals of the `when`, extremes) and the condition is evaluated for each.
"""

from __future__ import annotations

import itertools
import math
from functools import lru_cache
from typing import Any

import numpy as np

from .. import units
from ..delivery import vocabulary
from ..errors import OrthospecError
from ..profile import expr
from ..profile.models import Rule
from ..profile.operators import is_missing
from ..units import NON_NUMERIC, parse_unit
from .catalog import measure_info
from .compare import Undecidable
from .context import Context
from .names import NUMBER_LITERAL, STRING_LITERAL, Names, missing_mask, null_tested, param_key

#: at most this many probe combinations; beyond, a missing fact makes the item unknown
MAX_PROBES = 512


def unknown_note(rule: Rule, absent: list[str]) -> str:
    shown = ", ".join(a[len("manifest."):] + " (delivery.yaml)" if a.startswith("manifest.") else a
                      for a in absent)
    return (f"applicability unknown: no value for {shown}; the rule applies when {rule.when} - "
            "declare the fact (or deliver the data) so the rule can be decided")


def is_global(ctx: Context, name: str) -> bool:
    """A name with one value for the whole delivery (parameter, manifest fact, delivery measure)."""
    if name in ctx.params or name.startswith(("manifest.", "param.")):
        return True
    info = measure_info(name)
    return info is not None and info[0] in ("delivery", "project")


def _missing_of(ctx: Context, name: str, names: Names, n: int) -> np.ndarray:
    """Per item: the fact or measure ``name`` has no value (so a `when` over it cannot be decided)."""
    key = param_key(name)
    if key in ctx.params:
        return np.full(n, ctx.params[key].value is None)
    if key.startswith("manifest."):
        return np.full(n, is_missing(ctx.manifest.get(key)))
    info = measure_info(key)
    try:
        m = ctx.cache.get(key)
    except OrthospecError:
        return np.ones(n, dtype=bool)
    if info is not None and names.broadcast(info[0]):
        one = m.values.iloc[0] if len(m.values) else None
        return np.full(n, is_missing(one))
    vals = m.values.reindex(names.item_ids).to_numpy(dtype=object)
    # a word outside the column's closed vocabulary is an unknown fact, not a mismatch (issue 25)
    return missing_mask(vals) | vocabulary.unknown_values(key, vals)


def _probes(ctx: Context, name: str, when: str) -> list[Any]:
    """Values that stand in for a missing ``name`` to see whether the `when` depends on it."""
    strings = [a or b for a, b in STRING_LITERAL.findall(when)]
    numbers = [float(x) for x in NUMBER_LITERAL.findall(when)]
    key = param_key(name)
    if key in ctx.params:
        p = ctx.params[key]
        if p.unit in NON_NUMERIC:
            return [True, False] if p.unit == "bool" else [*strings, "\x00absent"]
        return [units.Q_(v, parse_unit(p.unit)) for v in (-1e12, 0.0, *numbers, 1e12)]
    info = measure_info(key)
    unit = info[1] if info else "any"
    if unit == "bool":
        return [True, False]
    if unit in NON_NUMERIC:
        return [*strings, "\x00absent"]
    if unit == "any":
        return [True, False, 0.0, *numbers, *strings, "\x00absent"]
    return [-1e12, 0.0, *numbers, 1e12]


def _truth(v: Any, n: int) -> np.ndarray:
    v = getattr(v, "magnitude", v)
    if v is None:
        return np.zeros(n, dtype=bool)
    if np.ndim(v) == 0:
        return np.full(n, bool(v), dtype=bool)
    return np.array(
        [bool(c) if not is_missing(c) else False for c in np.asarray(v, dtype=object)], dtype=bool
    )


def _probe_all(
    e: expr.Expression, names: Names, probe: list[str], cands: list[list[Any]], n: int
) -> tuple[np.ndarray | None, np.ndarray]:
    """Evaluate the `when` for every combination of stand-ins: (first outcome, items whose outcome varies)."""
    first: np.ndarray | None = None
    varies = np.zeros(n, dtype=bool)
    if math.prod(len(c) for c in cands) > MAX_PROBES:
        return None, varies
    for combo in itertools.product(*cands):
        names.fill = dict(zip(probe, combo, strict=True))
        try:
            v = _truth(e.evaluate(names), n)
        except (OrthospecError, TypeError, ValueError):
            continue  # a stand-in the expression cannot use (e.g. text where it compares numbers)
        if first is None:
            first = v
        else:
            varies |= v != first
    return first, varies


def when(
    ctx: Context, rule: Rule, items: list[str], *, scalar: bool = False
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(applies, unknown, absent names) per item of a rule's `when`."""
    n = 1 if scalar else len(items)
    e = expr.parse(rule.when or "true")
    names = Names(ctx.params, ctx.manifest, ctx.cache, rule.scope, items, scalar=scalar)
    base = _truth(e.evaluate(names), n)
    nulls = null_tested(rule.when or "")
    missing = {k: _missing_of(ctx, k, names, n) for k in sorted(e.names) if k not in nulls}
    probe = [k for k, mk in missing.items() if mk.any()]
    if not probe:
        return base, np.zeros(n, dtype=bool), []
    has_missing = np.logical_or.reduce([missing[k] for k in probe])
    first, varies = _probe_all(
        e, names, probe, [_probes(ctx, k, rule.when or "") for k in probe], n
    )
    if first is None:
        return base & ~has_missing, has_missing, probe
    unknown = varies & has_missing
    return first & ~unknown, unknown, probe


@lru_cache(maxsize=4096)
def _vocabulary_problems(when: str, measure: str, values: tuple[Any, ...]) -> tuple[str, ...]:
    return tuple(vocabulary.literal_problems(when, extra=[(measure, v) for v in values]))


def check_vocabulary(rule: Rule) -> None:
    """A `when` (or an ``in`` requirement) comparing a closed-vocabulary column with a word that is
    not one of its values can never match a cell the reader normalised: the rule cannot be
    decided (``missing``), never silently not applicable (issue 25 item 4)."""
    values = tuple(rule.requirement.values or ()) if rule.requirement.op == "in" else ()
    problems = _vocabulary_problems(rule.when or "", rule.measure, values)
    if problems:
        raise Undecidable(
            f"{rule.id} cannot be decided: "
            + "; ".join(problems)
            + " - the profile must use the column's values (specs/delivery-tables.yaml)"
        )


def applicable(
    ctx: Context, rule: Rule, items: list[str]
) -> tuple[np.ndarray, np.ndarray, str | None]:
    """Per-item applicability from `when`: (applies, unknown, note for the unknown items)."""
    n = len(items)
    check_vocabulary(rule)
    if not rule.when:
        return np.ones(n, dtype=bool), np.zeros(n, dtype=bool), None
    applies, unknown, absent = when(ctx, rule, items)
    return applies, unknown, unknown_note(rule, absent) if unknown.any() else None


def scalar_condition(ctx: Context, rule: Rule) -> tuple[bool | None, str | None]:
    """A `when` over delivery-wide facts only, decided once: (True/False, None), (None, why
    unknown), or (None, None) when it reads per-item measures."""
    check_vocabulary(rule)
    if not rule.when:
        return None, None
    e = expr.parse(rule.when)
    if any(not is_global(ctx, n) for n in e.names):
        return None, None
    applies, unknown, absent = when(ctx, rule, [], scalar=True)
    if unknown[0]:
        return None, unknown_note(rule, absent)
    return bool(applies[0]), None
