"""``extends``: a profile merged onto the resolved profile it builds on. Parameters keep the
authority and unit of the profile that defines them; a standard's value, a mandatory rule removed
or an override that checks less needs a justification; the canonical form and its SHA-256 are
what every QCR cites."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ..errors import UnitError
from ..yamlio import Located
from .changes import Weakening, weakened_fields, weakening_changes
from .models import Parameter, Profile, Rule, RuleOverride
from .problems import Problem, _did_you_mean, _rule_at
from .resolved import Removal, ResolvedProfile, _Sites, canonical_dumps


def _check_unique_ids(prof: Profile, doc: Located, problems: list[Problem]) -> None:
    seen: dict[str, int] = {}
    for i, r in enumerate(prof.rules):
        if r.id in seen:
            line, col = doc.where(("rules", i, "id"))
            problems.append(Problem(doc.file, line, col, f"duplicate rule id {r.id!r} "
                                    f"(first at rules/{seen[r.id]})", r.id))
        else:
            seen[r.id] = i


def _effective(p: Parameter) -> Any:
    return p.value if p.value is not None else p.default


def _same_value(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return float(a) == float(b)
    return a == b


def _unjustified(rule_id: str, changes: list[str], base: ResolvedProfile | None, how: str) -> str:
    """One message for a mandatory rule of the base weakened without a justification."""
    where = f"{base.id} {base.version}" if base is not None else "the base profile"
    listed = "`spec diff`, the annex and every report checked under this profile list the change"
    if how == "remove":
        return (
            f"remove_rules: {rule_id} is a mandatory rule of {where}; removing it needs a justification: "
            f'write `{{id: {rule_id}, justification: "ITT §...: why it does not apply"}}` ({listed})'
        )
    what = "; ".join(changes)
    if how == "restate":
        return (
            f"rule {rule_id} is mandatory in {where}, and this profile writes it again so that it checks less "
            f"({what}): write only the keys that change under `override: true`, with `justification: "
            f'"ITT §...: why"` ({listed})'
        )
    return (
        f"rule {rule_id} is mandatory in {where}, and this override makes it check less ({what}) without a "
        f'justification: add `justification: "ITT §...: why"` to the override ({listed})'
    )


def _unit_change(name: str, old: Parameter, new: Parameter, base: ResolvedProfile | None) -> str:
    """One message for an extending profile that gives an inherited parameter another unit.

    The parameter keeps the unit of the profile that defines it (every rule reading it, the annex
    and the QCR print that unit); without this the mistake surfaced as one dimension error per rule
    reading the parameter, some of them located in the standard's own file."""
    from ..units import profile_unit_problem

    where = f"{base.id} {base.version}" if base is not None else "the profile that defines it"
    spelled = profile_unit_problem(new.unit)
    if spelled and f"write {old.unit!r}" in spelled:
        return f"parameter {name}: {spelled}"
    head = f"parameter {name}: unit {new.unit!r}, but {name} is in {old.unit!r} in {where}"
    value = new.value if new.value is not None else None
    if (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and old.unit not in (None, "text", "bool", "date")
    ):
        try:
            from ..units import convert

            got = float(convert([float(value)], new.unit, old.unit)[0])
            return (
                f"{head}: a tender gives the value in the parameter's unit: write `value: {got:g}` "
                f"({value:g} {new.unit}) and leave out `unit`"
            )
        except (UnitError, ValueError, TypeError):
            pass
    return (
        f"{head} (another kind of quantity): a tender gives the value in {old.unit!r} and leaves out "
        f"`unit`"
    )


def _merge(
    prof: Profile, base: ResolvedProfile | None, path: Path, doc: Located, problems: list[Problem]
) -> ResolvedProfile | None:
    """``prof`` (the file ``doc``) merged onto ``base``: its parameters, its removals, its rules
    and overrides, each problem appended (in that order); None when there is any."""
    sites = _Sites(top=doc)
    if base is not None and base.sites is not None:
        sites.rules = {k: list(v) for k, v in base.sites.rules.items()}
        sites.params = {k: list(v) for k, v in base.sites.params.items()}
    params = _merge_parameters(prof, base, doc, sites, problems)
    m = _Rules(
        dict((r.id, r) for r in base.rules) if base else {},
        list(base.removed) if base else [],
        list(base.weakened) if base else [],
        {k: tuple(v) for k, v in base.overridden.items()} if base else {},
    )
    _remove_rules(prof, base, doc, sites, m, problems)
    _merge_rules(prof, base, doc, sites, m, problems)
    if problems:
        return None
    return _resolved(prof, base, path, doc, params, m, sites, problems)


@dataclass
class _Rules:
    """The rules of a profile being merged, and what the chain removed, weakened and overrode."""

    rules: dict[str, Rule]
    removed: list[Removal]
    weakened: list[Weakening]
    overridden: dict[str, tuple[str, ...]]


def _merge_parameters(
    prof: Profile,
    base: ResolvedProfile | None,
    doc: Located,
    sites: _Sites,
    problems: list[Problem],
) -> dict[str, Parameter]:
    """The base's parameters with this profile's added or changed (authority and unit kept)."""
    params = dict(base.parameters) if base else {}
    sites.inherited_params = set(params)
    for name, p in prof.parameters.items():
        sites.params.setdefault(name, []).append(doc)
        if name not in params:
            if p.unit is None:
                line, col = doc.where(("parameters", name))
                problems.append(
                    Problem(
                        doc.file,
                        line,
                        col,
                        f"parameter {name}: a new parameter needs a unit"
                        + _did_you_mean(name, sites.inherited_params, "inherited"),
                    )
                )
                continue
            params[name] = p.model_copy(update={"set_by": p.authority()})
            sites.own_params.add(name)
            continue
        old = params[name]
        given = p.model_dump(exclude_unset=True)
        if "set_by" in given and given["set_by"] != old.authority():
            line, col = doc.where(("parameters", name, "set_by"))
            problems.append(
                Problem(
                    doc.file,
                    line,
                    col,
                    f"parameter {name}: set_by is {old.authority()!r} where "
                    "the parameter is defined; an extending profile cannot change it",
                )
            )
            continue
        if "unit" in given and old.unit is not None and given["unit"] != old.unit:
            line, col = doc.where(("parameters", name, "unit"))
            problems.append(Problem(doc.file, line, col, _unit_change(name, old, p, base)))
            continue
        if "default" in given and not _same_value(given["default"], old.default):
            line, col = doc.where(("parameters", name, "default"))
            problems.append(
                Problem(
                    doc.file,
                    line,
                    col,
                    f"parameter {name}: an extending profile sets `value:`, "
                    "not `default:` (the default is the value of the profile that defines it)",
                )
            )
            continue
        merged = old.model_dump()
        merged.update(given)
        merged["set_by"] = old.authority()
        if "justification" not in given:
            merged["justification"] = None
        new = Parameter.model_validate(merged)
        if (
            old.authority() == "standard"
            and base is not None
            and not _same_value(_effective(new), _effective(old))
            and not p.justification
        ):
            key = "value" if "value" in given else ("default" if "default" in given else None)
            line, col = doc.where(("parameters", name, *((key,) if key else ())))
            problems.append(
                Problem(
                    doc.file,
                    line,
                    col,
                    f"parameter {name}: {_effective(old)!r} is the standard's value ({base.id} {base.version}); "
                    f"a tender profile that changes it to {_effective(new)!r} must say why: add "
                    f'`justification: "ITT §...: ..."` to the parameter (the report annex prints it)',
                )
            )
        params[name] = new
    return params


def _remove_rules(
    prof: Profile,
    base: ResolvedProfile | None,
    doc: Located,
    sites: _Sites,
    m: _Rules,
    problems: list[Problem],
) -> None:
    """``remove_rules``: an inherited rule taken out (a mandatory one only with a justification)."""
    for i, item in enumerate(prof.remove_rules):
        rid = item if isinstance(item, str) else item.id
        if rid not in m.rules:
            line, col = doc.where(("remove_rules", i))
            problems.append(
                Problem(
                    doc.file,
                    line,
                    col,
                    f"remove_rules: no inherited rule {rid!r}"
                    + _did_you_mean(rid, m.rules, "inherited"),
                )
            )
            continue
        justification = None if isinstance(item, str) else item.justification
        if m.rules[rid].level == "mandatory":
            if justification is None:
                line, col = doc.where(("remove_rules", i))
                problems.append(
                    Problem(doc.file, line, col, _unjustified(rid, ["removed"], base, "remove"))
                )
                continue
            m.weakened.append(
                Weakening(rid, ("removed",), justification, prof.id, m.rules[rid].title)
            )
        del m.rules[rid]
        sites.rules.pop(rid, None)
        m.overridden.pop(rid, None)
        m.removed.append(Removal(rid, justification, prof.id))


def _merge_rules(
    prof: Profile,
    base: ResolvedProfile | None,
    doc: Located,
    sites: _Sites,
    m: _Rules,
    problems: list[Problem],
) -> None:
    """This profile's rules: new ones, inherited ones written again, and overrides (one that
    checks less only with a justification)."""
    for i, r in enumerate(prof.rules):
        before = m.rules.get(r.id)
        if isinstance(r, RuleOverride):
            if before is None:
                line, col = doc.where(("rules", i))
                problems.append(
                    Problem(
                        doc.file,
                        line,
                        col,
                        f"override of unknown rule {r.id!r}"
                        + _did_you_mean(r.id, m.rules, "inherited"),
                        r.id,
                    )
                )
                continue
            merged_r = before.model_dump()
            changed = {
                k: v
                for k, v in r.model_dump(exclude_unset=True).items()
                if k not in ("override", "id", "justification")
            }
            merged_r.update(changed)
            try:
                after = Rule.model_validate(merged_r)
            except ValidationError as exc:
                line, col = doc.where(("rules", i))
                problems.append(
                    Problem(
                        doc.file, line, col, f"override invalid: {exc.errors()[0]['msg']}", r.id
                    )
                )
                continue
            weak = weakening_changes(before, after)
            if weak and not r.justification:
                key = weakened_fields(before, after)[0]
                line, col = doc.where(("rules", i, key))
                problems.append(
                    Problem(doc.file, line, col, _unjustified(r.id, weak, base, "override"), r.id)
                )
                continue
            if weak:
                m.weakened.append(
                    Weakening(r.id, tuple(weak), r.justification, prof.id, after.title)
                )
            m.overridden[r.id] = tuple(sorted({*m.overridden.get(r.id, ()), *changed}))
            m.rules[r.id] = after
            sites.rules.setdefault(r.id, []).append((doc, i))
        else:
            weak = weakening_changes(before, r) if before is not None else []
            if (
                weak
            ):  # an inherited rule written again in full, checking less: say how to do it openly
                key = weakened_fields(before, r)[0] if before is not None else "id"
                line, col = doc.where(("rules", i, key))
                problems.append(
                    Problem(doc.file, line, col, _unjustified(r.id, weak, base, "restate"), r.id)
                )
                continue
            m.rules[r.id] = r
            sites.rules[r.id] = [(doc, i)]
            m.overridden.pop(r.id, None)


def _resolved(
    prof: Profile,
    base: ResolvedProfile | None,
    path: Path,
    doc: Located,
    params: dict[str, Parameter],
    m: _Rules,
    sites: _Sites,
    problems: list[Problem],
) -> ResolvedProfile | None:
    """The resolved profile: its canonical form and SHA-256 (None, with the place of a value that
    is not a finite number, when it cannot be hashed)."""
    tables = {**(base.tables if base else {}), **prof.tables}
    classes = {**(base.classes if base else {}), **prof.classes}
    final_rules = tuple(m.rules.values())
    chain = ((prof.id, prof.version, str(path)), *(base.chain if base else ()))
    waivers = (*(base.waivers if base else ()), *prof.waivers)
    canonical: dict[str, Any] = {
        "id": prof.id,
        "version": prof.version,
        "title": prof.title,
        "source": prof.source.model_dump(mode="json"),
        "extends": [{"id": c[0], "version": c[1]} for c in chain[1:]],
        "parameters": {k: _param_json(v) for k, v in sorted(params.items())},
        "tables": {
            k: (v.model_dump(mode="json") if hasattr(v, "model_dump") else v)
            for k, v in sorted(tables.items())
        },
        "classes": {
            k: (v.model_dump(mode="json") if hasattr(v, "model_dump") else v)
            for k, v in sorted(classes.items())
        },
        "rules": [_rule_json(r) for r in final_rules],
        "waivers": [w.model_dump(mode="json") for w in waivers],
    }
    if prof.allow_no_mandatory:
        canonical["allow_no_mandatory"] = True
    if m.removed:
        canonical["removed_rules"] = [
            {"id": x.id, "justification": x.justification, "profile": x.profile} for x in m.removed
        ]
    if m.weakened:
        canonical["weakened_rules"] = [w.to_dict() for w in m.weakened]
    try:
        sha = hashlib.sha256(canonical_dumps(canonical).encode("utf-8")).hexdigest()
    except ValueError:  # nan or inf somewhere: say where (only on this failure path)
        for where in _nonfinite(doc.data, ()):
            line, col = doc.where(where)
            problems.append(
                Problem(
                    doc.file,
                    line,
                    col,
                    f"{'/'.join(map(str, where))}: not a finite number "
                    "(write a number such as 1.0)",
                    _rule_at(doc, where),
                )
            )
        if not problems:
            problems.append(
                Problem(
                    doc.file, None, None, "the profile holds a value that is not a finite number"
                )
            )
        return None
    return ResolvedProfile(
        id=prof.id,
        version=prof.version,
        title=prof.title,
        description=prof.description,
        source=prof.source,
        parameters=params,
        tables=tables,
        classes=classes,
        rules=final_rules,
        tests=tuple(prof.tests),
        waivers=waivers,
        path=path,
        chain=chain,
        canonical=canonical,
        sha256=sha,
        allow_no_mandatory=prof.allow_no_mandatory,
        sites=sites,
        removed=tuple(m.removed),
        overridden=m.overridden,
        weakened=tuple(m.weakened),
    )


#: keys added to the models after profiles were published: written into the canonical form only when
#: set, so a profile that does not use them keeps its SHA-256
_NEW_KEYS = {"checker_may_set": False, "internal_note": None}


def _rule_json(r: Rule) -> dict[str, Any]:
    d = r.model_dump(mode="json", exclude={"override"})
    if d.get("internal_note") is None:
        d.pop("internal_note", None)
    return d


def _param_json(p: Parameter) -> dict[str, Any]:
    d = p.model_dump(mode="json")
    for k, default in _NEW_KEYS.items():
        if k in d and d[k] == default:
            del d[k]
    return d


def _nonfinite(obj: Any, path: tuple[Any, ...]) -> list[tuple[Any, ...]]:
    if isinstance(obj, float) and (obj != obj or obj in (float("inf"), float("-inf"))):
        return [path]
    if isinstance(obj, dict):
        return [w for k, v in obj.items() for w in _nonfinite(v, (*path, k))]
    if isinstance(obj, list):
        return [w for i, v in enumerate(obj) for w in _nonfinite(v, (*path, i))]
    return []
