"""The verdict vocabulary: the one place the names of item and overall verdicts are spelled.

The engine, the QCR writers, the reports and the ledger import these names instead of spelling the
strings, so a verdict cannot be renamed (or misspelt) in one of them only. They are plain ``str``
constants (not an enum) so that ``==`` with the strings read back from a qcr.json, JSON, YAML and
SQLite all keep working unchanged. Standard library only: the start-up-critical commands may import it.
"""

from __future__ import annotations

from collections.abc import Iterable
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
CONSEQUENCES: Final[tuple[str, ...]] = (REJECT_ITEM, REJECT_BLOCK, RETURN_DELIVERY, INCOMPLETE, WARN)
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
