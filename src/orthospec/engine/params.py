"""Resolve profile parameters: --param > tender profile `value` > delivery `parameters` > default."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pint

from ..errors import OrthospecError, UnitError
from ..spec.loader import ResolvedProfile
from ..units import NON_NUMERIC, Q_, canonical, parse_unit


class ParameterError(OrthospecError, ValueError):
    """A parameter is required but unset, or given a value that does not fit its unit."""


@dataclass(frozen=True)
class ParamValue:
    name: str
    value: Any  # float magnitude in `unit`, or str/bool
    unit: str
    source: str  # cli | profile | delivery | default

    def quantity(self) -> Any:
        if self.unit in NON_NUMERIC or not isinstance(self.value, int | float) or isinstance(self.value, bool):
            return self.value
        return Q_(float(self.value), parse_unit(self.unit))

    def to_dict(self) -> dict[str, Any]:
        return {"value": self.value, "unit": self.unit, "source": self.source}


def parse_cli_params(items: tuple[str, ...] | list[str]) -> dict[str, str]:
    out: dict[str, str] = {}
    for it in items:
        if "=" not in it:
            raise ParameterError(f"--param {it!r}: expected NAME=VALUE, e.g. tolerance_xy=0.5m")
        k, v = it.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _coerce(name: str, raw: Any, unit: str, where: str) -> Any:
    if unit == "bool":
        if isinstance(raw, bool):
            return raw
        t = str(raw).strip().lower()
        if t in ("true", "yes", "1"):
            return True
        if t in ("false", "no", "0"):
            return False
        raise ParameterError(f"{where}: parameter {name} expects true/false, got {raw!r}")
    if unit in ("text", "date"):
        return str(raw)
    if isinstance(raw, dict) and set(raw) == {"value", "unit"}:
        raw = f"{raw['value']} {raw['unit']}"
    if isinstance(raw, bool):
        raise ParameterError(f"{where}: parameter {name} expects a number in {unit}, got {raw!r}")
    if isinstance(raw, int | float):
        return float(raw)
    text = str(raw).strip()
    try:
        return float(text)
    except ValueError:
        pass
    for sym, spelled in (("µm", "micrometer"), ("um", "micrometer"), ("%", "percent"), ("px", "pixel"),
                         ("deg", "degree"), ("usft", "US_survey_foot")):
        if text.endswith(sym):
            text = text[: -len(sym)].strip() + " " + spelled
            break
    try:
        q = Q_(text)
    except (pint.errors.UndefinedUnitError, pint.errors.DefinitionSyntaxError, ValueError,
            AttributeError, TypeError):
        raise ParameterError(f"{where}: parameter {name}: cannot read {raw!r} as a number with a unit "
                             f"(expected e.g. 0.5 or 0.5 {unit})") from None
    if not isinstance(q, pint.Quantity):
        return float(q)
    if q.dimensionless and q.units == Q_(1).units:
        return float(q.magnitude)
    try:
        return float(q.to(parse_unit(unit)).magnitude)
    except (pint.errors.DimensionalityError, UnitError):
        raise ParameterError(f"{where}: parameter {name} is in {canonical(unit)}, "
                             f"got {raw!r} which does not convert") from None


def resolve_parameters(profile: ResolvedProfile, delivery_params: dict[str, Any],
                       cli: dict[str, str]) -> dict[str, ParamValue]:
    unknown = sorted(set(cli) - set(profile.parameters))
    if unknown:
        raise ParameterError(f"--param {unknown[0]}: profile {profile.id} has no such parameter; "
                             f"known: {', '.join(sorted(profile.parameters)) or 'none'}")
    out: dict[str, ParamValue] = {}
    missing = []
    for name, p in sorted(profile.parameters.items()):
        unit = p.unit if p.unit in NON_NUMERIC else canonical(p.unit)
        if name in cli:
            val, src = _coerce(name, cli[name], p.unit, "--param"), "cli"
        elif p.value is not None:
            val, src = _coerce(name, p.value, p.unit, f"profile {profile.id}"), "profile"
        elif name in delivery_params and delivery_params[name] is not None:
            raw = delivery_params[name]
            if hasattr(raw, "model_dump"):
                raw = raw.model_dump()
            val, src = _coerce(name, raw, p.unit, "delivery.yaml parameters"), "delivery"
        elif p.default is not None:
            val, src = _coerce(name, p.default, p.unit, f"profile {profile.id} default"), "default"
        else:
            val, src = None, "unset"
            if p.required:
                missing.append(name)
        if p.choices is not None and val is not None and val not in p.choices:
            raise ParameterError(f"parameter {name}={val!r} is not one of {p.choices}")
        out[name] = ParamValue(name, val, unit, src)
    if missing:
        hints = ", ".join(f"{m} ({profile.parameters[m].unit})" for m in missing)
        raise ParameterError(
            f"profile {profile.id} needs parameter(s) {hints}: set them with --param NAME=VALUE, in a "
            "tender profile that extends it, or under `parameters:` in delivery.yaml")
    return out
