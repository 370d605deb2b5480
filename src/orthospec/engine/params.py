"""Resolve profile parameters, and record who set each one.

Order: ``--param`` (source ``cli``) > the checker file's ``parameters:`` (``checker``) > a
profile's ``value`` (``tender``) > the shipped default (``standard``). The delivery manifest's
``tender.parameters`` is *evidence*, never authority: it cannot set or loosen a threshold. Its
declared value is kept (``declared``) only so ORTHOSPEC-ITT-DECLARED can compare it with the value
in force (red team R1: a manifest tolerance of 1.0 m used to accept a 0.63 m RMSEy).

A parameter with no value that an applicable rule's requirement reads stops the run here (exit 2
with advice) instead of producing ``error`` records later.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from .. import units
from ..errors import ExpressionError, OrthospecError, UnitError
from ..profile import expr
from ..profile.loader import ResolvedProfile, param_location, params_named
from ..profile.models import Parameter
from ..units import (
    NON_NUMERIC,
    canonical,
    number_problem,
    parse_number_text,
    parse_unit,
    same_value,
)

if TYPE_CHECKING:
    from ..delivery.checker import Checker

Source = Literal["cli", "checker", "tender", "standard", "unset"]
SOURCES: tuple[str, ...] = ("cli", "checker", "tender", "standard", "unset")


class ParameterError(OrthospecError, ValueError):
    """A parameter is required but unset, or given a value that does not fit its unit."""


@dataclass(frozen=True)
class ParamValue:
    name: str
    value: Any  # float magnitude in `unit`, or str/bool; None when unset
    unit: str
    source: str  # one of SOURCES
    #: the value the delivery manifest declares (in `unit`), None when it declares none or it is unreadable
    declared: Any = None
    #: "standard" or "itt" (see models.Parameter.set_by)
    set_by: str = "standard"
    #: why a tender profile changed a standard value (printed in the annex)
    justification: str | None = None
    #: why a declared value could not be read, or was not used
    note: str | None = None
    #: the profile's own value (the tender's, else the standard's default) when --param or the
    #: checker's file set this one; None when the profile leaves the parameter open
    profile_value: Any = None

    @property
    def differs(self) -> bool:
        """The value in force is not the profile's: set by --param or the checker's file to another
        value, or to one the profile leaves open (printed on page 1 and in the terminal header)."""
        return (
            self.source in ("cli", "checker")
            and self.value is not None
            and (self.profile_value is None or not same_value(self.value, self.profile_value))
        )

    def quantity(self) -> Any:
        if (
            self.unit in NON_NUMERIC
            or not isinstance(self.value, int | float)
            or isinstance(self.value, bool)
        ):
            return self.value
        return units.Q_(float(self.value), parse_unit(self.unit))

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"value": self.value, "unit": self.unit, "source": self.source}
        if self.declared is not None:
            out["declared"] = self.declared
        if self.justification:
            out["justification"] = self.justification
        if self.note:
            out["note"] = self.note
        if self.profile_value is not None:
            out["profile_value"] = self.profile_value
        return out


def _shown(v: Any, unit: str) -> str:
    text = f"{v:g}" if isinstance(v, float) else str(v)
    return f"{text} {unit}" if unit and unit not in ("1", *NON_NUMERIC) else text


def _refuse_against_contract(
    name: str,
    p: Parameter,
    val: Any,
    src: str,
    own: Any,
    unit: str,
    profile: ResolvedProfile,
    checker: Checker | None,
    cli: Mapping[str, str],
) -> None:
    """A tender's value is the contract (issue 26): --param or the checker's file may replace it only
    where the tender marks the parameter ``checker_may_set: true``. A standard profile checked on its
    own has no tender: there the checker's value is allowed (and printed beside the profile's)."""
    if len(profile.chain) < 2 or p.checker_may_set:
        return
    if src == "cli":
        where = f"--param {name}={cli[name]}"
    else:
        where = (
            f"checker file {checker.at('parameters', name) if checker else ''}: parameters.{name}"
        )
    at = param_location(profile, name, "value" if p.value is not None else "default")
    raise ParameterError(
        f"{where}: {_shown(val, unit)} differs from {_shown(own, unit)}, the value tender profile {profile.id} "
        f"{profile.version} fixes for {name} ({at}); the contract wins: the checker's side may replace a "
        f"tender's value only where the tender marks the parameter `checker_may_set: true`. Check with the "
        f"tender's value, or publish a new tender version"
    )


def parse_cli_params(items: tuple[str, ...] | list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for it in items:
        if "=" not in it:
            raise ParameterError(f"--param {it!r}: expected NAME=VALUE, e.g. tolerance_xy=0.5m")
        k, v = it.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _bool(raw: Any) -> bool | None:
    if isinstance(raw, bool):
        return raw
    t = str(raw).strip().lower()
    if t in ("true", "yes", "1"):
        return True
    if t in ("false", "no", "0"):
        return False
    return None


def _typed(raw: Any, p: Parameter, bool_error: str, number: Callable[[Any, str], float]) -> Any:
    """A parameter value in its kind: bool, text/date, or a number read by ``number(raw, unit)``."""
    unit = p.unit or "1"
    if unit == "bool":
        b = _bool(raw)
        if b is None:
            raise ParameterError(f"{bool_error}, got {raw!r}")
        return b
    if unit in ("text", "date"):
        return str(raw)
    return number(raw, unit)


def _from_cli(name: str, text: str, p: Parameter) -> Any:
    """``--param NAME=TEXT``: the one number parser (no decimal comma, finite, unit converted)."""

    def number(raw: Any, unit: str) -> float:
        try:
            return parse_number_text(raw, unit)
        except UnitError as exc:
            raise ParameterError(f"--param {name}={raw}: {exc}") from None

    return _typed(text, p, f"--param {name}: expects true or false", number)


def _from_profile(name: str, raw: Any, p: Parameter, profile: ResolvedProfile) -> Any:
    """A profile `value`/`default` (validated at load; re-checked so no path can skip it)."""

    def number(value: Any, _unit: str) -> float:
        why = number_problem(value)
        if why:
            raise ParameterError(f"profile {profile.id}: parameter {name}: {why}")
        return float(value)

    return _typed(raw, p, f"profile {profile.id}: parameter {name} expects true or false", number)


def _read_value(raw: Any, p: Parameter, what: str) -> Any:
    """A ``tender.parameters``-shaped value (``{value, unit}``, a number, text, true/false) in the
    parameter's unit; UnitError saying why it cannot be read. One reader for the manifest's
    declaration and the checker file's ``parameters:``."""
    if hasattr(raw, "model_dump"):
        raw = raw.model_dump()
    unit = p.unit or "1"
    if unit == "bool":
        b = _bool(raw)
        if b is None:
            raise UnitError(f"{what}: {raw!r}, not true/false")
        return b
    if unit in ("text", "date"):
        return str(raw)
    if isinstance(raw, dict) and set(raw) == {"value", "unit"}:
        why = number_problem(raw["value"])
        if why:
            raise UnitError(why)
        text = f"{float(raw['value'])!r} {raw['unit']}"
    elif isinstance(raw, int | float) and not isinstance(raw, bool):
        why = number_problem(raw)
        if why:
            raise UnitError(why)
        return float(raw)
    elif isinstance(raw, str):
        text = raw
    else:
        raise UnitError(f"expected a number in {canonical(unit)}, got {raw!r}")
    return parse_number_text(text, unit)


def _declared(name: str, raw: Any, p: Parameter) -> tuple[Any, str | None]:
    """The manifest's declared value in the parameter's unit, or (None, why it cannot be read)."""
    if raw is None:
        return None, None
    try:
        return _read_value(raw, p, f"the manifest declares {name}"), None
    except UnitError as exc:
        return None, f"the manifest's tender.parameters.{name} cannot be read ({exc}); ignored"


def _from_checker(name: str, raw: Any, p: Parameter, checker: Checker) -> Any:
    """The checker file's ``parameters.NAME`` (exit 2 naming file and line when unreadable)."""
    try:
        return _read_value(raw, p, f"parameter {name}")
    except UnitError as exc:
        raise ParameterError(
            f"checker file {checker.at('parameters', name)}: parameters.{name}: {exc}"
        ) from None


def resolve_parameters(
    profile: ResolvedProfile,
    delivery_params: Mapping[str, Any],
    cli: Mapping[str, str],
    *,
    manifest: Mapping[str, Any] | None = None,
    checker: Checker | None = None,
) -> dict[str, ParamValue]:
    """Every parameter's value with its source; raise ParameterError (exit 2) with advice.

    ``delivery_params`` is the manifest's ``tender.parameters`` (evidence only: never a value);
    ``manifest`` the flat manifest (``manifest.<path>`` -> value), used to tell whether a rule gated
    on a manifest fact applies to this delivery when deciding that an unset parameter is needed;
    ``checker`` the checker's file, whose ``parameters:`` are values in force (source ``checker``).
    """
    unknown = sorted(set(cli) - set(profile.parameters))
    if unknown:
        import difflib

        near = difflib.get_close_matches(unknown[0], list(profile.parameters), n=1, cutoff=0.6)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        raise ParameterError(
            f"--param {unknown[0]}: profile {profile.id} has no such parameter{hint} "
            f"(known: {', '.join(sorted(profile.parameters)) or 'none'})"
        )
    from_checker = dict(checker.model.parameters) if checker is not None else {}
    if checker is not None:
        _refuse_misspelt(from_checker, profile, checker)
    out: dict[str, ParamValue] = {}
    missing = []
    for name, p in sorted(profile.parameters.items()):
        unit = p.unit if p.unit in NON_NUMERIC else canonical(p.unit)
        authority = p.authority()
        declared, note = _declared(name, delivery_params.get(name), p)
        val: Any
        src: str
        # the checker's value is read even when --param wins: a bad entry is never silently ignored
        stated = (
            _from_checker(name, from_checker[name], p, checker)
            if name in from_checker and checker is not None
            else None
        )
        own: Any = None  # the profile's own value (a tender's value, else the standard's default)
        own_src = "unset"
        if p.value is not None:
            own, own_src = _from_profile(name, p.value, p, profile), "tender"
        elif p.default is not None:
            own, own_src = _from_profile(name, p.default, p, profile), "standard"
        if name in cli:
            val, src = _from_cli(name, cli[name], p), "cli"
        elif stated is not None:
            val, src = stated, "checker"
        else:
            val, src = own, own_src
        if (
            val is None and p.required
        ):  # the manifest's declaration never fills the gap (evidence only)
            missing.append(name)
        if p.choices is not None and val is not None and val not in p.choices:
            where = {
                "cli": "--param",
                "checker": f"checker file {checker.at('parameters', name) if checker else ''}",
            }.get(src, f"profile {profile.id}")
            raise ParameterError(f"{where}: parameter {name}={val!r} is not one of {p.choices}")
        if is_crs(name, p):
            val = _crs_in_force(name, val, src, profile, checker)
            if src in ("cli", "checker"):
                own = _crs_in_force(name, own, own_src, profile, checker)
            declared, note = _crs_declared(name, declared, note)
        if src in ("cli", "checker") and own is not None and not same_value(val, own):
            _refuse_against_contract(name, p, val, src, own, unit, profile, checker, cli)
        out[name] = ParamValue(
            name,
            val,
            unit,
            src,
            declared=declared,
            set_by=authority,
            justification=p.justification,
            note=note,
            profile_value=own if src in ("cli", "checker") else None,
        )
    needed, all_off = _needed(profile, out, manifest)
    for name in missing:
        needed.setdefault(name, [])
    if needed:
        raise ParameterError(_advice(profile, needed, all_off))
    return out


def is_crs(name: str, p: Parameter) -> bool:
    """A text parameter named ``*_crs`` is a coordinate reference system: ``map_crs``, the map
    projection the ITT fixes (JRC §12.4 Table 12 "georeferenced to the (national) map projection",
    red team R16). It is read with pyproj when the run starts and held as ``EPSG:<code>``."""
    return (p.unit or "") == "text" and name.endswith("_crs")


def _crs_in_force(
    name: str, val: Any, src: str, profile: ResolvedProfile, checker: Checker | None
) -> Any:
    """The CRS value in force as ``EPSG:<code>``; exit 2 naming its source (and line) when pyproj
    cannot read it or it has no EPSG code."""
    from ..delivery.crs import CrsProblem, epsg_name

    if val is None:
        return None
    try:
        return epsg_name(val)
    except CrsProblem as exc:
        if src == "cli":
            where = f"--param {name}={val}"
        elif src == "checker" and checker is not None:
            where = f"checker file {checker.at('parameters', name)}: parameters.{name}"
        else:
            file, line, _col = (
                profile.sites.param_where(name, "value" if src == "tender" else "default")
                if profile.sites is not None
                else (f"profile {profile.id}", None, None)
            )
            where = f"{file}:{line}: parameter {name}" if line else f"{file}: parameter {name}"
        raise ParameterError(f"{where}: {exc}") from None


def _crs_declared(name: str, declared: Any, note: str | None) -> tuple[Any, str | None]:
    """The manifest's declared CRS as ``EPSG:<code>`` (so ``epsg:25832`` equals ``EPSG:25832`` for
    ORTHOSPEC-ITT-DECLARED), or None with why it cannot be read."""
    from ..delivery.crs import CrsProblem, epsg_name

    if declared is None:
        return None, note
    try:
        return epsg_name(declared), note
    except CrsProblem as exc:
        return None, f"the manifest's tender.parameters.{name} cannot be read ({exc}); ignored"


def _refuse_misspelt(given: Mapping[str, Any], profile: ResolvedProfile, checker: Checker) -> None:
    """A checker-file parameter this profile lacks but spells almost like one of its own is a typo
    (it would leave a default in force unnoticed): exit 2. Other unknown names are ignored, as one
    checker file may serve several profiles (jrc-v3's tolerance_xy means nothing to asprs-2023)."""
    import difflib

    for name in sorted(set(given) - set(profile.parameters)):
        near = difflib.get_close_matches(name, list(profile.parameters), n=1, cutoff=0.8)
        if near:
            raise ParameterError(
                f"checker file {checker.at('parameters', name)}: parameters.{name}: profile "
                f"{profile.id} has no such parameter; did you mean {near[0]!r}?"
            )


def _advice(profile: ResolvedProfile, needed: dict[str, list[str]], all_off: bool = False) -> str:
    if all_off:
        lines = [
            f"profile {profile.id} would check no mandatory requirement: every mandatory rule reads a "
            "parameter that has no value (set at least the ones the ITT fixes):"
        ]
    else:
        lines = [f"profile {profile.id} needs parameter(s) that have no value:"]
    for name in sorted(needed):
        p = profile.parameters[name]
        unit = p.unit if p.unit in NON_NUMERIC else canonical(p.unit)
        rules = needed[name]
        who = (
            f"read by {', '.join(rules[:6])}"
            + (f" and {len(rules) - 6} more" if len(rules) > 6 else "")
            if rules
            else "required by the profile"
        )
        if is_crs(name, p):
            who += " (a coordinate reference system: EPSG:<code>)"
        lines.append(f"  {name} ({unit}): {who}")
    first = sorted(needed)[0]
    p = profile.parameters[first]
    example = "EPSG:<code>" if is_crs(first, p) else "..."
    shape = example if p.unit in NON_NUMERIC else "{value: ..., unit: ...}"
    lines.append(
        f"set them with --param NAME=VALUE (e.g. --param {first}={example}), in the checker file "
        f"(check --checker FILE; parameters: {{{first}: {shape}}}), or in a tender "
        f"profile that extends {profile.id} (parameters: {{{first}: {{value: {example}}}}}); the value "
        "the delivery manifest declares (tender.parameters) is the contractor's evidence, never "
        "the value in force"
    )
    return "\n".join(lines)


def _needed(
    profile: ResolvedProfile,
    values: Mapping[str, ParamValue],
    manifest: Mapping[str, Any] | None = None,
) -> tuple[dict[str, list[str]], bool]:
    """Unset parameters an applicable rule's requirement reads: name -> rule ids.

    A rule whose ``when`` itself tests the parameter (``tolerance_z != null``) is written to be
    optional and does not count. A rule whose ``when`` reads only parameters and manifest facts is
    decided here when ``manifest`` is given (false: it does not apply, so it needs nothing).
    Also, when every mandatory automatic rule is switched off by unset parameters, the profile
    checks nothing mandatory: every such parameter is reported.
    """
    unset = {n for n, v in values.items() if v.value is None}
    if not unset:
        return {}, False
    needed: dict[str, list[str]] = {}
    mandatory_total = 0
    mandatory_off: dict[str, list[str]] = {}
    for r in profile.rules:
        if r.manual or r.measure.startswith("manual."):
            continue
        req = r.requirement
        reads: set[str] = set()
        for v in (req.value, req.min, req.max):
            if isinstance(v, str):
                try:
                    reads |= params_named(expr.parse(v).names, values)
                except ExpressionError:
                    continue
        when_names: set[str] = set()
        when_params: set[str] = set()
        if r.when:
            try:
                when_names = set(expr.parse(r.when).names)
            except ExpressionError:
                when_names = set()
            when_params = params_named(when_names, values)
        if r.level == "mandatory":
            mandatory_total += 1
            for n in sorted((reads | when_params) & unset):
                mandatory_off.setdefault(n, []).append(r.id)
        missing_reads = (reads & unset) - when_params
        if not missing_reads:
            continue
        if r.when and _may_not_apply(r.when, when_names, values, manifest):
            continue
        for n in sorted(missing_reads):
            needed.setdefault(n, []).append(r.id)
    if mandatory_total and not needed:
        switched_off = {rid for ids in mandatory_off.values() for rid in ids}
        if len(switched_off) == mandatory_total:
            return {n: ids for n, ids in mandatory_off.items()}, True
    return needed, False


def _fact_of_the_files(name: str) -> bool:
    """A delivery-wide ``derived.*`` fact (one value per delivery, computed from the files)."""
    from ..profile.catalog import measure_info

    info = measure_info(name) if name.startswith("derived.") else None
    return info is not None and info[0] in ("delivery", "project")


def _may_not_apply(
    when: str, names: set[str], values: Mapping[str, ParamValue], manifest: Mapping[str, Any] | None
) -> bool:
    """True unless ``when`` surely holds: it reads only parameters and manifest facts and is true.

    A ``when`` that reads measures may hold for some items: it counts as applying (False here).

    Without the manifest, a ``when`` that reads manifest facts cannot be decided: the rule may not
    apply, so the parameter is left to the evaluator (which must record ``missing``).
    """
    measures = [n for n in names if not (n in values or n.startswith(("param.", "manifest.")))]
    # issue 25 (helper facts): a delivery-wide fact computed from the files (derived.dem_delivered) is not
    # known before the run: it is taken as false here, so only what the manifest alone makes apply
    # needs its parameter now; otherwise the evaluator decides and records `missing` if it applies
    files = set(measures) if measures and all(_fact_of_the_files(n) for n in measures) else set()
    if measures and not files:
        return False  # reads measures: it may apply to some item, so the parameter is needed
    reads_manifest = any(n.startswith("manifest.") for n in names)
    if reads_manifest and manifest is None:
        return True
    env: dict[str, Any] = {}
    for n in names:
        if n in files:
            env[n] = False
        elif n.startswith("manifest."):
            v = (manifest or {}).get(n)
            if isinstance(v, dict) and set(v) == {"value", "unit"}:
                try:
                    v = units.Q_(float(v["value"]), parse_unit(v["unit"]))
                except (UnitError, TypeError, ValueError):
                    v = None
            env[n] = v
        else:
            key = n[6:] if n.startswith("param.") else n
            env[n] = values[key].quantity()
    try:
        got = expr.parse(when).evaluate(env)
    except (ExpressionError, UnitError, TypeError, ValueError):
        return True  # undecidable here: leave it to the evaluator
    got = getattr(got, "magnitude", got)
    try:
        return got is None or not bool(got)
    except (TypeError, ValueError):
        return True
