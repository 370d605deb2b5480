"""The technical-specification annex of an invitation to tender (ITT), rendered from a profile.

The annex is what bidders read: every parameter the tender fixes (value, unit, description), then
every requirement grouped as the source document groups them (section, or table), with the
clause, the quoted text, the level and the consequence of failing it. Markdown, HTML and PDF/A-3b
(with the resolved profile JSON attached, so the annex and the checker share one source).
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import date as Date
from pathlib import Path
from typing import Any

import jinja2
from markupsafe import Markup, escape

from ..errors import ExpressionError, ReportError
from ..present import NO_UNIT, fmt_value
from ..profile.applicability import cannot_apply
from ..profile.expr import parse
from ..profile.loader import ResolvedProfile
from ..profile.models import Parameter, Requirement, Rule
from ..profile.wording import param_value, profile_requirement_text
from ..qcr import natural_key
from ..resources import templates_dir
from .findings import condition_prose
from .html import environment

__all__ = ["ANNEX_FORMATS", "annex_context", "annex_filename", "default_out_dir", "render_annex"]

ANNEX_FORMATS = ("md", "html", "pdf")
CONSEQUENCES = {
    "reject_item": "the item (image, point, ...) is rejected",
    "reject_block": "all products of the block are rejected",
    "return_delivery": "the whole delivery is returned to the contractor",
    "incomplete": "the check is incomplete until the checker completes it (e.g. more check points); "
    "the contractor's products are not rejected for it",
    "warn": "recorded as a warning; not a ground for rejection by itself",
}
LEVELS = {
    "mandatory": 'must be met ("shall", "must", "will")',
    "recommended": "should be met; failing it is reported as a warning",
}


def _num(v: Any) -> str:
    """A number or word in a table cell (template filter), printed as the requirement prints it.
    The templates print a value the ITT has not fixed yet as a dash (with "to be fixed in the ITT"
    beside it), not as a missing measurement."""
    return fmt_value(v) if isinstance(v, bool | float) else str(v)


def _evaluate(source: str, values: dict[str, Any]) -> Any:
    """An expression over the parameters' values (``tolerance_xy / gcp_accuracy_factor``), or None
    when it names anything else or cannot be computed: the annex then prints it as written."""
    try:
        e = parse(source)
        if not e.names or not e.names <= values.keys() or any(values[n] is None for n in e.names):
            return None
        return e.evaluate({n: values[n] for n in e.names})
    except (ExpressionError, ArithmeticError, TypeError, ValueError):
        return None


def _words(source: str) -> str:
    """A threshold the annex cannot compute, in words (manifest facts as prose)."""
    return condition_prose(source) if "manifest." in source else source


def requirement_text(req: Requirement, params: dict[str, Parameter]) -> str:
    """'≤ 0.166667 m': the requirement as the QCR words it (``spec.wording``), with the thresholds
    the profile's parameters fix, expressions evaluated over them."""
    units = {params[n].unit for n in params if n in _names(req)} - NO_UNIT - {None}
    evaluate = _evaluate if units <= {req.unit} else None  # a unit change is the checker's to make
    return profile_requirement_text(req, params, evaluate=evaluate, words=_words)


def _names(req: Requirement) -> set[str]:
    out: set[str] = set()
    for v in (req.value, req.min, req.max):
        if isinstance(v, str):
            with contextlib.suppress(ExpressionError):
                out |= set(parse(v).names)
    return out


def plain_note(note: str | None) -> str:
    """A public note in plain words for bidders: markup removed, data names in words.

    Rule notes are written in two parts: ``note`` (public: printed here and by ``explain``) and
    ``internal_note`` (for the profile's maintainers, never printed). Nothing is filtered out of a
    public note: a sentence that says what a rule measures or what failing it does reaches the
    bidders whole (tests/test_annex_public.py keeps internal vocabulary out of every shipped annex).
    """
    if not note:
        return ""
    text = re.sub(r"\*\*(.+?)\*\*", r"\1", " ".join(note.split()))
    text = re.sub(r"(?<![\w*])\*(\S.*?\S|\S)\*(?![\w*])", r"\1", text)
    text = text.replace("`", "").replace("**", "")
    text = re.sub(r"\bTrap:\s*", "Caution: ", text)
    text = re.sub(r"\bmanifest\.[\w.]*\w", lambda m: condition_prose(m.group(0)), text)
    text = re.sub(r"\bmanifest\.", "manifest file.", text)
    return text.strip()


def _title(rule: Rule, requirement: str, tender_params: set[str]) -> str:
    """The rule title, its range in parentheses replaced by the resolved value when the ITT fixed it
    (a title '(5-10 %)' under a tender's 5 % would contradict the requirement)."""
    title = rule.title
    req = rule.requirement
    used = {v for v in (req.value, req.min, req.max) if isinstance(v, str)}
    names: set[str] = set()
    for u in used:
        with contextlib.suppress(ExpressionError):
            names |= set(parse(u).names)
    if names & tender_params:
        if re.search(r"\([^()]*\d[^()]*\)\s*$", title):
            title = re.sub(r"\s*\([^()]*\d[^()]*\)\s*$", "", title) + f" ({requirement})"
        elif re.search(r"\d", title):
            title += f" (this ITT: {requirement})"
    return title


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


def _rule_view(
    rule: Rule,
    params: dict[str, Parameter],
    tender_params: set[str] | None = None,
    change: str = "",
) -> dict[str, Any]:
    req = requirement_text(rule.requirement, params)
    return {
        "id": rule.id,
        "title": _title(rule, req, tender_params or set()),
        "clause": rule.clause.text(),
        "quote": _plain_markup(rule.quote),
        "quote_html": _html_markup(rule.quote),
        "scope": rule.scope,
        "when": rule.when,
        "when_prose": condition_prose(rule.when) if rule.when else "",
        "requirement": req,
        "measure": rule.measure,
        "level": rule.level,
        "consequence": rule.consequence,
        "consequence_text": CONSEQUENCES.get(rule.consequence, rule.consequence),
        "manual": rule.manual,
        "note": plain_note(rule.note),
        "audit": rule.audit.model_dump(exclude_none=True) if rule.audit else {},
        "tags": list(rule.tags),
        "change": change,
        "sort": (
            natural_key(str(rule.clause.section or "")),
            natural_key(str(rule.clause.row or "")),
            rule.id,
        ),
    }


def _plain_markup(text: str | None) -> str:
    """Source emphasis (**bold**, *italic*) as plain text."""
    t = re.sub(r"\*\*(.+?)\*\*", r"\1", text or "")
    return re.sub(r"(?<![\w*])\*(\S(?:.*?\S)?)\*(?![\w*])", r"\1", t).replace("**", "")


def _html_markup(text: str | None) -> Markup:
    """Source emphasis rendered: **bold** -> <b>, *italic* -> <i>; everything else escaped."""
    t = str(escape(text or ""))
    t = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", t)
    t = re.sub(r"(?<![\w*])\*(\S(?:.*?\S)?)\*(?![\w*])", r"<i>\1</i>", t).replace("**", "")
    return Markup(t)


SENSOR_TYPES = ("aerial", "satellite")


def tender_sensor(profile: ResolvedProfile) -> tuple[set[str], bool | None]:
    """The sensor types and digital/film the tender requires, from its own mandatory rules on the
    delivery's sensor that apply unconditionally (``in [satellite]``, ``== satellite``,
    ``!= aerial``; ``sensor.digital`` true or false)."""
    types: set[str] | None = None
    digital: bool | None = None
    for r in profile.rules:
        if r.level != "mandatory" or r.when or r.manual:
            continue
        req = r.requirement
        if r.measure == "manifest.sensor.type":
            allowed: set[str] | None = None
            if req.op == "in":
                allowed = {str(v) for v in req.values or []}
            elif req.op == "==" and isinstance(req.value, str):
                allowed = {req.value}
            elif req.op == "!=" and isinstance(req.value, str):
                allowed = set(SENSOR_TYPES) - {req.value}
            if allowed is not None:
                types = allowed if types is None else types & allowed
        if r.measure == "manifest.sensor.digital":
            if req.op in ("true", "false"):
                digital = req.op == "true"
            elif req.op in ("==", "!=") and isinstance(req.value, bool):
                digital = req.value if req.op == "==" else not req.value
    return types or set(), digital


def _parent(profile: ResolvedProfile) -> ResolvedProfile | None:
    """The profile this one extends, resolved (to mark what the ITT added, changed or removed)."""
    if len(profile.chain) < 2:
        return None
    from ..profile.loader import load_profile

    # the parent was resolved to load this profile: an error here is real and reaches the user
    return load_profile(profile.chain[1][2], check_measures=False)


def _changed_keys(a: Rule, b: Rule) -> list[str]:
    da, db = a.model_dump(mode="json"), b.model_dump(mode="json")
    return sorted(k for k in set(da) | set(db) if da.get(k) != db.get(k) and k not in ("override",))


def annex_context(
    profile: ResolvedProfile, *, day: str, sensor: str | None = None
) -> dict[str, Any]:
    """Everything the annex templates show, from the resolved profile."""
    params = dict(profile.parameters)
    parent = _parent(profile)
    base_rules = {r.id: r for r in parent.rules} if parent is not None else {}
    base_params = dict(parent.parameters) if parent is not None else {}
    tender_params = {
        n
        for n, p in params.items()
        if parent is not None
        and (n not in base_params or param_value(base_params[n]) != param_value(p))
    }
    sensors, digital = tender_sensor(profile)
    if sensor:
        sensors = {sensor}
    if sensors == {"satellite"} and digital is None:
        digital = True  # satellite sensors are digital: film-camera rules cannot apply
    groups: dict[tuple[Any, ...], Group] = {}
    members: dict[tuple[Any, ...], list[Rule]] = {}
    excluded: list[dict[str, Any]] = []
    changes: list[dict[str, Any]] = []
    notes: list[dict[str, Any]] = []
    for rule in profile.rules:
        why = cannot_apply(rule, sensors, digital)
        if why is not None:
            excluded.append(
                {"id": rule.id, "title": rule.title, "clause": rule.clause.text(), "why": why}
            )
            continue
        change = ""
        if parent is not None:
            if rule.id not in base_rules:
                change = "added by the ITT"
            else:
                keys = _changed_keys(base_rules[rule.id], rule)
                if keys:
                    change = (
                        "changed by the ITT (" + ", ".join(k.replace("_", " ") for k in keys) + ")"
                    )
        view = _rule_view(rule, params, tender_params, change)
        if change:
            changes.append(
                {
                    "id": rule.id,
                    "title": view["title"],
                    "change": change,
                    "requirement": view["requirement"],
                    "level": rule.level,
                    "consequence": rule.consequence,
                }
            )
        if view["note"]:
            notes.append({"id": rule.id, "note": view["note"]})
        key, title = _group_of(rule)
        groups.setdefault(key, Group(key, title)).rules.append(view)
        members.setdefault(key, []).append(rule)
    removed = []
    if parent is not None:
        ids = {r.id for r in profile.rules}
        just = {
            str(getattr(x, "id", x)): getattr(x, "justification", None)
            for x in getattr(profile, "removed", ()) or ()
        }
        removed = [
            {
                "id": rid,
                "title": r.title,
                "clause": r.clause.text(),
                "justification": just.get(rid) or "no justification recorded in the profile",
            }
            for rid, r in base_rules.items()
            if rid not in ids
        ]
    ordered = sorted(groups.values(), key=lambda g: _group_order(g, members[g.key]))
    for g in ordered:
        g.rules.sort(key=lambda r: r["sort"])
    body = [r for rules in members.values() for r in rules]
    body_ids = {r.id for r in body}
    unset = _unset_itt(params, body, [r for r in profile.rules if r.id not in body_ids])
    weakened = [
        {**w.to_dict(), "changes_text": "; ".join(w.changes)}
        for w in getattr(profile, "weakened", ())
    ]
    sensor_unstated = (
        parent is not None
        and not sensors
        and any(cannot_apply(r, {t}, None) is not None for r in profile.rules for t in SENSOR_TYPES)
    )
    src = profile.source
    n_rules = sum(len(g.rules) for g in ordered)
    return {
        "profile": profile,
        "day": day,
        "source": src,
        "parameters": [
            {
                "name": n,
                "value": param_value(p),
                "unit": p.unit or "",
                "required": p.required,
                "description": plain_note(p.description) or p.description,
                "choices": p.choices,
                "changed": n in tender_params,
                "justification": getattr(p, "justification", None),
                "fixed_by": "tender"
                if p.value is not None
                else ("standard" if p.default is not None else "to be fixed in the ITT"),
            }
            for n, p in sorted(params.items())
        ],
        "groups": ordered,
        "tables": sorted(profile.tables.items()),
        "classes": sorted(profile.classes.items()),
        "waivers": list(profile.waivers),
        "consequences": CONSEQUENCES,
        "levels": LEVELS,
        "n_rules": n_rules,
        "n_manual": sum(r["manual"] for g in ordered for r in g.rules),
        "excluded": excluded,
        "changes": changes,
        "removed": removed,
        "notes": notes,
        "sensors": sorted(sensors),
        "digital": digital,
        "parent": parent,
        "unset": unset,
        "weakened": weakened,
        "sensor_unstated": sensor_unstated,
        "title": f"Technical specification annex — {profile.title}",
    }


def _unset_itt(
    params: dict[str, Parameter], rules: list[Rule], others: list[Rule]
) -> list[dict[str, Any]]:
    """Parameters left to the ITT that have no value and that the annex's requirements use: the ITT
    must fix them before the call for tender is published (page 1 warns).

    A requirement uses a parameter when its threshold or condition reads it, or when its notes name
    it (a measure may read a parameter, e.g. the Table 9 master-image rules read ``master_images``).
    A parameter only the requirements of another sensor use (``others``) is not the tender's to fix.
    """

    def users(rs: list[Rule], name: str) -> list[str]:
        word = re.compile(rf"\b{re.escape(name)}\b")
        out = []
        for r in rs:
            names: set[str] = set(_names(r.requirement))
            if r.when:
                with contextlib.suppress(ExpressionError):
                    names |= set(parse(r.when).names)
            if (
                name in names
                or f"param.{name}" in names
                or any(word.search(t) for t in (r.note or "", r.internal_note or ""))
            ):
                out.append(r.id)
        return out

    out = []
    for name, p in sorted(params.items()):
        if param_value(p) is not None or p.authority() != "itt":
            continue
        ids = users(rules, name)
        if not ids and users(others, name):
            continue  # only requirements that cannot apply to this tender use it
        shown = ", ".join(ids[:6]) + (f" and {len(ids) - 6} more" if len(ids) > 6 else "")
        unit = p.unit if p.unit and p.unit not in NO_UNIT else ""
        out.append(
            {
                "name": name,
                "unit": unit,
                "readers": f"used by {shown}" if ids else "used by no requirement of this annex",
            }
        )
    return out


def human(name: Any) -> str:
    """snake_case column name -> 'Snake case' header."""
    text = str(name).replace("_", " ").strip()
    return text[:1].upper() + text[1:]


#: where `spec render` writes without --out, relative to the folder chosen by :func:`default_out_dir`
DEFAULT_OUT = Path("reports") / "annex"


def _is_orthospec_checkout(d: Path) -> bool:
    if not (d / ".git").exists():
        return False
    try:
        head = (d / "pyproject.toml").read_text(encoding="utf-8", errors="replace")[:4096]
    except OSError:
        return False
    return re.search(r'(?m)^name\s*=\s*"orthospec"', head) is not None


def _is_delivery(d: Path) -> bool:
    try:
        with (d / "delivery.yaml").open("rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return False
    return re.search(r"(?m)^orthospec_delivery\s*:", head) is not None


def default_out_dir(cwd: Path | None = None) -> Path:
    """Where `spec render` writes without ``--out``: ``reports/annex/`` under the current folder,
    or under the root of the orthospec checkout the current folder is in (its ``reports/`` is
    ignored by git), never the current folder itself. Inside a delivery it raises ReportError
    (orthospec never writes into a delivery): the user gives ``--out``."""
    here = (cwd or Path.cwd()).resolve()
    for d in (here, *here.parents):
        if _is_delivery(d):
            raise ReportError(
                f"the current folder is inside the delivery {str(d)!r}; orthospec never writes "
                "into a delivery: give --out DIR outside it"
            )
    for d in (here, *here.parents):
        if _is_orthospec_checkout(d):
            return d / DEFAULT_OUT
    return here / DEFAULT_OUT


def annex_filename(profile: ResolvedProfile, fmt: str) -> str:
    return f"annex-{profile.id}-{profile.version}.{fmt}"


def _md_cell(v: Any) -> str:
    """A Markdown table cell: pipes escaped, newlines folded (profile text stays text)."""
    text = "" if v is None else str(v)
    text = text.replace("\\", "\\\\").replace("|", "\\|")
    text = re.sub(r"<(?=[A-Za-z/!?])", "&lt;", text)
    return " ".join(text.split())


def _md_text(v: Any) -> str:
    """Markdown text: an angle bracket that could open a tag is escaped ('<80 km' stays as written)."""
    text = "" if v is None else str(v)
    text = re.sub(r"<(?=[A-Za-z/!?])", "&lt;", text)
    return " ".join(text.split())


def render_annex(
    profile: ResolvedProfile,
    *,
    formats: Iterable[str] = ANNEX_FORMATS,
    day: str | None = None,
    sensor: str | None = None,
) -> dict[str, str | bytes]:
    """Render the annex in memory: ``{"annex-<id>-<version>.md": ..., ...}``."""
    fmts = list(dict.fromkeys(formats))
    bad = [f for f in fmts if f not in ANNEX_FORMATS]
    if bad:
        raise ReportError(
            f"unknown annex format(s) {', '.join(bad)}; choose from {', '.join(ANNEX_FORMATS)}"
        )
    day = day or Date.today().isoformat()
    ctx = annex_context(profile, day=day, sensor=sensor)
    out: dict[str, str | bytes] = {}
    if "md" in fmts:
        env = jinja2.Environment(
            loader=jinja2.FileSystemLoader(str(templates_dir())),
            autoescape=False,
            undefined=jinja2.StrictUndefined,
            trim_blocks=True,
            lstrip_blocks=True,
            keep_trailing_newline=True,
        )
        env.filters.update(cell=_md_cell, text=_md_text, num=_num, human=human)
        out[annex_filename(profile, "md")] = env.get_template("annex.md.j2").render(**ctx)
    if "html" in fmts or "pdf" in fmts:
        env = environment()
        env.filters["num"] = _num
        env.filters["human"] = human
        if "html" in fmts:
            out[annex_filename(profile, "html")] = env.get_template("annex.html.j2").render(
                **ctx, pdf=False
            )
        if "pdf" in fmts:
            from .fetcher import SafeFetcher
            from .pdf import FileAttachment, write_pdf

            fetcher = SafeFetcher(templates_dir())
            html = env.get_template("annex.html.j2").render(**ctx, pdf=True)
            canonical = profile.canonical_json().encode("utf-8")
            files = [
                FileAttachment(
                    f"{profile.id}-{profile.version}.json",
                    canonical,
                    f"Resolved profile {profile.id} {profile.version} (SHA-256 {profile.sha256})",
                    relationship="Source",
                )
            ]
            out[annex_filename(profile, "pdf")] = write_pdf(
                html, fetcher=fetcher, day=day, identifier=profile.sha256, attachments=files
            )
    return out
