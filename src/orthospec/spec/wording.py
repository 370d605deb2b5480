"""How a requirement is worded: one text for the QCR records, the terminal, reports and `explain`.

Pure (no numpy, no pint), so the commands that only word a rule do not import the engine.
"""

from __future__ import annotations

import math
from typing import Any

from .models import Requirement

_OP_TEXT = {"<": "<", "<=": "<=", ">": ">", ">=": ">=", "==": "=", "!=": "!="}


def fmt_value(x: Any) -> str:
    """A measured or threshold value as printed: 6 significant digits, NaN as n/a."""
    if isinstance(x, float):
        if math.isnan(x):
            return "n/a"
        return f"{x:.6g}"
    return str(x)


#: requirement texts already built: (id of the requirement, resolved unit and bounds) -> (requirement, text)
_TEXT_MEMO: dict[tuple[Any, ...], tuple[Requirement, str]] = {}


def _memo_part(v: Any) -> Any:
    """A key part that tells 0.0 from -0.0 (they print differently) and types apart (1 vs 1.0 vs True)."""
    if isinstance(v, float):
        return (float, v, math.copysign(1.0, v))
    return (type(v), v)


def requirement_text(req: Requirement, resolved: dict[str, Any]) -> str:
    """The requirement as text, e.g. ``<= tolerance_xy (2.5 m)``.

    Records call this once per item with the item's resolved threshold; the text depends only on
    the requirement and those resolved values, so it is built once per distinct value (a rule
    with one threshold for 1,000,000 check points builds it once).
    """
    try:
        key = (id(req), _memo_part(resolved.get("unit")), _memo_part(resolved.get("min")),
               _memo_part(resolved.get("max")), _memo_part(resolved.get("value")))
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
    u = f" {resolved['unit']}" if resolved.get("unit") and resolved["unit"] not in ("1",) else ""

    def show(spec: Any, val: Any) -> str:
        if isinstance(spec, str) and val is not None and not isinstance(val, str):
            return f"{spec} ({fmt_value(val)}{u})"
        if isinstance(spec, str):
            return spec
        return f"{fmt_value(spec)}{u}"

    if req.op == "between":
        lo = show(req.min, resolved.get("min")) if req.min is not None else "-inf"
        hi = show(req.max, resolved.get("max")) if req.max is not None else "+inf"
        lb = "[" if req.min_inclusive else "("
        rb = "]" if req.max_inclusive else ")"
        return f"in {lb}{lo}, {hi}{rb}"
    if req.op == "in":
        return "one of " + ", ".join(map(str, req.values or []))
    if req.op == "present":
        return "present"
    if req.op in ("true", "false"):
        return f"is {req.op}"
    return f"{_OP_TEXT[req.op]} {show(req.value, resolved.get('value'))}"
