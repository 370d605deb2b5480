"""Load, validate and resolve spec profiles (``extends``, overrides, removals, checksum).

Validation runs in three passes and reports *every* problem with ``file:line:column``:
the published JSON Schema (what editors see), the pydantic models, then semantic checks
(unique ids, units, expressions, known measures, scope of each measure).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import jsonschema
from pydantic import ValidationError

from ..errors import ExpressionError, SpecError, UnitError
from ..resources import specs_dir
from ..units import NON_NUMERIC, parse_unit
from . import expr
from .models import Parameter, Profile, Rule, RuleOverride
from .yamlio import Located, YamlError, load_file

MAX_EXTENDS_DEPTH = 8


@dataclass(frozen=True)
class Problem:
    file: str
    line: int | None
    column: int | None
    message: str
    rule: str | None = None

    def __str__(self) -> str:
        where = self.file
        if self.line is not None:
            where += f":{self.line}" + (f":{self.column}" if self.column is not None else "")
        who = f" (rule {self.rule})" if self.rule else ""
        return f"{where}: {self.message}{who}"


@dataclass(frozen=True)
class ResolvedProfile:
    """A profile with ``extends`` applied: what the evaluator runs and every QCR cites."""

    id: str
    version: str
    title: str
    description: str | None
    source: Any
    parameters: dict[str, Parameter]
    tables: dict[str, Any]
    classes: dict[str, Any]
    rules: tuple[Rule, ...]
    tests: tuple[Any, ...]
    waivers: tuple[Any, ...]
    path: Path
    chain: tuple[tuple[str, str, str], ...]  # (id, version, file) from this profile to its root
    canonical: dict[str, Any] = field(repr=False)
    sha256: str = ""

    def rule(self, rule_id: str) -> Rule:
        for r in self.rules:
            if r.id == rule_id:
                return r
        raise KeyError(rule_id)

    def canonical_json(self) -> str:
        return canonical_dumps(self.canonical)


def canonical_dumps(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


@lru_cache(maxsize=1)
def _schema() -> dict[str, Any]:
    return json.loads((specs_dir() / "schema" / "profile.schema.json").read_text(encoding="utf-8"))


def schema_problems(doc: Located) -> list[Problem]:
    validator = jsonschema.Draft202012Validator(_schema())
    out = []
    for err in sorted(validator.iter_errors(doc.data), key=lambda e: [str(p) for p in e.absolute_path]):
        while err.context:  # anyOf/oneOf: report the most specific branch, where the mistake is
            err = jsonschema.exceptions.best_match(err.context)
        path = tuple(err.absolute_path)
        line, col = doc.where(path)
        loc = "/".join(str(p) for p in path) or "(document)"
        out.append(Problem(doc.file, line, col, f"{loc}: {_short(err.message)}", _rule_at(doc, path)))
    return out


def _short(msg: str) -> str:
    return msg if len(msg) < 300 else msg[:297] + "..."


def _rule_at(doc: Located, path: tuple[Any, ...]) -> str | None:
    if len(path) >= 2 and path[0] == "rules" and isinstance(path[1], int):
        try:
            rid = doc.data["rules"][path[1]].get("id")
            return str(rid) if rid else None
        except (KeyError, IndexError, AttributeError, TypeError):
            return None
    return None


def parse_profile(doc: Located) -> tuple[Profile | None, list[Problem]]:
    """Schema + pydantic validation of one file (no extends resolution)."""
    if not isinstance(doc.data, dict):
        return None, [Problem(doc.file, 1, 1, "a profile must be a YAML mapping")]
    if "orthospec_profile" not in doc.data:
        return None, [Problem(doc.file, 1, 1, "not an orthospec spec profile (it has no "
                              "'orthospec_profile: 1' key)")]
    problems = schema_problems(doc)
    try:
        prof = Profile.model_validate(doc.data)
    except ValidationError as exc:
        for e in exc.errors():
            path = tuple(p for p in e["loc"] if not (isinstance(p, str) and p in ("rule", "override")))
            line, col = doc.where(path)
            loc = "/".join(str(p) for p in path)
            problems.append(Problem(doc.file, line, col, f"{loc}: {e['msg']}", _rule_at(doc, path)))
        return None, _dedupe(problems)
    return prof, _dedupe(problems)


def _dedupe(problems: list[Problem]) -> list[Problem]:
    seen: set[tuple[Any, ...]] = set()
    out = []
    for p in problems:
        key = (p.file, p.line, p.column)
        if key in seen:
            continue
        seen.add(key)
        out.append(p)
    return out


# --- finding profiles ---------------------------------------------------------------------

def profile_files(extra: list[Path] | None = None) -> list[Path]:
    dirs = [specs_dir(), *(extra or [])]
    files: list[Path] = []
    for d in dirs:
        if d.is_dir():
            files.extend(sorted(p for p in d.glob("*.yaml") if _looks_like_profile(p)))
    return files


def _looks_like_profile(path: Path) -> bool:
    try:
        with open(path, encoding="utf-8") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    return "orthospec_profile:" in head


def _header(path: Path) -> tuple[str, str, str] | None:
    try:
        doc = load_file(path)
    except YamlError:
        return None
    d = doc.data if isinstance(doc.data, dict) else {}
    if "id" not in d:
        return None
    return str(d.get("id")), str(d.get("version", "")), str(d.get("title", ""))


def available(extra: list[Path] | None = None) -> list[tuple[str, str, str, Path]]:
    """Shipped (and extra) profiles as (id, version, title, path)."""
    out = []
    for p in profile_files(extra):
        h = _header(p)
        if h:
            out.append((*h, p))
    return sorted(out, key=lambda t: (t[0], t[1]))


def find_profile(ref: str | Path, *, near: Path | None = None, version: str | None = None) -> Path:
    """A path to a profile given a file path or an id (optionally pinned to a version)."""
    p = Path(ref)
    if p.suffix in (".yaml", ".yml") or p.exists():
        if not p.is_file():
            raise SpecError(f"profile file {str(ref)!r} not found")
        return p
    extra = [near] if near else []
    matches = [t for t in available(extra) if t[0] == str(ref) and (version is None or t[1] == version)]
    if not matches:
        import difflib

        have = available(extra)
        known = ", ".join(f"{i} {v}" for i, v, _, _ in have) or "none"
        pin = f" version {version}" if version else ""
        near = difflib.get_close_matches(str(ref), [i for i, _, _, _ in have], n=1, cutoff=0.6)
        hint = f"; did you mean {near[0]!r}?" if near and not version else ""
        raise SpecError(f"unknown profile {str(ref)!r}{pin}{hint}; available: {known}")
    return matches[-1][3]


# --- resolution ---------------------------------------------------------------------------

def load_profile(ref: str | Path, *, check_measures: bool = True) -> ResolvedProfile:
    """Load a profile by id or path, resolve ``extends``, validate, and checksum it."""
    path = find_profile(ref)
    problems: list[Problem] = []
    resolved = _resolve(path, problems, depth=0, seen=())
    if resolved is not None and not problems:
        problems.extend(semantic_problems(resolved, check_measures=check_measures))
    if problems:
        raise SpecError(_format(problems))
    assert resolved is not None
    return resolved


def validate_file(path: str | Path, *, check_measures: bool = True) -> list[Problem]:
    """Every problem of a profile file (and what it extends), without raising."""
    problems: list[Problem] = []
    try:
        resolved = _resolve(find_profile(path), problems, depth=0, seen=())
    except SpecError as exc:
        return [*problems, Problem(str(path), None, None, str(exc))]
    if resolved is not None and not problems:
        problems.extend(semantic_problems(resolved, check_measures=check_measures))
    return problems


def _format(problems: list[Problem]) -> str:
    head = f"{len(problems)} problem(s) in profile:" if len(problems) > 1 else "invalid profile:"
    lines = [str(p) for p in problems[:50]]
    if len(problems) > 50:
        lines.append(f"... and {len(problems) - 50} more")
    return head + "\n  " + "\n  ".join(lines)


def _resolve(path: Path, problems: list[Problem], *, depth: int,
             seen: tuple[str, ...]) -> ResolvedProfile | None:
    try:
        doc = load_file(path)
    except YamlError as exc:
        problems.append(Problem(str(path), None, None, str(exc).split(": ", 1)[-1]))
        return None
    prof, probs = parse_profile(doc)
    problems.extend(probs)
    if prof is None or probs:
        return None
    key = f"{prof.id}@{prof.version}"
    if key in seen:
        problems.append(Problem(doc.file, *doc.where(("extends",)), f"extends cycle: {' -> '.join((*seen, key))}"))
        return None
    _check_unique_ids(prof, doc, problems)
    base: ResolvedProfile | None = None
    if prof.extends is not None:
        if depth >= MAX_EXTENDS_DEPTH:
            problems.append(Problem(doc.file, *doc.where(("extends",)), "extends chain too deep"))
            return None
        try:
            parent_path = find_profile(prof.extends.id, near=path.parent, version=prof.extends.version)
        except SpecError as exc:
            problems.append(Problem(doc.file, *doc.where(("extends",)), str(exc)))
            return None
        base = _resolve(parent_path, problems, depth=depth + 1, seen=(*seen, key))
        if base is None:
            return None
    return _merge(prof, base, path, doc, problems)


def _check_unique_ids(prof: Profile, doc: Located, problems: list[Problem]) -> None:
    seen: dict[str, int] = {}
    for i, r in enumerate(prof.rules):
        if r.id in seen:
            line, col = doc.where(("rules", i, "id"))
            problems.append(Problem(doc.file, line, col, f"duplicate rule id {r.id!r} "
                                    f"(first at rules/{seen[r.id]})", r.id))
        else:
            seen[r.id] = i


def _merge(prof: Profile, base: ResolvedProfile | None, path: Path, doc: Located,
           problems: list[Problem]) -> ResolvedProfile | None:
    params = dict(base.parameters) if base else {}
    for name, p in prof.parameters.items():
        if name not in params and p.unit is None:
            line, col = doc.where(("parameters", name))
            problems.append(Problem(doc.file, line, col, f"parameter {name}: a new parameter needs a unit"))
            continue
        if name in params:
            merged = params[name].model_dump()
            merged.update(p.model_dump(exclude_unset=True))
            params[name] = Parameter.model_validate(merged)
        else:
            params[name] = p
    tables = {**(base.tables if base else {}), **prof.tables}
    classes = {**(base.classes if base else {}), **prof.classes}
    rules: dict[str, Rule] = {r.id: r for r in base.rules} if base else {}
    order = list(rules)
    for i, rid in enumerate(prof.remove_rules):
        if rid not in rules:
            line, col = doc.where(("remove_rules", i))
            problems.append(Problem(doc.file, line, col, f"remove_rules: no inherited rule {rid!r}"))
            continue
        del rules[rid]
        order.remove(rid)
    for i, r in enumerate(prof.rules):
        if isinstance(r, RuleOverride):
            if r.id not in rules:
                line, col = doc.where(("rules", i))
                problems.append(Problem(doc.file, line, col, f"override of unknown rule {r.id!r}", r.id))
                continue
            merged = rules[r.id].model_dump()
            merged.update({k: v for k, v in r.model_dump(exclude_unset=True).items() if k != "override"})
            try:
                rules[r.id] = Rule.model_validate(merged)
            except ValidationError as exc:
                line, col = doc.where(("rules", i))
                problems.append(Problem(doc.file, line, col, f"override invalid: {exc.errors()[0]['msg']}", r.id))
        else:
            if r.id not in rules:
                order.append(r.id)
            rules[r.id] = r
    if problems:
        return None
    final_rules = tuple(rules[rid] for rid in order if rid in rules)
    chain = ((prof.id, prof.version, str(path)), *(base.chain if base else ()))
    canonical = {
        "id": prof.id,
        "version": prof.version,
        "title": prof.title,
        "source": prof.source.model_dump(mode="json"),
        "extends": [{"id": c[0], "version": c[1]} for c in chain[1:]],
        "parameters": {k: v.model_dump(mode="json") for k, v in sorted(params.items())},
        "tables": {k: (v.model_dump(mode="json") if hasattr(v, "model_dump") else v)
                   for k, v in sorted(tables.items())},
        "classes": {k: (v.model_dump(mode="json") if hasattr(v, "model_dump") else v)
                    for k, v in sorted(classes.items())},
        "rules": [r.model_dump(mode="json", exclude={"override"}) for r in final_rules],
        "waivers": [w.model_dump(mode="json") for w in (*(base.waivers if base else ()), *prof.waivers)],
    }
    sha = hashlib.sha256(canonical_dumps(canonical).encode("utf-8")).hexdigest()
    return ResolvedProfile(
        id=prof.id, version=prof.version, title=prof.title, description=prof.description,
        source=prof.source, parameters=params, tables=tables, classes=classes, rules=final_rules,
        tests=tuple(prof.tests), waivers=(*(base.waivers if base else ()), *prof.waivers), path=path, chain=chain, canonical=canonical, sha256=sha,
    )


def semantic_problems(p: ResolvedProfile, *, check_measures: bool = True) -> list[Problem]:
    """Units parse, expressions are in the grammar and name known things, measures exist."""
    from ..engine.registry import measure_info  # late: the engine imports spec

    out: list[Problem] = []
    docs = {str(c[2]): None for c in p.chain}
    locs = _rule_locations(p)

    def add(rule: Rule | None, key: tuple[Any, ...], msg: str) -> None:
        file, line, col = locs.get((rule.id if rule else None, key[:1]), (str(p.path), None, None))
        out.append(Problem(file, line, col, msg, rule.id if rule else None))

    for name, par in p.parameters.items():
        if par.unit is not None and par.unit not in NON_NUMERIC:
            try:
                parse_unit(par.unit)
            except UnitError as exc:
                out.append(Problem(str(p.path), None, None, f"parameter {name}: {exc}"))
    for cname, cset in p.classes.items():
        try:
            parse_unit(cset.unit)
        except UnitError as exc:
            out.append(Problem(str(p.path), None, None, f"class set {cname}: {exc}"))
    for r in p.rules:
        info = None
        if r.manual or r.measure.startswith("manual."):
            if not r.measure.startswith("manual."):
                add(r, ("measure",), f"a manual rule reads measure 'manual.{r.id}', not {r.measure!r}")
        elif check_measures:
            info = measure_info(r.measure)
            if info is None:
                add(r, ("measure",), f"unknown measure {r.measure!r}{_near_measure(r.measure)} "
                    "(see `orthospec measures`)")
            elif info[0] != r.scope and not r.measure.startswith("manifest."):
                add(r, ("scope",), f"measure {r.measure!r} is at scope {info[0]!r}, rule says {r.scope!r}")
        req = r.requirement
        if req.unit is not None and req.unit not in NON_NUMERIC:
            try:
                parse_unit(req.unit)
            except UnitError as exc:
                add(r, ("requirement",), str(exc))
        if req.op == "between" and (req.min is None and req.max is None):
            add(r, ("requirement",), "op 'between' needs min and/or max")
        if req.op == "in" and not req.values:
            add(r, ("requirement",), "op 'in' needs values")
        if req.op in ("<", "<=", ">", ">=", "==", "!=") and req.value is None:
            add(r, ("requirement",), f"op {req.op!r} needs a value")
        known = set(p.parameters) | {f"class.{c}" for c in p.classes}
        for text in (r.when, *(v for v in (req.value, req.min, req.max) if isinstance(v, str))):
            if not isinstance(text, str) or (text is not r.when and req.op in ("==", "!=", "in")
                                             and not _looks_like_expr(text, known)):
                continue
            try:
                e = expr.parse(text)
            except ExpressionError as exc:
                add(r, ("when",) if text is r.when else ("requirement",), str(exc))
                continue
            for n in e.names:
                if n in known or n.startswith("manifest.") or n.startswith("param."):
                    continue
                if not check_measures or measure_info(n) is not None:
                    continue
                add(r, ("when",) if text is r.when else ("requirement",),
                    f"expression {text!r} names {n!r}, which is neither a parameter nor a measure")
    del docs
    return out


def _near_measure(name: str) -> str:
    import difflib

    from ..delivery.convention import table_specs
    from ..engine.registry import ROLLUP, known_measures

    names = [*known_measures(), *ROLLUP]
    for t, spec in table_specs().items():
        names += [f"{t}.{c}" for c in spec.columns] + [f"{t}.present", f"{t}.count"]
    near = difflib.get_close_matches(name, names, n=1, cutoff=0.8)
    return f"; did you mean {near[0]!r}?" if near else ""


def _looks_like_expr(text: str, known: set[str]) -> bool:
    try:
        e = expr.parse(text)
    except ExpressionError:
        return False
    return bool(e.names & known)


def _rule_locations(p: ResolvedProfile) -> dict[tuple[Any, ...], tuple[str, int | None, int | None]]:
    out: dict[tuple[Any, ...], tuple[str, int | None, int | None]] = {}
    for _, _, file in reversed(p.chain):
        try:
            doc = load_file(file)
        except YamlError:
            continue
        for i, r in enumerate((doc.data or {}).get("rules", []) or []):
            if not isinstance(r, dict):
                continue
            for key in ("measure", "scope", "requirement", "when", "id"):
                line, col = doc.where(("rules", i, key))
                out[(r.get("id"), (key,))] = (file, line, col)
    return out
