"""Whether a rule can apply under a tender's sensor, read from the rule alone (no delivery).

Used by ``orthospec init --sensor`` (spec/template.py) and the tender annex (reports/annex.py) to
leave out the rules a sensor type or film/digital choice excludes. Only conjunctive conditions are
read: a condition with ``or`` is kept (it might apply).
"""

from __future__ import annotations

import re

from .models import Rule

_TYPE_EQ = re.compile(r"manifest\.sensor\.type\s*(==|!=)\s*['\"](\w+)['\"]")
_DIGITAL_EQ = re.compile(r"manifest\.sensor\.digital\s*==\s*(true|false)")
#: measure-name prefixes of the satellite-only tables
SATELLITE_TABLES = ("scenes.",)


def cannot_apply(rule: Rule, sensors: set[str], digital: bool | None) -> str | None:
    """Why ``rule`` cannot apply under the tender's ``sensors`` (and film/digital), or None."""
    when = " ".join((rule.when or "").split())
    if when and " or " not in when:
        for op, val in _TYPE_EQ.findall(when):
            if sensors and op == "==" and val not in sensors:
                return f"applies to {val} sensors only"
            if sensors and op == "!=" and sensors == {val}:
                return f"does not apply to {val} sensors"
        for val in _DIGITAL_EQ.findall(when):
            if digital is not None and (val == "true") != digital:
                return "applies to film cameras only" if val == "false" else "applies to digital sensors only"
    if sensors and "satellite" not in sensors and (
            rule.measure.startswith(SATELLITE_TABLES) or any(t in when for t in SATELLITE_TABLES)):
        return "reads the satellite scenes table"
    return None
