"""Semantic checks of a resolved profile, beyond its models: units and their dimensions,
threshold numbers, expressions, manifest paths the delivery schema defines, known measures and
their scope, parameters nobody reads, a profile with no mandatory rule; and the profile's own
``tests:``. Linear in the number of rules."""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, get_origin

from pydantic import BaseModel

from ..errors import ExpressionError, UnitError
from .models import Rule
from .problems import Problem, _did_you_mean, _unwrap
from .resolved import ResolvedProfile, _Sites

if TYPE_CHECKING:
    from . import expr

_ORDER_OPS = ("<", "<=", ">", ">=", "between")


@lru_cache(maxsize=1)
def manifest_paths() -> tuple[frozenset[str], tuple[str, ...]]:
    """Paths the delivery manifest model defines, and prefixes under which any key is allowed.

    Derived by walking ``delivery.manifest.Manifest`` (dict-typed fields such as
    ``tender.parameters`` or ``documents`` accept any sub-key), so a rule's ``when`` can only read
    facts a delivery can state in the published schema.
    """
    from ..delivery.manifest import Manifest

    exact: set[str] = set()
    open_: list[str] = []

    def walk(model: type[BaseModel], prefix: str, depth: int) -> None:
        for name, f in model.model_fields.items():
            path = f"{prefix}{name}"
            exact.add(path)
            t = _unwrap(f.annotation)
            if isinstance(t, type) and issubclass(t, BaseModel) and depth < 6:
                walk(t, path + ".", depth + 1)
            elif get_origin(t) is dict or t is dict:
                open_.append(path + ".")

    walk(Manifest, "", 0)
    return frozenset(exact), tuple(sorted(open_))


def manifest_path_problem(name: str) -> str | None:
    """Why ``manifest.<path>`` is not a path the delivery schema defines (None when it is)."""
    path = name[len("manifest."):]
    exact, open_ = manifest_paths()
    if path in exact or any(path.startswith(p) and len(path) > len(p) for p in open_):
        return None
    cands = sorted(exact | {p + "<key>" for p in open_})
    parent = path.rsplit(".", 1)[0] if "." in path else ""
    children = sorted(c[len(parent) + 1:] for c in exact if parent and c.startswith(parent + ".")
                      and "." not in c[len(parent) + 1:])
    near = difflib.get_close_matches(path, cands, n=1, cutoff=0.6)
    if children:
        near_child = difflib.get_close_matches(path.rsplit(".", 1)[1], children, n=1, cutoff=0.6)
        hint = (f"; did you mean 'manifest.{parent}.{near_child[0]}'?" if near_child else
                f"; manifest.{parent} has {', '.join(children)}")
    else:
        hint = f"; did you mean 'manifest.{near[0]}'?" if near else ""
    return (
        f"{name!r} is not a key the delivery manifest defines (specs/schema/delivery.schema.json): "
        f"a rule may read only what a delivery can state in its schema{hint}"
    )


def _parse(text: str) -> expr.Expression:
    from . import expr  # numpy: only when a profile is validated, not when served from the cache

    return expr.parse(text)


def semantic_problems(p: ResolvedProfile, *, check_measures: bool = True) -> list[Problem]:
    """Units, threshold numbers, expressions, manifest paths, measures, parameters: linear in rules."""
    from .catalog import measure_info

    out: list[Problem] = []
    sites = p.sites or _Sites()

    def add(rule: Rule | None, key: tuple[Any, ...], msg: str) -> None:
        if rule is None:
            out.append(Problem(str(p.path), None, None, msg))
            return
        file, line, col = sites.rule_where(rule.id, key)
        out.append(Problem(file, line, col, msg, rule.id))

    def add_param(name: str, key: str | None, msg: str) -> None:
        file, line, col = sites.param_where(name, key)
        out.append(Problem(file, line, col, msg))

    numeric_units = _parameter_problems(p, add_param)
    _class_problems(p, out)
    checks = _RuleChecks(
        p,
        set(p.parameters) | {f"class.{c}" for c in p.classes},
        check_measures,
        measure_info,
        add,
        numeric_units,
        out,
        sites,
    )
    read_params: set[str] = set()
    mandatory = 0
    for r in p.rules:
        if r.level == "mandatory":
            mandatory += 1
        read_params |= _rule_problems(r, checks)
    # a parameter an extending profile adds but no rule reads is almost always a misspelling
    for name in sorted(sites.own_params - read_params):
        if not sites.inherited_params:
            break
        near = difflib.get_close_matches(name, sorted(sites.inherited_params), n=1, cutoff=0.6)
        hint = (
            (
                f"; did you mean {near[0]!r} (inherited)? As written, the inherited {near[0]} keeps its "
                "value"
            )
            if near
            else ""
        )
        add_param(name, None, f"parameter {name} is defined here but no rule reads it{hint}")
    if mandatory == 0 and not p.allow_no_mandatory:
        top = sites.top
        out.append(
            Problem(
                top.file if top else str(p.path),
                1 if top else None,
                1 if top else None,
                f"profile {p.id} has no mandatory rule, so it would accept every delivery; "
                "add one, or say so explicitly with `allow_no_mandatory: true`",
            )
        )
    return out


def _parameter_problems(p: ResolvedProfile, add_param: Any) -> dict[str, str]:
    """Units, choices, map projections and numbers of the parameters; the numeric ones' units."""
    from ..units import NON_NUMERIC, number_problem, profile_unit_problem
    from ..units import check_unit as parse_unit  # the usual spellings without loading pint

    numeric_units: dict[str, str] = {}
    for name, par in p.parameters.items():
        unit = par.unit
        spelled = profile_unit_problem(unit)
        if spelled:
            add_param(name, "unit", f"parameter {name}: {spelled}")
            continue
        for key in ("value", "default"):
            v = getattr(par, key)
            if v is not None and par.choices is not None and v not in par.choices:
                add_param(
                    name,
                    key,
                    f"parameter {name}: {key} {v!r} is not one of "
                    f"{', '.join(map(str, par.choices))}"
                    + _did_you_mean(str(v), map(str, par.choices)),
                )
            elif isinstance(v, str) and unit == "text" and name.endswith("_crs"):
                why = _crs_problem(v)
                if why:
                    add_param(name, key, f"parameter {name}: {why}")
        if unit is None or unit in NON_NUMERIC:
            continue
        try:
            parse_unit(unit)
        except UnitError as exc:
            add_param(name, "unit", f"parameter {name}: {exc}")
            continue
        numeric_units[name] = unit
        for key in ("value", "default"):
            v = getattr(par, key)
            if v is not None:
                why = number_problem(v)
                if why:
                    add_param(name, key, f"parameter {name}: {key}: {why}")
        for i, c in enumerate(par.choices or []):
            why = number_problem(c)
            if why:
                add_param(name, "choices", f"parameter {name}: choices[{i}]: {why}")
    return numeric_units


def _class_problems(p: ResolvedProfile, out: list[Problem]) -> None:
    """Each class set's unit is a unit."""
    from ..units import check_unit as parse_unit
    from ..units import profile_unit_problem

    for cname, cset in p.classes.items():
        try:
            why = profile_unit_problem(cset.unit)
            if why:
                raise UnitError(why)
            parse_unit(cset.unit)
        except UnitError as exc:
            out.append(Problem(str(p.path), None, None, f"class set {cname}: {exc}"))


@dataclass
class _RuleChecks:
    """What checking one rule needs of the profile, and the memos shared by every rule."""

    p: ResolvedProfile
    known: set[str]
    check_measures: bool
    measure_info: Any
    add: Any
    numeric_units: dict[str, str]
    out: list[Problem]
    sites: _Sites
    manifest_checked: dict[str, str | None] = field(default_factory=dict)
    unit_ok: dict[tuple[str, str], str | None] = field(default_factory=dict)

    def manifest_names(self, rule: Rule, key: tuple[str, ...], names: Any) -> None:
        for n in names:
            if n.startswith("manifest."):
                if n not in self.manifest_checked:
                    self.manifest_checked[n] = manifest_path_problem(n)
                if self.manifest_checked[n]:
                    self.add(rule, key, str(self.manifest_checked[n]))


def _rule_problems(r: Rule, c: _RuleChecks) -> set[str]:
    """One rule's measure, requirement and condition; the parameters it reads."""
    from ..units import NON_NUMERIC, profile_unit_problem
    from ..units import check_unit as parse_unit

    add = c.add
    if r.manual or r.measure.startswith("manual."):
        if not r.measure.startswith("manual."):
            add(r, ("measure",), f"a manual rule reads measure 'manual.{r.id}', not {r.measure!r}")
    elif r.measure.startswith("manifest."):
        c.manifest_names(r, ("measure",), (r.measure,))
    elif c.check_measures:
        info = c.measure_info(r.measure)
        if info is None:
            add(
                r,
                ("measure",),
                f"unknown measure {r.measure!r}{_near_measure(r.measure)} "
                "(see `orthospec measures`)",
            )
        elif info[0] != r.scope:  # located at the measure: an override that swaps it is the cause
            add(
                r,
                ("measure",),
                f"measure {r.measure!r} is at scope {info[0]!r}, rule says {r.scope!r}",
            )
    req = r.requirement
    req_numeric = req.unit is not None and req.unit not in NON_NUMERIC and req.unit != "any"
    if req_numeric:
        try:
            why = profile_unit_problem(req.unit)
            if why:
                raise UnitError(why)
            parse_unit(req.unit)
        except UnitError as exc:
            add(r, ("requirement", "unit"), str(exc))
            req_numeric = False
    if req.op == "between" and (req.min is None and req.max is None):
        add(r, ("requirement",), "op 'between' needs min and/or max")
    if req.op == "in" and not req.values:
        add(r, ("requirement",), "op 'in' needs values")
    if req.op in ("<", "<=", ">", ">=", "==", "!=") and req.value is None:
        add(r, ("requirement",), f"op {req.op!r} needs a value")
    read: set[str] = set()
    if r.when:
        try:
            e = _parse(r.when)
        except ExpressionError as exc:
            add(r, ("when",), str(exc) + _single_equals(r.when))
        else:
            if not e.names:
                add(r, ("when",), _constant_when(e, r.when))
            _check_names(r, ("when",), e, c.known, c.check_measures, c.measure_info, add)
            c.manifest_names(r, ("when",), e.names)
            read |= params_named(e.names, c.p.parameters)
    return read | _threshold_problems(r, c, req_numeric)


def _threshold_problems(r: Rule, c: _RuleChecks, req_numeric: bool) -> set[str]:
    """A rule's threshold values (numbers, or expressions over parameters whose units must meet
    the requirement's); the parameters they read."""
    from ..units import number_problem

    req, add = r.requirement, c.add
    read: set[str] = set()
    numeric_threshold = req_numeric or req.op in _ORDER_OPS
    for key in ("value", "min", "max"):
        v = getattr(req, key)
        if v is None:
            continue
        if not isinstance(v, str):
            if numeric_threshold:
                why = number_problem(v)
                if why:
                    add(r, ("requirement", key), f"requirement {key}: {why}")
            continue
        if numeric_threshold:
            why = number_problem(v)
            if why and "is not a number" not in why:
                add(r, ("requirement", key), f"requirement {key}: {why}")
                continue
        elif req.op in ("==", "!=", "in") and not _looks_like_expr(v, c.known):
            continue
        try:
            e = _parse(v)
        except ExpressionError as exc:
            hint = (
                " (a threshold is a number such as 1.0, or an expression over parameters)"
                if numeric_threshold
                else ""
            )
            add(r, ("requirement", key), f"{exc}{hint}{_single_equals(v)}")
            continue
        _check_names(r, ("requirement", key), e, c.known, c.check_measures, c.measure_info, add)
        c.manifest_names(r, ("requirement", key), e.names)
        used = params_named(e.names, c.p.parameters)
        read |= used
        if req_numeric and used and req.unit is not None:
            _check_dimensions(
                r, key, v, e, used, c.numeric_units, req.unit, c.unit_ok, c.out, c.sites
            )
    return read


def _crs_problem(text: str) -> str | None:
    """Why a map projection value cannot be used (pyproj cannot read it, or it has no EPSG code)."""
    from ..delivery.crs import CrsProblem, epsg_name

    try:
        epsg_name(text)
    except CrsProblem as exc:
        return str(exc)
    return None


_VERDICTS_EXPECTED = ("accepted", "rejected", "incomplete")


def _test_problems(p: ResolvedProfile, sites: _Sites, *, paths: bool = True) -> list[Problem]:
    """The profile's own `tests:`: every delivery folder and checker file exists (relative to the
    profile file), every parameter and rule named exists, every verdict is one a check gives. Found
    here with a line, not later by `orthospec verify`."""
    from ..verdicts import VERDICTS

    top = sites.top
    out: list[Problem] = []

    def add(i: int, key: tuple[Any, ...], msg: str) -> None:
        line, col = top.where(("tests", i, *key)) if top is not None else (None, None)
        out.append(
            Problem(top.file if top is not None else str(p.path), line, col, f"tests[{i}]: {msg}")
        )

    here = p.path.parent
    rule_ids = {r.id for r in p.rules}
    for i, t in enumerate(p.tests):
        folder = here / t.delivery
        if not paths:
            pass
        elif not folder.is_dir():
            add(
                i,
                ("delivery",),
                f"delivery folder {t.delivery!r} not found (paths are relative to the profile "
                f"file's folder {str(here)!r}){_near_path(folder)}",
            )
        elif not (folder / "delivery.yaml").is_file():
            add(i, ("delivery",), f"{t.delivery!r} is not a delivery (it has no delivery.yaml)")
        checker = here / t.checker if t.checker is not None else None
        if (
            paths
            and checker is not None
            and not (checker.is_file() or (checker / "checker.yaml").is_file())
        ):
            add(
                i,
                ("checker",),
                f"checker file or folder {t.checker!r} not found (relative to the profile file's folder)"
                + _near_path(checker),
            )
        for name, given in t.params.items():
            par = p.parameters.get(name)
            if par is None:
                add(
                    i,
                    ("params", name),
                    f"params: profile {p.id} has no parameter {name!r}"
                    + _did_you_mean(name, p.parameters),
                )
                continue
            own = par.value if par.value is not None else par.default
            if (
                len(p.chain) > 1
                and not par.checker_may_set
                and own is not None
                and isinstance(given, int | float)
                and isinstance(own, int | float)
                and not isinstance(given, bool)
                and float(given) != float(own)
            ):
                add(
                    i,
                    ("params", name),
                    f"params: {name} = {given} differs from {own}, the value this tender "
                    "fixes; the check would stop (the contract wins): leave it out, or mark the parameter "
                    "`checker_may_set: true`",
                )
        extra = sorted(set(t.expect) - {"verdict", "rules"})
        if extra:
            add(
                i,
                ("expect", extra[0]),
                f"expect: unknown key {extra[0]!r}; expect holds verdict and rules",
            )
        verdict = t.expect.get("verdict")
        if verdict is not None and verdict not in _VERDICTS_EXPECTED:
            add(
                i,
                ("expect", "verdict"),
                f"expect: verdict {verdict!r} is not one of {', '.join(_VERDICTS_EXPECTED)}"
                + _did_you_mean(str(verdict), _VERDICTS_EXPECTED),
            )
        rules = t.expect.get("rules") or {}
        if not isinstance(rules, dict):
            add(
                i,
                ("expect", "rules"),
                "expect: rules maps a rule id to the verdict expected, e.g. {JRC-12.7-RMSEX: pass}",
            )
            continue
        for rid, want in rules.items():
            if rid not in rule_ids:
                add(
                    i,
                    ("expect", "rules", rid),
                    f"expect: profile {p.id} has no rule {rid!r}"
                    + _did_you_mean(str(rid), rule_ids),
                )
            elif want not in VERDICTS:
                add(
                    i,
                    ("expect", "rules", rid),
                    f"expect: {rid}: verdict {want!r} is not one of "
                    f"{', '.join(VERDICTS)}" + _did_you_mean(str(want), VERDICTS),
                )
    return out


def _near_path(path: Path) -> str:
    """`; did you mean '../x'?` for a missing path whose name exists in a nearby folder."""
    parent = path.parent
    for _ in range(4):
        if parent.is_dir():
            break
        parent = parent.parent
    else:
        return ""
    try:
        names = [x.name for x in parent.iterdir()][:500]
    except OSError:
        return ""
    near = difflib.get_close_matches(path.name, names, n=1, cutoff=0.8)
    return (
        f"; {str(parent / near[0])!r} exists"
        if near and parent != path.parent
        else (f"; did you mean {near[0]!r}?" if near and near[0] != path.name else "")
    )


def params_named(names: Any, params: Mapping[str, Any]) -> set[str]:
    """The parameters an expression's names refer to (``NAME`` or ``param.NAME``)."""
    out = set()
    for n in names:
        n2 = n[6:] if n.startswith("param.") else n
        if n2 in params:
            out.add(n2)
    return out


def _check_names(
    rule: Rule,
    key: tuple[str, ...],
    e: expr.Expression,
    known: set[str],
    check_measures: bool,
    measure_info: Any,
    add: Any,
) -> None:
    for n in e.names:
        if n in known or n.startswith("manifest.") or n.startswith("param."):
            continue
        if not check_measures or measure_info(n) is not None:
            continue
        add(
            rule,
            key,
            f"expression {e.source!r} names {n!r}, which is neither a parameter nor a measure"
            + _did_you_mean(n, known, "parameter"),
        )


def _check_dimensions(
    r: Rule,
    key: str,
    text: str,
    e: expr.Expression,
    used: set[str],
    numeric_units: dict[str, str],
    req_unit: str,
    memo: dict[tuple[str, str], str | None],
    out: list[Problem],
    sites: _Sites,
) -> None:
    """The unit an expression over parameters yields must meet the requirement's unit (px meets m)."""
    from ..units import UnitProbe, probe_meets

    if any(
        not (n in numeric_units or (n.startswith("param.") and n[6:] in numeric_units))
        for n in e.names
    ):
        return  # reads measures, manifest facts or text parameters: checked when evaluated
    sig = (text, req_unit + "|" + ",".join(f"{n}={numeric_units[n]}" for n in sorted(used)))
    if sig not in memo:
        env = {
            n: UnitProbe.of(numeric_units[n[6:] if n.startswith("param.") else n]) for n in e.names
        }
        units = ", ".join(f"{n} is in {numeric_units[n]!r}" for n in sorted(used))
        why: str | None = None
        try:
            got = e.evaluate(env)
            if not probe_meets(got, req_unit):
                why = (
                    f"requirement {key} {text!r} yields {got.units.describe()} ({units}), which cannot be "
                    f"compared with the rule's unit {req_unit!r}"
                )
        except (ExpressionError, UnitError, ValueError, TypeError) as exc:
            why = f"requirement {key} {text!r}: units do not combine ({units}): {exc}"
        memo[sig] = why
    if memo[sig]:
        name = sorted(used)[0]
        file, line, col = sites.param_where(name, "unit")
        rfile, rline, _ = sites.rule_where(r.id, ("requirement",))
        out.append(
            Problem(
                file, line, col, f"parameter {name}: {memo[sig]} (rule {r.id} at {rfile}:{rline})"
            )
        )


def _constant_when(e: expr.Expression, text: str) -> str:
    """A condition that reads no fact decides nothing: say what it always is and what to write."""
    try:
        value = bool(getattr(e.evaluate({}), "magnitude", e.evaluate({})))
    except (ExpressionError, ArithmeticError, TypeError, ValueError):
        value = None
    if value is False:
        return (
            f"condition {text!r} reads no fact and is always false: the rule would never apply; to take a rule "
            "out, list it in remove_rules with a justification"
        )
    return f"condition {text!r} reads no fact and is always {'true' if value else 'the same'}: leave `when` out"


def _single_equals(text: str) -> str:
    """The hint for ``a = b`` written for ``a == b`` (the grammar has no assignment)."""
    return (
        "; compare with `==` (a single `=` is not an operator)"
        if re.search(r"(?<![=!<>])=(?!=)", text)
        else ""
    )


def _near_measure(name: str) -> str:
    from .catalog import all_names, stale_hint

    near = difflib.get_close_matches(name, all_names(), n=1, cutoff=0.8)
    return (f"; did you mean {near[0]!r}?" if near else "") + stale_hint()


def _looks_like_expr(text: str, known: set[str]) -> bool:
    try:
        e = _parse(text)
    except ExpressionError:
        return False
    return bool(e.names & known)
