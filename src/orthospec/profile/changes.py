"""What a profile changes in a mandatory rule of the profile it extends, in words.

A tender builds on a standard; it may tighten it freely, but a change that can only make a mandatory
rule of the standard check less (remove it, make it recommended, give it a lighter consequence, gate
it with a condition the standard did not have, swap what it measures, make it manual, change its
requirement) needs a justification: the loader refuses it without one, and `spec diff`, the annex's
first page and page 1 of every report checked under the tender list it. The observation behind it:
`when: "1 == 0"` or a measure that cannot fail left the title and quote in place, and the report
still printed "Block RMSEy within the tolerance: pass".

Pure (models only): used by the loader, `spec diff`, the annex and the QCR.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from .models import Rule

__all__ = ["CONSEQUENCE_RANK", "Weakening", "weakened_fields", "weakening_changes"]

#: how much of the delivery a failing rule takes with it (a move down this scale weakens the rule);
#: ``incomplete`` sends the finding to the checker, so the contractor's products are never rejected
CONSEQUENCE_RANK = {
    "warn": 0,
    "incomplete": 1,
    "reject_item": 2,
    "reject_block": 3,
    "return_delivery": 4,
}


@dataclass(frozen=True)
class Weakening:
    """A mandatory rule of the base profile that an extending profile removed or changed so it
    can check less, with the profile's justification (None only in `spec diff` of unrelated files)."""

    id: str
    changes: tuple[str, ...]
    justification: str | None
    profile: str
    title: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "title": self.title,
            "changes": list(self.changes),
            "justification": self.justification,
            "profile": self.profile,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Weakening:
        return cls(
            str(d["id"]),
            tuple(str(c) for c in d["changes"]),
            d.get("justification"),
            str(d["profile"]),
            str(d.get("title") or ""),
        )


def _text(v: Any) -> str:
    return json.dumps(v, ensure_ascii=False, sort_keys=True) if isinstance(v, dict) else str(v)


def weakened_fields(before: Rule, after: Rule) -> list[str]:
    """The fields of ``after`` that can make the mandatory ``before`` check less (field names)."""
    if before.level != "mandatory":
        return []
    out = []
    if after.level != "mandatory":
        out.append("level")
    if CONSEQUENCE_RANK.get(after.consequence, -1) < CONSEQUENCE_RANK.get(before.consequence, -1):
        out.append("consequence")
    if after.when and " ".join(after.when.split()) != " ".join((before.when or "").split()):
        out.append("when")  # a condition the base did not have (removing one only widens the rule)
    if after.measure != before.measure:
        out.append("measure")
    if after.scope != before.scope:
        out.append("scope")
    if after.manual and not before.manual:
        out.append("manual")
    if after.requirement != before.requirement:
        out.append("requirement")
    return out


def weakening_changes(before: Rule, after: Rule | None) -> list[str]:
    """Each change of ``after`` that can make the mandatory rule ``before`` check less, in words
    (``["level mandatory -> recommended", "when added: 1 == 0"]``); ``after`` None: removed."""
    if before.level != "mandatory":
        return []
    if after is None:
        return ["removed"]
    out = []
    for f in weakened_fields(before, after):
        if f == "level":
            out.append(f"level {before.level} -> {after.level}")
        elif f == "consequence":
            out.append(f"consequence {before.consequence} -> {after.consequence}")
        elif f == "when":
            if not before.when:
                out.append(f"condition added: when {after.when}")
            else:
                out.append(f"condition when {before.when} -> when {after.when}")
        elif f == "measure":
            out.append(f"measure {before.measure} -> {after.measure}")
        elif f == "scope":
            out.append(f"scope {before.scope} -> {after.scope}")
        elif f == "manual":
            out.append("made manual (a human verdict instead of the measurement)")
        elif f == "requirement":
            out.append(
                f"requirement {_text(before.requirement.model_dump(exclude_defaults=True))} -> "
                f"{_text(after.requirement.model_dump(exclude_defaults=True))}"
            )
    return out
