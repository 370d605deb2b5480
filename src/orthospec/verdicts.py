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

# --- overall verdict of a delivery ---------------------------------------------------------------
ACCEPTED: Final = "accepted"
REJECTED: Final = "rejected"
Overall = Literal["accepted", "rejected"]
#: the overall verdicts, in the order the QCR schema lists them
OVERALL: Final[tuple[str, ...]] = (ACCEPTED, REJECTED)

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


def overall(rejected: bool) -> str:
    """The delivery's overall verdict from whether any reason rejects it."""
    return REJECTED if rejected else ACCEPTED
