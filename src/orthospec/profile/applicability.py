"""Whether a rule can apply under a tender's sensor, read from the rule alone (no delivery).

Used by ``orthospec init --sensor`` (profile/template.py) and the tender annex (reports/annex.py) to
leave out the rules a sensor type or film/digital choice excludes. Only the parts of a condition
joined by a top-level ``and`` are read: ``type == 'aerial' and (a or b)`` cannot apply to a
satellite tender; a part with a top-level ``or`` is kept (it might apply).
"""

from __future__ import annotations

import re

from .models import Rule

_TYPE_EQ = re.compile(r"manifest\.sensor\.type\s*(==|!=)\s*['\"](\w+)['\"]")
_DIGITAL_EQ = re.compile(r"manifest\.sensor\.digital\s*==\s*(true|false)")
#: measure-name prefixes of the satellite-only tables
SATELLITE_TABLES = ("scenes.",)


def _conjuncts(when: str) -> list[str]:
    """The parts of ``when`` joined by a top-level ``and`` (outside parentheses); a part that holds
    a top-level ``or`` is dropped (it might hold either way). ``a and (b or c)`` -> ``[a]``."""
    parts, depth, start, i = [], 0, 0, 0
    while i < len(when):
        ch = when[i]
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0 and when.startswith(" and ", i):
            parts.append(when[start:i])
            start = i = i + 5
            continue
        i += 1
    parts.append(when[start:])
    out = []
    for part in parts:
        p = part.strip()
        while p.startswith("(") and p.endswith(")") and _balanced(p[1:-1]):
            p = p[1:-1].strip()
        if not _top_level_or(p):
            out.append(p)
    return out


def _balanced(text: str) -> bool:
    depth = 0
    for ch in text:
        depth += ch == "("
        depth -= ch == ")"
        if depth < 0:
            return False
    return depth == 0


def _top_level_or(text: str) -> bool:
    depth = 0
    for i, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0 and text.startswith(" or ", i):
            return True
    return False


def cannot_apply(rule: Rule, sensors: set[str], digital: bool | None) -> str | None:
    """Why ``rule`` cannot apply under the tender's ``sensors`` (and film/digital), or None."""
    when = " ".join((rule.when or "").split())
    for part in _conjuncts(when) if when else []:
        if part.startswith("not ") or part.startswith("not("):
            continue  # a negated part says what the rule does not need
        for op, val in _TYPE_EQ.findall(part):
            if sensors and op == "==" and val not in sensors:
                return f"applies to {val} sensors only"
            if sensors and op == "!=" and sensors == {val}:
                return f"does not apply to {val} sensors"
        for val in _DIGITAL_EQ.findall(part):
            if digital is not None and (val == "true") != digital:
                return (
                    "applies to film cameras only"
                    if val == "false"
                    else "applies to digital sensors only"
                )
    if (
        sensors
        and "satellite" not in sensors
        and (rule.measure.startswith(SATELLITE_TABLES) or any(t in when for t in SATELLITE_TABLES))
    ):
        return "reads the satellite scenes table"
    return None
