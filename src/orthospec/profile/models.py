"""Pydantic models of a spec profile. The JSON Schema in specs/schema/ is generated from these."""

from __future__ import annotations

import datetime as _dt
import re
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, field_validator

from ..present import cite

SEMVER = r"^(0|[1-9]\d*)\.(0|[1-9]\d*)\.(0|[1-9]\d*)(?:-[0-9A-Za-z.-]+)?$"
PROFILE_ID = r"^[a-z0-9][a-z0-9._-]*$"
RULE_ID = r"^[A-Za-z0-9][A-Za-z0-9._-]*$"

Scope = Literal[
    "delivery", "project", "block", "image", "band", "checkpoint", "gcp", "flight", "camera",
    "scanner", "dem", "mosaic", "edge",
]
Level = Literal["mandatory", "recommended"]
Consequence = Literal["reject_item", "reject_block", "return_delivery", "incomplete", "warn"]
Op = Literal["<", "<=", ">", ">=", "==", "!=", "between", "in", "present", "true", "false"]
Scalar = float | int | str | bool


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Clause(_Strict):
    """Where in the source document a requirement is written."""

    document: str = Field(description="Document short name, e.g. 'JRC EUR 23638 EN'.")
    section: str | int | float | None = Field(None, description="Section number, e.g. '12.7'.")
    table: str | int | None = Field(None, description="Table number, e.g. 9.")
    row: str | int | None = Field(None, description="Table row or item, when there is one.")
    figure: str | int | None = None
    seed: str | None = Field(
        None, description="Seed file the quote is taken from, when not the profile's."
    )

    @field_validator("section", "table", "row", "figure", mode="before")
    @classmethod
    def _to_text(cls, v: Any) -> Any:
        return None if v is None else str(v)

    def ref(self) -> str:
        """Section, table and figure without the document name (short form for terminals)."""
        return cite(self, "ref")

    def text(self) -> str:
        """The citation a person reads (:func:`orthospec.present.cite`)."""
        return cite(self)


class Source(_Strict):
    title: str
    issue: str | int | float | None = None
    year: int | None = None
    identifier: str | None = None
    seed: str | None = Field(
        None, description="Seed file in ../shared/seeds that quotes come from."
    )
    url: str | None = None

    @field_validator("issue", mode="before")
    @classmethod
    def _issue_text(cls, v: Any) -> Any:
        return None if v is None else str(v)


SetBy = Literal["standard", "itt"]


class Parameter(_Strict):
    """A value a rule compares against (tolerance, pixel size...), with its unit and its authority.

    Who may set it matters as much as the number: the standard's own constants change only in a
    tender profile (with a justification), never through the contractor's delivery manifest.
    """

    unit: str | None = Field(
        None,
        description="m, mm, µm, ft, usft, px, %, deg, DN, 1, or text/bool/date "
        "(required for a new parameter; optional when overriding).",
    )
    default: Scalar | None = Field(
        None,
        description="Value from the standard, when it gives one. A number "
        "for a numeric unit (write 1.0, not '1.0' or 1,0).",
    )
    value: Scalar | None = Field(
        None, description="Value fixed by a tender profile (wins over defaults)."
    )
    required: bool = False
    description: str = Field(
        "",
        description="Public: what the value means and where the source fixes it "
        "(the annex prints it).",
    )
    internal_note: str | None = Field(
        None, description="For the profile's maintainers; never printed."
    )
    choices: list[Scalar] | None = None
    set_by: SetBy | None = Field(
        None,
        description="Who fixes the value. 'standard': a constant of the published standard; only a "
        "tender profile that extends it may change it, with a `justification`, and the "
        "delivery manifest never does. 'itt': left to the invitation to tender; a tender "
        "profile or --param sets it, and failing both the value the contractor's manifest "
        "declares under tender.parameters is used with a visible warning. When omitted: "
        "'standard' if the parameter has a default, else 'itt'. Fixed by the profile that "
        "defines the parameter (an extending profile cannot change it).",
    )
    justification: str | None = Field(
        None,
        min_length=1,
        description="Why an extending (tender) profile changes the value of an inherited 'standard' "
        "parameter; required then, and printed in the report annex.",
    )
    checker_may_set: bool = Field(
        False,
        description="In a tender profile (one that extends another): the checker's file or --param may "
        "replace this parameter's value; every report prints the value in force beside the "
        "tender's. Without it the tender's value is the contract, and a different value from "
        "the checker's side stops the check (exit 2) naming both values.",
    )

    @field_validator("default", "value", mode="before")
    @classmethod
    def _date_as_written(cls, v: Any) -> Any:
        """YAML reads an unquoted 2026-04-01 as a date: a `unit: date` value is kept as its ISO text."""
        return v.isoformat() if isinstance(v, _dt.date) else v

    def authority(self) -> str:
        """``set_by`` as written, else the documented default rule."""
        if self.set_by is not None:
            return self.set_by
        return "standard" if self.default is not None else "itt"


class Requirement(_Strict):
    """Operator and threshold; values may be numbers or safe expressions over parameters."""

    op: Op
    value: Scalar | None = None
    min: Scalar | None = None
    max: Scalar | None = None
    min_inclusive: bool = True
    max_inclusive: bool = True
    values: list[Scalar] | None = None
    unit: str | None = Field(None, description="Unit of literal numbers and of the comparison.")


class Audit(_Strict):
    """JRC Tables 6 and 10: who produces the QCR, how the EC inspects it, when."""

    table: str | int | None = None
    qcr: str | None = None
    qcr_production: str | None = None
    inspection: str | None = None
    stage: str | None = None
    family: str | None = Field(None, description="QCR family for Normal/Tightened audit state.")

    @field_validator("table", mode="before")
    @classmethod
    def _t(cls, v: Any) -> Any:
        return None if v is None else str(v)


class Rule(_Strict):
    id: Annotated[str, Field(pattern=RULE_ID)]
    title: str
    clause: Clause
    quote: str = Field(min_length=1, description="The exact words of the source the rule encodes.")
    scope: Scope
    when: str | None = Field(None, description="Applicability condition (safe expression).")
    measure: str
    requirement: Requirement
    level: Level = "mandatory"
    consequence: Consequence
    manual: bool = False
    note: str | None = Field(
        None,
        description=(
            "Public note: how the rule reads its clause, written for bidders and checkers (printed in the "
            "annex and by `explain`)."
        ),
    )
    internal_note: str | None = Field(
        None,
        description=(
            "Internal note for the profile's maintainers (history, tests, tools, open questions): kept in the "
            "profile, never printed in the annex, reports or `explain`."
        ),
    )
    audit: Audit | None = None
    tags: list[str] = Field(default_factory=list)
    override: Literal[False] = False


class RuleOverride(_Strict):
    """In a profile that extends another: change some keys of an inherited rule."""

    id: Annotated[str, Field(pattern=RULE_ID)]
    override: Literal[True]
    title: str | None = None
    clause: Clause | None = None
    quote: str | None = None
    scope: Scope | None = None
    when: str | None = None
    measure: str | None = None
    requirement: Requirement | None = None
    level: Level | None = None
    consequence: Consequence | None = None
    manual: bool | None = None
    note: str | None = None
    internal_note: str | None = None
    audit: Audit | None = None
    tags: list[str] | None = None
    justification: str | None = Field(
        None,
        min_length=1,
        description="Why the ITT changes a mandatory rule of the profile it extends so that it can check "
        "less (level, a lighter consequence, a new `when`, another measure, scope or requirement, "
        "manual): required then; `spec diff`, the annex and every report print it.",
    )


def _rule_kind(v: Any) -> str:
    if isinstance(v, dict):
        return "override" if v.get("override") is True else "rule"
    return "override" if getattr(v, "override", False) else "rule"


AnyRule = Annotated[
    Annotated[Rule, Tag("rule")] | Annotated[RuleOverride, Tag("override")],
    Discriminator(_rule_kind),
]


class RuleRemoval(_Strict):
    """An inherited rule a tender profile takes out, and why (the report annex prints it)."""

    id: Annotated[str, Field(pattern=RULE_ID)]
    justification: str = Field(
        min_length=1,
        description="Why the ITT does not apply this rule (required "
        "for a mandatory rule; the annex and every report print it).",
    )


class Extends(_Strict):
    id: Annotated[str, Field(pattern=PROFILE_ID)]
    version: Annotated[str, Field(pattern=SEMVER)]


class LookupTable(_Strict):
    description: str = ""
    columns: list[str]
    units: dict[str, str] | None = None
    rows: list[list[Scalar | None]]
    clause: Clause | None = None
    note: str | None = None


class ClassItem(_Strict):
    id: str
    min: float | None = None
    max: float | None = None
    min_inclusive: bool = True
    max_inclusive: bool = True
    description: str | None = None


class ClassSet(_Strict):
    unit: str
    description: str = ""
    items: list[ClassItem]
    clause: Clause | None = None
    note: str | None = None


class ProfileTest(_Strict):
    delivery: str
    params: dict[str, Scalar] = Field(default_factory=dict)
    expect: dict[str, Any] = Field(default_factory=dict)
    description: str | None = None
    checker: str | None = Field(
        None,
        description=(
            "The checker's folder or file (check --checker), relative to the profile file: the manual-check "
            "verdicts, waivers and check point measurements in force for this test delivery (a delivery's own "
            "manual_checks and check points are only the contractor's evidence)."
        ),
    )


class ProfileWaiver(_Strict):
    """A waiver granted in the tender profile itself (e.g. a rule not applicable to this ITT)."""

    rule: str
    items: list[str] = Field(default_factory=lambda: ["*"])
    justification: str = Field(min_length=1)
    approver: str = Field(min_length=1)


class Profile(_Strict):
    """A versioned spec profile as written in one YAML file (before ``extends`` is resolved)."""

    orthospec_profile: Literal[1]
    id: Annotated[str, Field(pattern=PROFILE_ID)]
    version: Annotated[str, Field(pattern=SEMVER)]
    title: str
    description: str | None = None
    source: Source
    extends: Extends | None = None
    parameters: dict[str, Parameter] = Field(default_factory=dict)
    tables: dict[str, LookupTable] = Field(default_factory=dict)
    classes: dict[str, ClassSet] = Field(default_factory=dict)
    rules: list[AnyRule] = Field(default_factory=list)
    remove_rules: list[str | RuleRemoval] = Field(
        default_factory=list,
        description="Inherited rules this profile takes out: {id, justification} (the annex and every "
        "report print it); a bare id only for a rule that is not mandatory.",
    )
    waivers: list[ProfileWaiver] = Field(default_factory=list)
    tests: list[ProfileTest] = Field(default_factory=list)
    allow_no_mandatory: bool = Field(
        False,
        description="A resolved profile with no mandatory rule accepts every delivery; it is refused "
        "unless this says so explicitly (e.g. an informative profile of recommendations).",
    )

    @field_validator("parameters")
    @classmethod
    def _param_names(cls, v: dict[str, Parameter]) -> dict[str, Parameter]:
        for name in v:
            if not re.fullmatch(r"[a-z][a-z0-9_]*", name):
                raise ValueError(f"parameter name {name!r} must be lower_snake_case")
        return v
