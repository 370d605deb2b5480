"""Rules the engine adds to every profile: the contract values the contractor declares.

JRC EUR 23638 EN §2.5: "The acceptance criterion for this check is the tolerance stated in the
ITT." The ITT's numbers therefore come from the checker's side only: ``--param``, the checker's
file (``parameters:``), a tender profile, or the standard's own value (engine/params.py). The
contractor's manifest only *declares* them (``tender.parameters``): evidence, never authority,
never a value in force (red team R1). One built-in rule makes the declaration visible:

* ``ORTHOSPEC-ITT-DECLARED`` (mandatory, return_delivery): the manifest declares a value that
  differs from the one in force, or declares one that cannot be read. Why return the delivery:
  §2.5 makes the contractor's internal QC and its QCRs part of what the Commission audits; a
  delivery whose own record of the contract differs from the contract documents a QC made against
  other numbers, so the record is not evidence of conformity and goes back for correction. The
  products themselves are still judged against the value in force by the other rules.

(ORTHOSPEC-ITT-SOURCE, which warned when a manifest value was used, is gone: none is used.)
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .. import verdicts as V
from ..profile.models import Clause, Requirement, Rule

if TYPE_CHECKING:
    from ..delivery.reader import Delivery
    from .params import ParamValue

_CLAUSE = Clause(document="JRC EUR 23638 EN", section="2.5")

ITT_DECLARED = Rule(
    id="ORTHOSPEC-ITT-DECLARED",
    title="Manifest-declared contract value agrees with the value in force",
    clause=_CLAUSE,
    quote="The acceptance criterion for this check is the tolerance stated in the ITT.",
    scope="delivery",
    measure="engine.parameter_declared",
    requirement=Requirement(op="==", value="value in force"),
    level="mandatory",
    consequence="return_delivery",
    note=(
        "Built into the engine. tender.parameters in delivery.yaml is evidence, never authority; a "
        "declared value different from the one in force (--param, the checker's file, the tender "
        "profile or the standard) "
        "means the contractor's internal QC was run against other numbers, so its QCRs do not show "
        "conformity with the ITT (JRC §2.5): the delivery is returned for correction of the record."
    ),
    tags=["engine", "parameters"],
)

BUILTIN_RULES: tuple[Rule, ...] = (ITT_DECLARED,)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return bool(np.isclose(float(a), float(b), rtol=1e-9, atol=0.0))
    return str(a) == str(b)


def _show(v: Any, unit: str) -> str:
    if isinstance(v, float):
        v = f"{v:.6g}"
    return f"{v} {unit}" if unit and unit not in ("1", "text", "bool", "date") else str(v)


def parameter_findings(
    params: dict[str, ParamValue], d: Delivery
) -> dict[str, list[tuple[str, str, str | None, str]]]:
    """Per built-in rule id: (item, measured text, note, verdict) rows (verdict names of
    orthospec.verdicts)."""
    declared_raw = dict(d.manifest.tender.parameters) if d.manifest.tender else {}
    declared_rows: list[tuple[str, str, str | None, str]] = []
    for name, p in sorted(params.items()):
        src = getattr(p, "source", "")
        declared = getattr(p, "declared", None)
        if name not in declared_raw:
            continue
        if declared is None:
            why = (
                getattr(p, "note", None)
                or "the declared value cannot be read in the parameter's unit"
            )
            declared_rows.append(
                (
                    name,
                    str(declared_raw[name]),
                    f"delivery.yaml tender.parameters.{name}: {why}",
                    V.FAIL,
                )
            )
        elif p.value is None or not _same(declared, p.value):
            declared_rows.append(
                (
                    name,
                    _show(declared, p.unit),
                    f"delivery.yaml declares {name} = {_show(declared, p.unit)}, the value in force "
                    f"is {_show(p.value, p.unit)} (source: {src}); the contractor's QC used "
                    "other numbers than the contract",
                    V.FAIL,
                )
            )
        else:
            declared_rows.append(
                (
                    name,
                    _show(declared, p.unit),
                    f"declared {_show(declared, p.unit)} = value in force (source: {src})",
                    V.PASS,
                )
            )
    if not declared_rows:
        declared_rows.append(
            (
                d.id,
                "",
                "no contract value declared in delivery.yaml to cross-check against "
                "--param, the checker's file, a tender profile or the standard",
                V.NOT_APPLICABLE,
            )
        )
    return {ITT_DECLARED.id: declared_rows}
