"""The verdict vocabulary: the one place the names of item and overall verdicts are spelled.

The engine, the QCR writers, the reports and the ledger import these names instead of spelling the
strings, so a verdict cannot be renamed (or misspelt) in one of them only. They are plain ``str``
constants (not an enum) so that ``==`` with the strings read back from a qcr.json, JSON, YAML and
SQLite all keep working unchanged. Standard library only: the start-up-critical commands may import it.
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import StrEnum
from typing import Final, Literal

# --- item verdicts (one per rule x item record) --------------------------------------------------
PASS: Final = "pass"
FAIL: Final = "fail"
WARN: Final = "warn"
NOT_APPLICABLE: Final = "not_applicable"
MISSING: Final = "missing"
ERROR: Final = "error"
WAIVED: Final = "waived"

Verdict = Literal["pass", "fail", "warn", "not_applicable", "missing", "error", "waived"]

#: every item verdict, in the order summaries print them; a verdict's index here is its integer
#: code in the evaluator's columnar arrays (``VERDICTS[code]``, ``CODE[name]``)
VERDICTS: Final[tuple[str, ...]] = (PASS, FAIL, WARN, NOT_APPLICABLE, MISSING, ERROR, WAIVED)
CODE: Final[dict[str, int]] = {v: i for i, v in enumerate(VERDICTS)}

#: worst first: a rule's (or a block's) overall verdict is the first of these among its items
SEVERITY: Final[tuple[str, ...]] = (ERROR, FAIL, MISSING, WARN, WAIVED, PASS, NOT_APPLICABLE)
#: verdicts a report lists as findings (in severity order)
PROBLEMS: Final[tuple[str, ...]] = (ERROR, FAIL, MISSING, WARN)
#: verdicts that can reject: nothing unmeasured passes, so missing and error count with fail
FAILING: Final[frozenset[str]] = frozenset({FAIL, MISSING, ERROR})
#: verdicts that say nothing about how the item performed (JUnit "skipped", audit-neutral)
NEUTRAL: Final[frozenset[str]] = frozenset({NOT_APPLICABLE, WAIVED})

# --- rule consequences (what a blocking finding does) --------------------------------------------
REJECT_ITEM: Final = "reject_item"
REJECT_BLOCK: Final = "reject_block"
RETURN_DELIVERY: Final = "return_delivery"
#: the finding is the checker's to fix (too few or bad check points, a short sample, an unsigned
#: manual check): the check is not complete, the contractor's products are not rejected for it
INCOMPLETE: Final = "incomplete"
Consequence = Literal["reject_item", "reject_block", "return_delivery", "incomplete", "warn"]
#: every consequence a rule may state, in the order the schemas list them
CONSEQUENCES: Final[tuple[str, ...]] = (
    REJECT_ITEM,
    REJECT_BLOCK,
    RETURN_DELIVERY,
    INCOMPLETE,
    WARN,
)
#: consequences that reject the contractor's products
REJECTING: Final[frozenset[str]] = frozenset({REJECT_ITEM, REJECT_BLOCK, RETURN_DELIVERY})

# --- overall verdict of a delivery ---------------------------------------------------------------
ACCEPTED: Final = "accepted"
REJECTED: Final = "rejected"
#: (and ``INCOMPLETE``, the same word as the consequence) the checker's part of the check is not
#: complete - a finding with consequence ``incomplete``, or a manual check without the checker's
#: verdict - and nothing rejects: never accepted, exit code 3
Overall = Literal["accepted", "rejected", "incomplete"]
#: the overall verdicts, in the order the QCR schema lists them
OVERALL: Final[tuple[str, ...]] = (ACCEPTED, REJECTED, INCOMPLETE)
#: the CLI's exit code per overall verdict (2 is "could not evaluate", raised before any verdict)
EXIT_CODES: Final[dict[str, int]] = {ACCEPTED: 0, REJECTED: 1, INCOMPLETE: 3}

_RANK: Final[dict[str, int]] = {v: i for i, v in enumerate(SEVERITY)}


def severity_rank(verdict: str) -> int:
    """Sort key, worst first (0 = error); an unknown name sorts after every known verdict."""
    return _RANK.get(verdict, len(SEVERITY))


def worst(verdicts: Iterable[str]) -> str:
    """The worst verdict among ``verdicts``; none at all is ``not_applicable`` (nothing was judged)."""
    present = set(verdicts)
    for v in SEVERITY:
        if v in present:
            return v
    return NOT_APPLICABLE


def overall(rejected: bool, incomplete: bool = False) -> str:
    """The delivery's overall verdict: any reason that rejects it wins (a real failure rejects
    whatever the checker still has to do); else an open checker's finding makes it incomplete."""
    if rejected:
        return REJECTED
    return INCOMPLETE if incomplete else ACCEPTED


def exit_code(verdict: str) -> int:
    """0 accepted, 1 rejected, 3 incomplete; anything else is treated as rejected (never 0)."""
    return EXIT_CODES.get(verdict, 1)


# --- reason codes (why a record is not a pass) ---------------------------------------------------
class Reason(StrEnum):
    """Why a record is not ``pass``: the cause beside the message (pandera's ``SchemaErrorReason``).

    The message is for people; the reason is for grouping (reports, JUnit, the ledger audit), so
    nothing reads a cause back from the message text. A ``str`` enum: it is written as its value
    (``"unset_parameter"``) and compares equal to the string read back from a qcr.json."""

    #: the measured value is outside the requirement (``fail``, or ``warn`` for a recommended rule)
    NOT_MET = "not_met"
    #: the requirement's threshold names a parameter nobody set (``missing``)
    UNSET_PARAMETER = "unset_parameter"
    #: a value in pixels cannot be converted without the item's GSD (``missing``)
    NO_GSD = "no_gsd"
    #: the threshold cannot be computed for the item (a measure it uses is missing) (``missing``)
    NO_THRESHOLD = "no_threshold"
    #: the threshold is not a finite number (``error``)
    BAD_THRESHOLD = "bad_threshold"
    #: the measure gives no value for the item (``missing``)
    NO_VALUE = "no_value"
    #: the rule has no item to judge at its scope (``missing``)
    NO_ITEMS = "no_items"
    #: the rule's `when` reads a fact the delivery does not give, and the condition depends on it
    UNKNOWN_FACT = "unknown_fact"
    #: the measure's provider could not read or compute the item's value (``error``)
    PROVIDER_ERROR = "provider_error"
    #: the requirement cannot be evaluated on the measure (units that do not convert, an expression
    #: that cannot be computed) (``error``)
    REQUIREMENT_ERROR = "requirement_error"
    #: the rule crashed (an internal error of orthospec, never the delivery's fault) (``error``)
    INTERNAL_ERROR = "internal_error"
    #: a manual check without the checker's verdict for the item (or for this content) (``missing``)
    UNSIGNED = "unsigned"
    #: ``not_applicable``: the rule's `when` is false for the item
    CONDITION_FALSE = "condition_false"
    #: ``not_applicable``: the measure's provider says the rule does not apply to the item
    PROVIDER_NOT_APPLICABLE = "provider_not_applicable"
    #: ``not_applicable``: with ``check --sample``, the item is outside the external QC sample
    OUTSIDE_SAMPLE = "outside_sample"
    #: ``waived``: a waiver in force covers the finding
    WAIVED = "waived"


#: every reason code, in the order the schemas list them
REASONS: Final[tuple[str, ...]] = tuple(r.value for r in Reason)

#: the reason of a record whose rule gave none, by verdict (None: a pass needs no reason)
DEFAULT_REASON: Final[dict[str, Reason | None]] = {
    PASS: None,
    FAIL: Reason.NOT_MET,
    WARN: Reason.NOT_MET,
    NOT_APPLICABLE: Reason.CONDITION_FALSE,
    MISSING: Reason.NO_VALUE,
    ERROR: Reason.PROVIDER_ERROR,
    WAIVED: Reason.WAIVED,
}


#: the reasons a record of each verdict may carry (a rule's reason for another verdict - the verdict
#: was changed after, by a waiver say - gives way to the verdict's default)
ALLOWED_REASONS: Final[dict[str, frozenset[str]]] = {
    PASS: frozenset(),
    FAIL: frozenset({Reason.NOT_MET}),
    WARN: frozenset({Reason.NOT_MET}),
    NOT_APPLICABLE: frozenset(
        {Reason.CONDITION_FALSE, Reason.PROVIDER_NOT_APPLICABLE, Reason.OUTSIDE_SAMPLE}
    ),
    MISSING: frozenset(
        {
            Reason.UNSET_PARAMETER,
            Reason.NO_GSD,
            Reason.NO_THRESHOLD,
            Reason.NO_VALUE,
            Reason.NO_ITEMS,
            Reason.UNKNOWN_FACT,
            Reason.UNSIGNED,
        }
    ),
    ERROR: frozenset(
        {
            Reason.BAD_THRESHOLD,
            Reason.PROVIDER_ERROR,
            Reason.REQUIREMENT_ERROR,
            Reason.INTERNAL_ERROR,
        }
    ),
    WAIVED: frozenset({Reason.WAIVED}),
}


def reason_of(verdict: str, given: object = None) -> str | None:
    """The reason code a record of ``verdict`` carries: the rule's own (``given``) when it is one a
    record of that verdict may carry, else the verdict's default; None for a pass."""
    if given is not None and given in ALLOWED_REASONS.get(verdict, ()):
        return str(given.value if isinstance(given, Reason) else given)
    d = DEFAULT_REASON.get(verdict)
    return d.value if d is not None else None
