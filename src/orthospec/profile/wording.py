"""How a requirement is worded: one text for the QCR records, the terminal, reports, `explain` and
the tender annex (the annex the buyer publishes and the QCR the contractor receives state a
requirement the same way).

The sentence of each operator lives with the operator (``profile/operators.py``); this module formats
the thresholds (number, unit) it is given with ``orthospec.present`` (whose ``fmt_value`` and
``unit_suffix`` it re-exports). Pure (no numpy, no pint), so the commands that only word a rule do
not import the engine.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from ..present import NO_UNIT, fmt_value, unit_suffix
from .models import Requirement
from .operators import operator

__all__ = [
    "NO_UNIT",
    "UNFIXED",
    "fmt_value",
    "param_value",
    "profile_requirement_text",
    "profile_thresholds",
    "requirement_text",
    "unit_suffix",
]

#: requirement texts already built: (id of the requirement, resolved unit and bounds) -> (requirement, text)
_TEXT_MEMO: dict[tuple[Any, ...], tuple[Requirement, str]] = {}


def _memo_part(v: Any) -> Any:
    """A key part that tells 0.0 from -0.0 (they print differently) and types apart (1 vs 1.0 vs True)."""
    if isinstance(v, float):
        return (float, v, math.copysign(1.0, v))
    return (type(v), v)


def requirement_text(req: Requirement, resolved: dict[str, Any]) -> str:
    """The requirement as text, e.g. ``≤ 2.5 m`` for ``{op: "<=", value: tolerance_xy, unit: m}``.

    ``resolved`` gives the threshold(s) in force (``value``, ``min``, ``max``): a number is printed
    with the requirement's unit; None words the threshold as the profile writes it; a string is
    printed as given (the annex passes its words for a threshold nobody has fixed yet).

    Records call this once per item with the item's resolved threshold; the text depends only on
    the requirement and those resolved values, so it is built once per distinct value (a rule
    with one threshold for 1,000,000 check points builds it once).
    """
    try:
        key = (
            id(req),
            _memo_part(resolved.get("unit")),
            _memo_part(resolved.get("min")),
            _memo_part(resolved.get("max")),
            _memo_part(resolved.get("value")),
        )
        hit = _TEXT_MEMO.get(key)
    except TypeError:  # an unhashable resolved value: build the text directly
        return _requirement_text(req, resolved)
    if hit is not None and hit[0] is req:
        return hit[1]
    text = _requirement_text(req, resolved)
    if len(_TEXT_MEMO) >= 4096:
        _TEXT_MEMO.clear()
    _TEXT_MEMO[key] = (req, text)
    return text


def _requirement_text(req: Requirement, resolved: dict[str, Any]) -> str:
    suffix = unit_suffix(req.unit if req.unit is not None else resolved.get("unit"))

    def show(key: str) -> str:
        """A threshold: its resolved number with the unit; text (a literal, an expression whose value
        varies per item or is not known, or the caller's words for it) as given."""
        spec = getattr(req, key)
        if spec is None:  # no such threshold (an open side of `between`)
            return ""
        val = resolved.get(key)
        if val is None:
            val = spec
        if isinstance(val, str):
            return val
        if isinstance(val, bool):
            return fmt_value(val)
        return f"{fmt_value(val)}{suffix}"

    op = operator(req.op)
    return op.text(
        show("value"),
        lo=show("min"),
        hi=show("max"),
        min_inclusive=req.min_inclusive,
        max_inclusive=req.max_inclusive,
        values=[fmt_value(v) for v in req.values or []],
    )


# --- the requirement in force before a delivery is read (annex, `explain`, `spec diff`) -----------

#: how a threshold reads while its parameter waits for the tender to fix it
UNFIXED = "the value fixed in the ITT"


def param_value(p: Any) -> Any:
    """The value a tender fixes, else the standard's default (None: the ITT must fix it)."""
    return p.value if p.value is not None else p.default


def profile_thresholds(
    req: Requirement,
    params: Mapping[str, Any],
    *,
    evaluate: Callable[[str, dict[str, Any]], Any] | None = None,
    words: Callable[[str], str] | None = None,
) -> dict[str, Any]:
    """The thresholds of ``req`` as the profile's parameters fix them, as ``requirement_text`` takes
    them: a bare parameter name gives its value (or :data:`UNFIXED`); an expression over parameters
    gives ``evaluate(source, {name: value})`` when the caller passes an evaluator (the annex does;
    `explain` does not, to stay free of numpy) and that returns a plain number; anything else is
    ``words(source)``, or the source as written."""
    out: dict[str, Any] = {"unit": req.unit}
    for key in ("value", "min", "max"):
        spec = getattr(req, key)
        if not isinstance(spec, str):
            continue
        if spec in params:
            v = param_value(params[spec])
            out[key] = UNFIXED if v is None else v
            continue
        got: Any = None
        if evaluate is not None:
            got = evaluate(spec, {n: param_value(p) for n, p in params.items()})
        if isinstance(got, int | float) and not isinstance(got, bool) and math.isfinite(got):
            out[key] = float(got)
        elif words is not None:
            out[key] = words(spec)
    return out


def profile_requirement_text(req: Requirement, params: Mapping[str, Any], **kw: Any) -> str:
    """``requirement_text`` with the thresholds the profile's parameters fix (see
    :func:`profile_thresholds`): what the tender annex, `spec diff` and `explain` print."""
    return requirement_text(req, profile_thresholds(req, params, **kw))
