"""Findings: what a person reads first, computed from qcr.json records.

A *finding* states one problem as measured against required, with the rule title, the item and
the clause (``B02: Block RMSEy within the tolerance: 0.641 m > 0.5 m (JRC EUR 23638 EN, §12.7)``).
Findings are ordered by consequence (return the delivery, reject a block, reject an item, the
checker's open work, then missing evidence, errors, warnings) and one root cause gives one finding:
the records of several
rules that fail for the same item with the same message (one missing file) become one finding
that lists the rules affected. The terminal, page 1 of the PDF and the failures table all use
:func:`findings`, so they never disagree.

Not-applicable records are summarised per condition by :func:`not_applicable_summary`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from .. import verdicts as V
from ..present import cite, fmt_number, fmt_value, unit_suffix
from ..profile.operators import OPERATORS
from ..qcr import natural_key

__all__ = [
    "Finding",
    "NotApplicableSummary",
    "by_reason",
    "checker_text",
    "clean_text",
    "findings",
    "fmt_number",
    "not_applicable_summary",
    "reason_line",
    "stated",
    "unsigned_manual_note",
]

PROBLEMS = V.PROBLEMS
_CONSEQUENCE_RANK = {"return_delivery": 0, "reject_block": 1, "reject_item": 2}
RANK_LABELS = (
    "returns the delivery",
    "rejects a block",
    "rejects an item",
    "check incomplete (checker's)",
    "fails (no rejection)",
    "missing evidence",
    "could not be evaluated",
    "warning",
)
# ANSI CSI/OSC sequences and C0/C1 control characters (delivery text must not drive a terminal)
_ESCAPES = re.compile(
    r"\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)?|\x1b\[[0-?]*[ -/]*[@-~]|\x1b[@-_]?|[\x00-\x08\x0b-\x1f\x7f-\x9f]"
)


def checker_text(doc: dict[str, Any]) -> str | None:
    """Who checked, as the reports name them: ``--operator`` (who ran the check), and the party of the
    checker's file (who decided the manual verdicts, waivers and ITT values) with its name and SHA-256.
    None when neither is known. The contractor's QA operator is never this (JRC §2: two parties)."""
    operator = doc.get("operator")
    chk = doc.get("checker") if isinstance(doc.get("checker"), dict) else None
    party = None
    if chk:
        who = ", ".join(str(chk[k]) for k in ("name", "role", "organisation") if chk.get(k))
        sha = str(chk.get("sha256") or "")[:12]
        where = (
            f"checker's folder {chk['folder']}, {chk.get('file', '?')}"
            if chk.get("folder")
            else f"checker's file {chk.get('file', '?')}"
        )
        party = f"{who} ({where}, sha256 {sha}…)"
    if operator and party:
        return f"{operator}; {party}"
    return operator or party


def unsigned_manual_note(records: Iterable[dict[str, Any]], *, checker: Any = None) -> str | None:
    """The one line terminal and page 1 show when manual checks have no checker verdict
    (docs/CHECKER.md: the contractor's statements are evidence, never verdicts). ``checker`` is
    qcr.json's ``checker`` entry: when a checker's file was given, the advice is to complete it."""
    n = sum(1 for r in records if r.get("manual") and r.get("verdict") == V.MISSING)
    if not n:
        return None
    head = f"{n} manual check{'s have' if n > 1 else ' has'} no verdict from the checker"
    if isinstance(checker, dict) and checker.get("file"):
        return (
            f"{head}: the checker's file {checker['file']} has no manual_checks entry for "
            f"{'them' if n > 1 else 'it'}; add one per check (the contractor's manual_checks are evidence, "
            "not verdicts)"
        )
    return (
        f"{head}: give the checker's file with --checker FILE (the contractor's manual_checks are "
        "evidence, not verdicts)"
    )


def clean_text(text: Any) -> str:
    """Delivery-supplied text without terminal escapes or control characters (tab/newline kept)."""
    return _ESCAPES.sub("", "" if text is None else str(text))


def _distinct(v: Any, required: Any) -> str:
    """The measured number with enough digits that it never reads equal to the requirement
    (1.0004 m > 1 m must not print as '1 m > 1 m')."""
    text = fmt_number(v)
    if (
        isinstance(v, float)
        and math.isfinite(v)
        and isinstance(required, int | float)
        and v != required
    ):
        digits = 3
        while digits < 12 and float(text) == float(required):
            digits += 1
            text = fmt_value(v, digits)
    return text


def _req_number(v: Any) -> str:
    """A required value as the profile states it (never rounded: 0.33 stays 0.33)."""
    return fmt_value(v, 10)


def stated(rec: dict[str, Any]) -> str | None:
    """'0.641 m > 0.5 m' for a record with a numeric value and a comparison; None otherwise (the
    operator words what a value that fails it is: ``Operator.unmet_text``)."""
    m = rec.get("measured") or {}
    v = m.get("value")
    req = rec.get("requirement") or {}
    op = OPERATORS.get(str(req.get("op")))
    if op is None or v is None or isinstance(v, str | list | dict):
        return None
    if isinstance(v, bool):  # only a truth requirement is stated for a boolean
        return None if op.has_threshold else op.unmet_text(fmt_value(v))
    if not op.has_threshold:
        return None
    unit = unit_suffix(m.get("unit") if unit_suffix(m.get("unit")) else req.get("unit"))
    if op.unmet:
        value = req.get("value")
        return (
            None
            if value is None
            else op.unmet_text(_distinct(v, value), _req_number(value), unit=unit)
        )
    return op.unmet_text(
        fmt_number(v),
        lo="" if req.get("min") is None else _req_number(req["min"]),
        hi="" if req.get("max") is None else _req_number(req["max"]),
        min_inclusive=req.get("min_inclusive", True),
        max_inclusive=req.get("max_inclusive", True),
        values=[str(x) for x in req.get("values") or []],
        unit=unit,
    )


def rank(verdict: str, consequence: str | None, manual: bool = False) -> int:
    """Consequence order: return delivery, reject block, reject item, the checker's open work
    (consequence ``incomplete``, an unsigned manual check), other fail, missing, error, warn."""
    if verdict in V.FAILING and (consequence == V.INCOMPLETE or (manual and verdict == V.MISSING)):
        return 3
    if verdict == V.FAIL:
        return _CONSEQUENCE_RANK.get(consequence or "", 4)
    return {V.MISSING: 5, V.ERROR: 6, V.WARN: 7}.get(verdict, 8)


def _rank(rec: dict[str, Any]) -> int:
    return rank(rec["verdict"], rec.get("consequence"), bool(rec.get("manual")))


@dataclass
class Finding:
    """One problem as a person reads it."""

    rank: int
    verdict: str
    consequence: str
    rule: str
    title: str
    clause: str
    items: list[str]
    what: str  # '0.641 m > 0.5 m' or the plain message
    rules: list[str] = field(default_factory=list)  # every rule this finding stands for
    n_records: int = 1
    reason: str = ""  # the reason code of the first record (orthospec.verdicts.Reason)
    reasons: dict[str, int] = field(default_factory=dict)  # records per reason code

    @property
    def item_text(self) -> str:
        if len(self.items) <= 6:
            return ", ".join(self.items)
        return f"{len(self.items)} items ({', '.join(self.items[:5])}, …)"

    @property
    def text(self) -> str:
        """'B02: Block RMSEy within the tolerance: 0.641 m > 0.5 m (JRC EUR 23638 EN, §12.7)'."""
        if len(self.rules) > 1:
            return (
                f"{self.item_text}: {self.what} ({len(self.rules)} checks affected: "
                f"{', '.join(self.rules[:4])}{', …' if len(self.rules) > 4 else ''})"
            )
        return f"{self.item_text}: {self.title}: {self.what} ({self.clause})"

    @property
    def label(self) -> str:
        return RANK_LABELS[self.rank] if self.rank < len(RANK_LABELS) else self.verdict

    def as_dict(self) -> dict[str, Any]:
        return {
            "rank": self.rank,
            "label": self.label,
            "verdict": self.verdict,
            "consequence": self.consequence,
            "rule": self.rule,
            "title": self.title,
            "clause": self.clause,
            "items": list(self.items),
            "item_text": self.item_text,
            "what": self.what,
            "rules": list(self.rules),
            "n_records": self.n_records,
            "reason": self.reason,
            "reason_text": REASON_WORDS.get(self.reason, self.reason.replace("_", " ")),
            "text": self.text,
        }


def _what(rec: dict[str, Any]) -> str:
    s = stated(rec)
    if s is not None:
        return s
    if (rec.get("requirement") or {}).get("op") == "present" and rec["verdict"] in (V.FAIL, V.WARN):
        return f"{rec.get('measure') or 'value'} not given, required for every item"
    msg = clean_text(rec.get("message")).strip()
    v = rec["verdict"]
    if v == V.MISSING:
        return f"not measured: {msg}" if msg else "not measured (evidence missing)"
    if v == V.ERROR:
        return f"could not be evaluated: {msg}" if msg else "could not be evaluated"
    return msg or f"{v}, required {(rec.get('requirement') or {}).get('text', '')}".strip()


def reason(rec: dict[str, Any]) -> str:
    """A record's reason code; a qcr.json written before reason codes: its verdict's default."""
    return V.reason_of(str(rec.get("verdict")), rec.get("reason")) or ""


def _count_reasons(recs: Iterable[dict[str, Any]]) -> dict[str, int]:
    out: dict[str, int] = {}
    for r in recs:
        why = reason(r)
        out[why] = out.get(why, 0) + 1
    return out


def findings(records: list[dict[str, Any]]) -> list[Finding]:
    """Every failing, missing, erring or warning record as findings, most consequential first.

    Records of one rule are grouped by their reason code (``orthospec.verdicts.Reason``), never by
    parsing the message; one root cause (one missing file) stays one finding whatever the reasons
    of its records (each finding counts its records per reason: :func:`by_reason`)."""
    problems = [r for r in records if r.get("verdict") in PROBLEMS]
    # 1. one root cause: the same item and message under several rules, without a measured value
    by_cause: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in problems:
        value = (r.get("measured") or {}).get("value")
        if (value is None or isinstance(value, bool)) and r.get("message"):
            by_cause.setdefault((str(r["item"]), str(r["message"])), []).append(r)
    grouped: set[int] = set()
    out: list[Finding] = []
    for (item, msg), recs in by_cause.items():
        if len({r["rule"] for r in recs}) < 2:
            continue
        recs.sort(key=lambda r: (_rank(r), r["rule"]))
        top = recs[0]
        grouped.update(id(r) for r in recs)
        out.append(
            Finding(
                _rank(top),
                top["verdict"],
                top.get("consequence") or "",
                top["rule"],
                top.get("title", ""),
                cite(top.get("clause")),
                [item],
                clean_text(msg),
                rules=[r["rule"] for r in recs],
                n_records=len(recs),
                reason=reason(top),
                reasons=_count_reasons(recs),
            )
        )
    # 2. the same rule and message for many items (no value): one finding listing the items
    by_rule: dict[tuple[str, str, str, str], list[dict[str, Any]]] = {}
    for r in problems:
        if id(r) in grouped:
            continue
        value = (r.get("measured") or {}).get("value")
        key = (
            (r["rule"], r["verdict"], reason(r), _what(r))
            if value is None or stated(r) is None
            else (r["rule"], r["verdict"], reason(r), f"#{id(r)}")
        )
        by_rule.setdefault(key, []).append(r)
    for (_rid, _v, why, _k), recs in by_rule.items():
        top = recs[0]
        out.append(
            Finding(
                _rank(top),
                top["verdict"],
                top.get("consequence") or "",
                top["rule"],
                top.get("title", ""),
                cite(top.get("clause")),
                sorted((str(r["item"]) for r in recs), key=natural_key),
                _what(top),
                rules=[top["rule"]],
                n_records=len(recs),
                reason=why,
                reasons={why: len(recs)},
            )
        )
    # 3. the same statement for the same rules in many items (one cause): one finding listing them
    merged: dict[tuple[Any, ...], Finding] = {}
    for f in out:
        same = (f.rank, f.verdict, f.reason, tuple(f.rules), f.what)
        g = merged.get(same)
        if g is None:
            merged[same] = f
        else:
            g.items = sorted(set(g.items) | set(f.items), key=natural_key)
            g.n_records += f.n_records
            for why, n in f.reasons.items():
                g.reasons[why] = g.reasons.get(why, 0) + n
    final = list(merged.values())
    final.sort(key=lambda f: (f.rank, f.rule, natural_key(f.items[0] if f.items else "")))
    return final


#: each reason code in words (a heading of the findings grouped by reason)
REASON_WORDS: dict[str, str] = {
    V.Reason.NOT_MET: "the measured value does not meet the requirement",
    V.Reason.UNSET_PARAMETER: "a threshold's parameter is not set (the ITT must fix it)",
    V.Reason.NO_GSD: "a value in pixels without the item's GSD",
    V.Reason.NO_THRESHOLD: "the threshold cannot be computed for the item",
    V.Reason.BAD_THRESHOLD: "the threshold is not a finite number",
    V.Reason.NO_VALUE: "no value measured for the item (evidence missing)",
    V.Reason.NO_ITEMS: "no item to judge",
    V.Reason.UNKNOWN_FACT: "the rule's condition reads a fact the delivery does not give",
    V.Reason.PROVIDER_ERROR: "the value could not be read or computed",
    V.Reason.REQUIREMENT_ERROR: "the requirement cannot be evaluated on the measure",
    V.Reason.INTERNAL_ERROR: "an internal error of orthospec",
    V.Reason.UNSIGNED: "a manual check without the checker's verdict",
    V.Reason.WAIVED: "waived",
}


def by_reason(found: Iterable[Finding]) -> list[dict[str, Any]]:
    """Findings grouped by reason code: {reason, text, findings, records, rules}, most records
    first (what the terminal and the report's section 1 print beside the findings). A finding of
    one root cause whose records have several reasons counts under each."""
    groups: dict[str, dict[str, Any]] = {}
    for f in found:
        for why, n in (f.reasons or {f.reason: f.n_records}).items():
            g = groups.setdefault(
                why,
                {
                    "reason": why,
                    "text": REASON_WORDS.get(why, why.replace("_", " ")),
                    "findings": 0,
                    "records": 0,
                    "rules": [],
                },
            )
            g["findings"] += 1
            g["records"] += n
            g["rules"] += [r for r in f.rules if r not in g["rules"]]
    return sorted(groups.values(), key=lambda g: (-g["records"], g["reason"]))


def reason_line(found: Iterable[Finding]) -> str | None:
    """``by reason: not_met 3 findings (5 records); no_value 1 finding (2 records)``, or None."""
    groups = by_reason(found)
    if not groups:
        return None
    return "by reason: " + "; ".join(
        f"{g['reason']} {g['findings']} finding{'s' if g['findings'] != 1 else ''} "
        f"({g['records']} record{'s' if g['records'] != 1 else ''})"
        for g in groups
    )


_NA = re.compile(r"^not applicable:\s*(?P<cond>.*?)\s+is false(?: for this delivery)?\s*$", re.S)


def condition_prose(cond: str) -> str:
    """``manifest.sensor.type == 'satellite'`` -> ``the sensor type is 'satellite'`` (plain words)."""
    text = " ".join(cond.split())
    text = re.sub(
        r"\bmanifest\.tables\.(\w+)", lambda m: "a " + m.group(1).replace("_", " ") + " table", text
    )
    text = re.sub(
        r"\bmanifest\.vectors\.(\w+)",
        lambda m: "a " + m.group(1).replace("_", " ") + " vector layer",
        text,
    )
    text = re.sub(
        r"\bmanifest\.(sensor|product|tender|project)\.(\w+)(?:\.value)?",
        lambda m: f"the {m.group(1)} {m.group(2).replace('_', ' ')}",
        text,
    )
    text = re.sub(
        r"\bmanifest\.(\w+)", lambda m: "the delivery's " + m.group(1).replace("_", " "), text
    )
    text = re.sub(
        r"\b([a-z]\w*)\.([a-z]\w*)\b",
        lambda m: f"the {m.group(2).replace('_', ' ')} (in the {m.group(1)} table)",
        text,
    )
    for a, b in (
        (" == true", " is true"),
        (" == false", " is false"),
        (" != true", " is not true"),
        (" != false", " is not false"),
        (" != null", " is given"),
        (" == null", " is not given"),
        (" != ", " is not "),
        (" == ", " is "),
        (" >= ", " is at least "),
        (" <= ", " is at most "),
        (" > ", " is above "),
        (" < ", " is below "),
    ):
        text = text.replace(a, b)
    text = re.sub(r"\b([a-z]+)_([a-z_]+)\b", lambda m: m.group(0).replace("_", " "), text)
    return text


class NotApplicableSummary:
    """Not-applicable records per condition, accumulated one record at a time (reports stream
    the records; the records themselves stay in qcr.json)."""

    def __init__(self) -> None:
        self.groups: dict[str, dict[str, Any]] = {}
        self._seen: dict[str, tuple[str, str]] = {}  # message -> (condition, prose): parsed once

    def add(self, r: dict[str, Any]) -> None:
        if r.get("verdict") != V.NOT_APPLICABLE:
            return
        msg = clean_text(r.get("message")).strip()
        why = r.get("reason") or V.Reason.CONDITION_FALSE  # a qcr.json written before reason codes
        hit = self._seen.get(f"{why}\0{msg}")
        if hit is None:
            # grouped by the reason code; only a false `when` has a condition to put in words
            m = _NA.match(msg) if why == V.Reason.CONDITION_FALSE else None
            cond = m.group("cond") if m else (msg or "not applicable to this delivery")
            hit = self._seen[f"{why}\0{msg}"] = (
                cond,
                f"applies only when {condition_prose(cond)}" if m else cond,
            )
        cond, prose = hit
        g = self.groups.setdefault(
            cond, {"condition": cond, "prose": prose, "rules": [], "records": 0}
        )
        g["records"] += 1
        if r["rule"] not in g["rules"]:
            g["rules"].append(r["rule"])

    def result(self) -> list[dict[str, Any]]:
        return sorted(self.groups.values(), key=lambda g: (-g["records"], g["condition"]))


def not_applicable_summary(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """Not-applicable records per condition: {condition, prose, rules, records} (records stay in qcr.json)."""
    acc = NotApplicableSummary()
    for r in records:
        acc.add(r)
    return acc.result()
