"""The checker folder's skeleton (`orthospec checker init`, issue 29 item 4): what the checker must fill.

A trial auditor generated 36 verdict rows by hand from qcr.csv for a 3-scene delivery. The skeleton
lists, for a delivery and a profile, what the external QC owes: the ITT parameters the profile leaves
open (commented out: a value the checker has not stated must stop a check, never be guessed), every
manual check item the profile applies to this delivery - with, for an item that is a delivered
file, the file and its SHA-256 written by the tool (the verdict is bound to the content judged) -
and the pins of every table, document, vector and area of interest the delivery uses, with their
roles. Verdicts are left empty (`verdict: null`): an entry still to be judged is ``missing``.

The text is YAML with comments, written by hand so that it reads as a form; it loads with
delivery/checker.py once the checker's name is filled in.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..delivery.checker import CHECKER_FILE, CHECKPOINTS_TABLE, INSPECTION_GRID, file_roles
from ..delivery.manifest import QuantityIn
from ..delivery.reader import Delivery
from ..profile.loader import ResolvedProfile
from ..units import NON_NUMERIC, canonical
from .applicability import applicable
from .context import Context
from .manual import item_files
from .params import ParamValue


@dataclass
class Skeleton:
    """What the skeleton holds, for the caller's summary and for tests."""

    text: str
    entries: list[dict[str, Any]] = field(default_factory=list)
    open_parameters: list[str] = field(default_factory=list)
    pins: dict[str, dict[str, str]] = field(default_factory=dict)


def _q(value: Any) -> str:
    """A YAML scalar (JSON is YAML): quoted text, plain numbers, null."""
    return json.dumps(value, ensure_ascii=False)


def _params(profile: ResolvedProfile) -> dict[str, ParamValue]:
    """The parameters as far as the profile itself fixes them (no checker, no --param): enough to decide
    which manual rules apply; an open ITT value is None."""
    out = {}
    for name, p in profile.parameters.items():
        unit = p.unit if p.unit in NON_NUMERIC else canonical(p.unit or "1")
        value = p.value if p.value is not None else p.default
        out[name] = ParamValue(name, value, unit, "tender" if p.value is not None else "standard")
    return out


def manual_items(profile: ResolvedProfile, d: Delivery) -> list[dict[str, Any]]:
    """Every manual check item the profile applies to ``d``: check, item, scope, and for an item that is a
    delivered file its file and SHA-256; an item whose applicability the delivery does not decide is
    listed with ``when`` (the checker judges whether it applies)."""
    ctx = Context.build(
        profile, d, _params(profile), fail_on="fail", options=None, checker=None, debug=False
    )
    out: list[dict[str, Any]] = []
    for rule in profile.rules:
        if not rule.manual:
            continue
        listed, _ = ctx.universe(rule.scope)
        items = listed if listed else [d.id]
        ok, unknown, _ = applicable(ctx, rule, items)
        files = item_files(ctx, rule.scope)
        one = rule.scope in ("delivery", "project")
        for item, yes, unk in zip(items, ok.tolist(), np.asarray(unknown).tolist(), strict=True):
            if not yes and not unk:
                continue
            entry: dict[str, Any] = {
                "check": rule.id,
                "item": "*" if one else str(item),
                "scope": rule.scope,
                "title": rule.title,
                "level": rule.level,
            }
            rel = files.get(str(item))
            sha = ctx.file_sha256(rel) if rel is not None else None
            if sha is not None:
                entry.update(file=rel, sha256=sha)
            if unk:
                entry["when"] = rule.when
            out.append(entry)
    return out


def checker_skeleton(profile: ResolvedProfile, d: Delivery, *, name: str | None = None) -> Skeleton:
    """The checker.yaml skeleton of ``d`` under ``profile`` (see the module docstring)."""
    from ..inspection.defects import catalogue

    entries = manual_items(profile, d)
    grid_rules = set(catalogue().rules)
    roles = file_roles(d, tables=False)
    pins = {
        rel: {"sha256": d.sha256(rel), "role": role}
        for role, rel in sorted(roles.items())
        if d.path(rel, what=role).is_file()
    }
    declared = dict(d.manifest.tender.parameters) if d.manifest.tender else {}
    lines = [
        "# The checker folder's checker.yaml (docs/CHECKER.md), written by `orthospec checker init`.",
        f"# Delivery {d.id}, profile {profile.id} {profile.version}. Fill in: your name, the ITT values,",
        "# a verdict (pass / fail) and date for each manual check; measure the check points into",
        f"# {CHECKPOINTS_TABLE} (orthospec measure checkpoints) and mark the inspection grid",
        f"# {INSPECTION_GRID} (orthospec inspect grid). Keep this folder outside the delivery.",
        "orthospec_checker: 1",
        f"checker: {{name: {_q(name or '')}, role: external QC}}   # name: who checks (required)",
        "delivery:",
        f"  id: {_q(d.id)}",
        "  # what the checker received: a file changed, or re-pointed by the manifest or a table, is refused",
        "  files:" + ("" if pins else " {}"),
    ]
    lines += [
        f"    {_q(rel)}: {{sha256: {p['sha256']}, role: {_q(p['role'])}}}"
        for rel, p in sorted(pins.items())
    ]
    open_params = []
    lines += [
        "# the ITT values in force (JRC §2.5): uncomment and fill in; one left commented out stops a check",
        "# that needs it (never guessed from the delivery's declaration)",
        "parameters:",
    ]
    body = []
    for pname, p in sorted(profile.parameters.items()):
        if p.authority() != "itt" or p.value is not None:
            continue
        open_params.append(pname)
        unit = p.unit or "1"
        said = declared.get(pname)
        hint = (
            f"; the delivery declares {said.value:g} {said.unit} (evidence only)"
            if isinstance(said, QuantityIn)
            else ""
        )
        if pname == "map_crs" and d.manifest.project.crs:
            hint = f"; the delivery declares project.crs {d.manifest.project.crs} (evidence only)"
        need = "required" if p.required else "optional"
        desc = " ".join((p.description or "").split())
        # the first sentence only ("e.g." and "i.e." end none)
        desc = re.split(r"(?<!\be\.g)(?<!\bi\.e)(?<=[a-z0-9)])\. (?=[A-Z])", desc)[0].rstrip(".")
        if unit in NON_NUMERIC:
            default = f", default {p.default}" if p.default is not None else ""
            body.append(
                f"  # {pname}: {_q(p.default) if p.default is not None else ''}   # {need}{default}: {desc}{hint}"
            )
        else:
            default = (
                f", default {p.default:g} {unit}" if isinstance(p.default, int | float) else ""
            )
            body.append(
                f"  # {pname}: {{value: , unit: {_q(unit)}}}   # {need}{default}: {desc}{hint}"
            )
    lines += body
    lines += [
        "# block outlines / area of interest in force (map_crs), when the checker states them:",
        "# blocks: [{id: B01, polygon: [[x, y], ...]}]",
        "# area_of_interest: [[x, y], ...]",
        "manual_checks:" + ("" if entries else " []"),
    ]
    for e in entries:
        lines.append(f"  - check: {_q(e['check'])}   # {e['title']} ({e['level']}, {e['scope']})")
        lines.append(f"    item: {_q(e['item'])}")
        if "file" in e:
            lines.append(f"    file: {_q(e['file'])}")
            lines.append(f"    sha256: {e['sha256']}")
        if "when" in e:
            lines.append(
                f"    # applies when {e['when']} (the delivery does not say): judge whether it does"
            )
        if e["check"] in grid_rules and e["scope"] == "image":
            lines.append(
                f"    # or mark the image's cells on {INSPECTION_GRID} (it answers this rule) and leave this null"
            )
        lines += [
            "    verdict: null   # pass | fail",
            "    date: null   # YYYY-MM-DD",
            "    note: null",
        ]
    lines += ["waivers: []", ""]
    text = "\n".join(lines)
    return Skeleton(text, entries, open_params, pins)


__all__ = ["CHECKER_FILE", "Skeleton", "checker_skeleton", "manual_items"]
