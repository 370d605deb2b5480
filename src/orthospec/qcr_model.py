"""The QCR document (qcr.json) as pydantic models: the typed boundary of issue 15 item 4.

``specs/schema/qcr.schema.json`` is generated from :class:`QcrDocument` (``qcr_schema()``, written
by ``python -m orthospec.profile.schema``; a test fails when the committed file is stale), and
``QcrDocument.model_validate(json.loads(text))`` checks a stored document. The writer
(:mod:`orthospec.qcr`) builds plain dicts for speed; these models describe exactly what it writes.
See docs/QCR.md for the meaning of every field, the compact columns and the parquet table.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from .verdicts import CONSEQUENCES, OVERALL, VERDICTS, Reason

SCHEMA_IDS = ("orthospec.qcr/1", "orthospec.qcr/2", "orthospec.qcr/3")
SCHEMA_BASE = "https://orthospec.dev/schema/"

Verdict = Literal["pass", "fail", "warn", "not_applicable", "missing", "error", "waived"]
CompactVerdict = Literal["pass", "not_applicable"]
Level = Literal["mandatory", "recommended"]
Consequence = Literal["reject_item", "reject_block", "return_delivery", "incomplete", "warn"]
Sha256 = Field(pattern="^[0-9a-f]{64}$")

assert set(Verdict.__args__) == set(VERDICTS)  # type: ignore[attr-defined]  # one vocabulary
assert set(Consequence.__args__) == set(CONSEQUENCES)  # type: ignore[attr-defined]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)


class _Open(BaseModel):
    model_config = ConfigDict(extra="allow", populate_by_name=True)


class EvidenceRef(_Closed):
    """One piece of evidence: a delivered file (its SHA-256), CSV data rows (1-based), a YAML path.

    Many rows (more than 1,000) are written as a selector when one stands for exactly them:
    ``where`` (column -> value; ``{}`` = every data row) and ``rows_count`` (version 3)."""

    file: str = Field(description="Path relative to the delivery root (POSIX separators).")
    sha256: str = Sha256
    rows: list[int] | None = Field(
        None, description="1-based data rows of a CSV table (header = row 0)."
    )
    where: dict[str, str] | None = Field(
        None,
        description="Selector standing for the rows: the data rows of the CSV table whose cell in each "
        "named column (surrounding whitespace stripped) equals the value; {} = every data "
        "row (blank lines are no rows). Exact: checked against the parsed table when written.",
    )
    rows_count: int | None = Field(None, ge=0, description="How many rows the selector stands for.")
    path: str | None = Field(None, description="Dotted YAML path of a manifest value.")


class Citation(_Open):
    """Where the requirement is written (the profile rule's clause)."""

    document: str
    section: str | None = None
    table: str | None = None
    row: str | None = None
    figure: str | None = None
    seed: str | None = None


class Measured(_Closed):
    value: float | int | bool | str | None
    unit: str | None


class Requirement(_Open):
    """The requirement as applied: operator, threshold(s) resolved to numbers where known, and
    the wording (``text``) shared with ``orthospec explain`` and the tender annex."""

    op: str
    text: str
    unit: str | None = None


_REASON = (
    "Why the record is not a pass (orthospec.verdicts.Reason); absent for a pass, and for a compact "
    "record whose reason is its verdict's default (not_applicable: condition_false)."
)


class Record(_Closed):
    """One quality control record: one rule applied to one item."""

    rule: str
    title: str
    clause: Citation
    quote: str
    scope: str
    item: str
    level: Level
    consequence: Consequence
    manual: bool = False
    verdict: Verdict
    measure: str = ""
    measured: Measured
    requirement: Requirement
    evidence: list[EvidenceRef]
    message: str
    waiver: dict[str, Any] | None = Field(
        None, description="The waiver in force (checker file or tender profile)."
    )
    waiver_requested: dict[str, Any] | None = Field(
        None,
        description="The contractor's waiver request (delivery.yaml): evidence, never in force by itself.",
    )
    waived_verdict: Verdict | None = Field(None, description="The verdict a waiver replaced.")
    audit: dict[str, Any] | None = None
    reason: Reason | None = Field(None, description=_REASON)


class StoredRecord(_Closed):
    """A record in full as version 2 stores it: only what is particular to the item. The rule's
    title, clause, quote, level, consequence, measure, unit, audit (and requirement, unless it
    varies by item) are in its rule summary; ``orthospec.qcr.all_records`` puts them together
    into a :class:`Record`."""

    rule: str
    item: str
    verdict: Verdict
    measured: float | int | bool | str | None
    requirement: Requirement | None = None
    evidence: list[EvidenceRef]
    message: str
    waiver: dict[str, Any] | None = None
    waived_verdict: Verdict | None = None
    waiver_requested: dict[str, Any] | None = None
    reason: Reason | None = Field(None, description=_REASON)


class ColumnRef(_Closed):
    """A compact column equal to one written before: ``[rule id, column name]`` of that column."""

    ref: tuple[str, str]


class AllSame(_Closed):
    """A compact column whose value is the same for every item of the block."""

    all: Any


class RowColumn(_Closed):
    """Evidence of a compact block whose every item is one row of one file (version 3): ``entry``
    indexes the document's ``evidence`` table (``{file, sha256}``), ``rows[i]`` is item i's 1-based
    data row (null: no evidence)."""

    entry: int = Field(ge=0)
    rows: list[int | None]


class AllVerdict(_Closed):
    all: CompactVerdict


class CompactBlock(_Closed):
    """A rule's pass and not-applicable records as columns, one entry per item (item order).

    Every column is a list as long as ``items`` or ``{"all": value}``. A ``message`` of null is
    the default wording rebuilt on reading (``<measure> = <value> <unit>; required <text>``);
    ``evidence`` entries index the document's ``evidence`` table (or, as a :class:`RowColumn`, give
    one row per item of one file); without ``requirement`` the
    rule summary's requirement applies to every item; ``{"ref": [rule, column]}`` is the same
    column of an earlier rule (rules over the same images share their item list)."""

    items: list[str] | ColumnRef
    verdict: list[CompactVerdict] | AllVerdict
    measured: list[Any] | AllSame | ColumnRef
    requirement: list[Requirement] | AllSame | ColumnRef | None = None
    evidence: list[list[int]] | AllSame | ColumnRef | RowColumn
    message: list[str | None] | AllSame | ColumnRef
    waiver_requested: list[dict[str, Any] | None] | AllSame | ColumnRef | None = None
    #: only when an item's reason is not its verdict's default (not applicable outside the sample,
    #: or by the measure's provider)
    reason: list[Reason | None] | AllSame | ColumnRef | None = None


class RuleSummary(_Closed):
    """One rule's outcome and everything its records share (compact records take it from here)."""

    rule: str
    title: str
    scope: str
    level: Level
    consequence: Consequence
    clause: str = Field(
        description="The clause as a reader cites it, e.g. 'JRC EUR 23638 EN, §12.7'."
    )
    clause_ref: str | None = None
    verdict: Verdict = Field(description="The worst verdict over the rule's items.")
    counts: dict[Verdict, int]
    offending: list[str] = Field(description="Items that failed, warned, lack evidence or erred.")
    error: str | None = None
    citation: Citation | None = None
    quote: str = ""
    manual: bool = False
    measure: str = ""
    unit: str | None = None
    requirement: Requirement | None = None
    audit: dict[str, Any] | None = None


class Summary(_Closed):
    rules: int = Field(ge=0)
    records: int = Field(ge=0)
    pass_: int = Field(alias="pass", ge=0)
    fail: int = Field(ge=0)
    warn: int = Field(ge=0)
    not_applicable: int = Field(ge=0)
    missing: int = Field(ge=0)
    error: int = Field(ge=0)
    waived: int = Field(ge=0)


class Rollup(_Open):
    rejected: dict[str, list[str]] = Field(
        description="Rejected items per scope (block, image...)."
    )
    reasons: list[str] = Field(
        description="Why the delivery is rejected (empty: nothing rejects it)."
    )
    incomplete: list[str] = Field(
        [],
        description="What the checker must still add or do before the check is complete (findings with "
        "consequence `incomplete`, manual checks without the checker's verdict), e.g. "
        "'B03: 6 more check points'. Non-empty and no reason: the verdict is `incomplete`.",
    )


class Tool(_Closed):
    name: str
    version: str


class ProfileRef(_Open):
    id: str
    version: str
    title: str | None = None
    sha256: str = Sha256
    source: dict[str, Any] | None = None
    extends: list[dict[str, str]] = []
    parameters: dict[str, dict[str, Any]]
    weakened: list[dict[str, Any]] = Field(
        [],
        description=(
            "Mandatory rules of the extended standard that this (tender) profile removed or made check less, "
            "each with its changes and justification (profile/changes.py)."
        ),
    )


class DeliveredFile(_Open):
    path: str
    sha256: str = Sha256
    bytes: int | None = None


class DeliveryRef(_Open):
    id: str
    path: str
    manifest_sha256: str = Sha256
    files: list[DeliveredFile]


class LedgerHead(_Closed):
    seq: int = Field(ge=0)
    hash: str = Sha256


class NssdaStatement(_Open):
    """One §3.2.3 statement (orthospec.metadata.nssda): the figure judged by ``rule`` for ``item``."""

    item: str
    axis: Literal["horizontal", "vertical"]
    value: float
    unit: Literal["m"]
    tested: bool = Field(
        description="'Tested' (independent reference confirmed) or 'Compiled to meet'."
    )
    valid: bool = Field(
        description="False when RMSE_min/RMSE_max < 0.6: the horizontal approximation does not hold."
    )
    rule: str
    text: str


class QcrDocument(_Open):
    """qcr.json: what `orthospec check` decided, why, on which evidence (docs/QCR.md)."""

    schema_: Literal["orthospec.qcr/1", "orthospec.qcr/2", "orthospec.qcr/3"] = Field(
        alias="schema"
    )
    tool: Tool
    date: str = Field(pattern=r"^\d{4}-\d{2}-\d{2}$")
    operator: str | None = Field(
        None,
        description="The checker who ran orthospec (--operator); null when not named. "
        "The contractor's QA operator is delivery.operator.",
    )
    checker: dict[str, Any] | None = Field(
        None, description="The checker's file (check --checker): party, file name and SHA-256."
    )
    profile: ProfileRef
    delivery: DeliveryRef
    verdict: Literal["accepted", "rejected", "incomplete"] = Field(
        description="accepted (exit 0), rejected (exit 1: a reason in rollup.reasons), or incomplete (exit 3: "
        "nothing rejects, but the checker's part is not complete: rollup.incomplete says what to add)."
    )
    fail_on: Literal["fail", "warn"] = "fail"
    summary: Summary
    rollup: Rollup
    waivers_unused: list[dict[str, Any]] = []
    manual_unused: list[dict[str, Any]] = Field(
        [],
        description="Checker-file manual verdicts that judged nothing the delivery lists "
        "(check, item, date, verdict, note, inspector, entry, checker_file, reason).",
    )
    waiver_requests: list[dict[str, Any]] = Field(
        [], description="The contractor's waiver requests and whether the checker granted them."
    )
    rules: list[RuleSummary]
    records: list[StoredRecord] | list[Record] = Field(
        description="Versions 2 and 3: every record whose verdict is not pass or not_applicable, each once, without "
        "its rule's text (StoredRecord). Version 1: every record, in full (Record)."
    )
    compact: dict[str, CompactBlock] = Field(
        {},
        description="Rule id -> its pass / not_applicable records as columns (versions 2 and 3).",
    )
    evidence: list[EvidenceRef] = Field(
        [], description="Evidence entries the compact columns index."
    )
    details: dict[str, Any] = {}
    ledger_head: LedgerHead | None = Field(
        None,
        description="The QCR ledger's chain head just before this run was recorded (check --ledger); "
        "`orthospec ledger verify --head` checks it later.",
    )
    sample: dict[str, Any] | None = Field(None, description="The sample checked (check --sample).")
    nssda: list[NssdaStatement] | None = Field(
        None,
        description="FGDC-STD-007.3-1998 §3.2.3 reporting statements, one per block and axis, when the "
        "profile judges an NSSDA figure ('Tested' only when the reference's independence passed).",
    )


def qcr_schema() -> dict[str, Any]:
    """JSON Schema of qcr.json, generated from :class:`QcrDocument`."""
    s = QcrDocument.model_json_schema(mode="validation", by_alias=True)
    s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    s["$id"] = SCHEMA_BASE + "qcr.schema.json"
    s["title"] = "orthospec quality control records (qcr.json)"
    return s


assert set(QcrDocument.model_fields["verdict"].annotation.__args__) == set(OVERALL)  # type: ignore[union-attr]
