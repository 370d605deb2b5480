"""Where a check departs from the profile it names: what page 1 and the terminal header say first.

Two things a reader of a verdict must see before the findings (issue 26): a threshold in force that
is not the profile's (set by ``--param`` or the checker's file: to another value where the tender
allows it, or to a value the profile leaves to the ITT), and a mandatory rule of the standard that
the tender removed or weakened, with its justification. Both come from qcr.json alone
(``profile.parameters[*].source/profile_value`` and ``profile.weakened``), so a stored result
re-renders to the same page 1.
"""

from __future__ import annotations

import math
from typing import Any

from ..units import same_value

__all__ = ["contract_lines", "parameter_lines", "weakened_lines"]

_SOURCES = {"cli": "--param", "checker": "the checker's file"}
_NO_UNIT = ("", "1", "text", "bool", "date", None)


def _show(v: Any, unit: Any) -> str:
    if isinstance(v, bool):
        text = "true" if v else "false"
    elif isinstance(v, float):
        text = f"{v:.6g}" if math.isfinite(v) else str(v)
    else:
        text = str(v)
    return text if unit in _NO_UNIT else f"{text} {unit}"


def parameter_lines(doc: dict[str, Any]) -> list[str]:
    """Parameters whose value in force does not come from the profile: one line per value that
    replaces the profile's (``cloud_cover_max = 10 % from the checker's file, instead of the tender's
    5 %``), then one line per source for values the profile leaves to the ITT."""
    prof = doc.get("profile") or {}
    whose = "tender's" if prof.get("extends") else "profile's"
    out: list[str] = []
    filled: dict[str, list[str]] = {}
    for name, p in sorted((prof.get("parameters") or {}).items()):
        if not isinstance(p, dict) or p.get("source") not in _SOURCES or p.get("value") is None:
            continue
        got = f"{name} = {_show(p['value'], p.get('unit'))}"
        if "profile_value" not in p:
            filled.setdefault(_SOURCES[p["source"]], []).append(got)
        elif not same_value(p["value"], p["profile_value"]):
            out.append(
                f"{got} from {_SOURCES[p['source']]}, instead of the {whose} "
                f"{_show(p['profile_value'], p.get('unit'))}"
            )
    for source, values in filled.items():
        out.append(
            f"{', '.join(values)} from {source} (the profile leaves {'them' if len(values) > 1 else 'it'} "
            "to the ITT)"
        )
    return out


def weakened_lines(doc: dict[str, Any]) -> list[str]:
    """One line per mandatory rule of the standard that the tender removed or made check less."""
    prof = doc.get("profile") or {}
    out = []
    for w in prof.get("weakened") or []:
        if not isinstance(w, dict):
            continue
        title = f" ({w['title']})" if w.get("title") else ""
        why = w.get("justification") or "no justification recorded"
        out.append(
            f"{w.get('id')}{title}, mandatory in the standard: {'; '.join(map(str, w.get('changes') or []))}"
            f" by {w.get('profile')}, justified: {why}"
        )
    return out


def contract_lines(doc: dict[str, Any]) -> dict[str, list[str]]:
    """``{"parameters": [...], "weakened": [...]}`` for page 1 and the terminal header."""
    return {"parameters": parameter_lines(doc), "weakened": weakened_lines(doc)}
