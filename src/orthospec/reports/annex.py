"""The technical-specification annex of an invitation to tender (ITT), rendered from a profile.

The annex is what bidders read: every parameter the tender fixes (value, unit, description), then
every requirement grouped as the source document groups them (section, or table), with the
clause, the quoted text, the level and the consequence of failing it. Markdown, HTML and PDF/A-3b
(with the resolved profile JSON attached, so the annex and the checker share one source).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import date as Date
from typing import Any

import jinja2

from ..errors import ReportError
from ..qcr import natural_key
from ..resources import templates_dir
from ..spec.loader import ResolvedProfile
from ..spec.models import Parameter, Requirement, Rule
from .html import environment

__all__ = ["ANNEX_FORMATS", "annex_context", "annex_filename", "render_annex"]

ANNEX_FORMATS = ("md", "html", "pdf")
CONSEQUENCES = {
    "reject_item": "the item (image, point, ...) is rejected",
    "reject_block": "all products of the block are rejected",
    "return_delivery": "the whole delivery is returned to the contractor",
    "warn": "recorded as a warning; not a ground for rejection by itself",
}
LEVELS = {"mandatory": "must be met (\"shall\", \"must\", \"will\")",
          "recommended": "should be met; failing it is reported as a warning"}
_NAME = re.compile(r"[a-z][a-z0-9_]*")
_OPS = {"<": "<", "<=": "≤", ">": ">", ">=": "≥", "==": "=", "!=": "≠"}


def _num(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def param_value(p: Parameter) -> Any:
    """The value a tender fixes, else the standard's default (None: the ITT must fix it)."""
    return p.value if p.value is not None else p.default


def requirement_text(req: Requirement, params: dict[str, Parameter]) -> str:
    """'≤ tolerance_xy (2.5 m)': operator, threshold, and a parameter's current value when named."""
    unit = req.unit if req.unit and req.unit != "1" else ""

    def show(v: Any) -> str:
        if isinstance(v, str) and _NAME.fullmatch(v) and v in params:
            p = params[v]
            val = param_value(p)
            pu = p.unit if p.unit and p.unit not in ("1", "text", "bool", "date") else ""
            return f"{v} ({_num(val)}{' ' + pu if pu else ''})" if val is not None else f"{v} (set by the ITT)"
        if isinstance(v, str):
            return v
        return f"{_num(v)}{' ' + unit if unit else ''}"

    if req.op == "between":
        lo = show(req.min) if req.min is not None else "−∞"
        hi = show(req.max) if req.max is not None else "+∞"
        return f"between {lo} {'(incl.)' if req.min_inclusive else '(excl.)'} and {hi} " \
               f"{'(incl.)' if req.max_inclusive else '(excl.)'}"
    if req.op == "in":
        return "one of " + ", ".join(_num(v) for v in req.values or [])
    if req.op == "present":
        return "present (recorded for every item)"
    if req.op in ("true", "false"):
        return f"is {req.op}"
    return f"{_OPS.get(req.op, req.op)} {show(req.value)}"


@dataclass
class Group:
    key: tuple[Any, ...]
    title: str
    rules: list[dict[str, Any]] = field(default_factory=list)


def _group_of(rule: Rule) -> tuple[tuple[Any, ...], str]:
    """Group like the source: by table when the clause cites one, else by top-level section."""
    c = rule.clause
    if c.table:
        return (c.document, "table", str(c.table)), f"{c.document} — Table {c.table}"
    if c.section:
        top = str(c.section).split(".")[0]
        label = f"Section {top}" if top[:1].isdigit() else top
        return (c.document, "section", top), f"{c.document} — {label}"
    return (c.document, "general", ""), f"{c.document} — general"


def _top(rule: Rule) -> str:
    return str(rule.clause.section or "").split(".")[0]


def _group_order(g: Group, sections: list[Rule]) -> tuple[Any, ...]:
    """Source order: each table right after the section its rules cite (Table 1 within §5...)."""
    doc, kind, key = g.key
    if kind == "section":
        return (doc, natural_key(key), 0, ())
    if kind == "table":
        tops = sorted((_top(r) for r in sections if _top(r)), key=natural_key)
        return (doc, natural_key(tops[0]) if tops else ((2, 0, ""),), 1, natural_key(key))
    return (doc, ((2, 0, ""),), 2, ())


def _rule_view(rule: Rule, params: dict[str, Parameter]) -> dict[str, Any]:
    return {
        "id": rule.id, "title": rule.title, "clause": rule.clause.text(), "quote": rule.quote,
        "scope": rule.scope, "when": rule.when, "requirement": requirement_text(rule.requirement, params),
        "measure": rule.measure, "level": rule.level, "consequence": rule.consequence,
        "consequence_text": CONSEQUENCES.get(rule.consequence, rule.consequence), "manual": rule.manual,
        "note": rule.note, "audit": rule.audit.model_dump(exclude_none=True) if rule.audit else {},
        "tags": list(rule.tags),
        "sort": (natural_key(str(rule.clause.section or "")), natural_key(str(rule.clause.row or "")), rule.id),
    }


def annex_context(profile: ResolvedProfile, *, day: str) -> dict[str, Any]:
    """Everything the annex templates show, from the resolved profile."""
    params = dict(profile.parameters)
    groups: dict[tuple[Any, ...], Group] = {}
    members: dict[tuple[Any, ...], list[Rule]] = {}
    for rule in profile.rules:
        key, title = _group_of(rule)
        groups.setdefault(key, Group(key, title)).rules.append(_rule_view(rule, params))
        members.setdefault(key, []).append(rule)
    ordered = sorted(groups.values(), key=lambda g: _group_order(g, members[g.key]))
    for g in ordered:
        g.rules.sort(key=lambda r: r["sort"])
    src = profile.source
    return {
        "profile": profile, "day": day, "source": src,
        "parameters": [{"name": n, "value": param_value(p), "unit": p.unit or "", "required": p.required,
                        "description": p.description, "choices": p.choices,
                        "fixed_by": "tender" if p.value is not None else ("standard" if p.default is not None
                                                                          else "to be fixed in the ITT")}
                       for n, p in sorted(params.items())],
        "groups": ordered,
        "tables": sorted(profile.tables.items()),
        "classes": sorted(profile.classes.items()),
        "waivers": list(profile.waivers),
        "consequences": CONSEQUENCES, "levels": LEVELS,
        "n_rules": len(profile.rules), "n_manual": sum(r.manual for r in profile.rules),
        "title": f"Technical specification annex — {profile.title}",
    }


def annex_filename(profile: ResolvedProfile, fmt: str) -> str:
    return f"annex-{profile.id}-{profile.version}.{fmt}"


def _md_cell(v: Any) -> str:
    """A Markdown table cell: pipes escaped, newlines folded (profile text stays text)."""
    text = "" if v is None else str(v)
    text = text.replace("\\", "\\\\").replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")
    return " ".join(text.split())


def _md_text(v: Any) -> str:
    text = "" if v is None else str(v)
    return " ".join(text.replace("<", "&lt;").replace(">", "&gt;").split())


def render_annex(profile: ResolvedProfile, *, formats: Iterable[str] = ANNEX_FORMATS,
                 day: str | None = None) -> dict[str, str | bytes]:
    """Render the annex in memory: ``{"annex-<id>-<version>.md": ..., ...}``."""
    fmts = list(dict.fromkeys(formats))
    bad = [f for f in fmts if f not in ANNEX_FORMATS]
    if bad:
        raise ReportError(f"unknown annex format(s) {', '.join(bad)}; choose from {', '.join(ANNEX_FORMATS)}")
    day = day or Date.today().isoformat()
    ctx = annex_context(profile, day=day)
    out: dict[str, str | bytes] = {}
    if "md" in fmts:
        env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(templates_dir())), autoescape=False,
                                 undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                                 keep_trailing_newline=True)
        env.filters.update(cell=_md_cell, text=_md_text, num=_num)
        out[annex_filename(profile, "md")] = env.get_template("annex.md.j2").render(**ctx)
    if "html" in fmts or "pdf" in fmts:
        env = environment()
        env.filters["num"] = _num
        if "html" in fmts:
            out[annex_filename(profile, "html")] = env.get_template("annex.html.j2").render(**ctx, pdf=False)
        if "pdf" in fmts:
            from .fetcher import SafeFetcher
            from .pdf import FileAttachment, write_pdf

            fetcher = SafeFetcher(templates_dir())
            html = env.get_template("annex.html.j2").render(**ctx, pdf=True)
            canonical = profile.canonical_json().encode("utf-8")
            files = [FileAttachment(f"{profile.id}-{profile.version}.json", canonical,
                                    f"Resolved profile {profile.id} {profile.version} (SHA-256 {profile.sha256})",
                                    relationship="Source")]
            out[annex_filename(profile, "pdf")] = write_pdf(html, fetcher=fetcher, day=day,
                                                            identifier=profile.sha256, attachments=files)
    return out
