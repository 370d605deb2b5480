"""The QCR ledger: an audit trail of check runs, sign-offs and audit levels (JRC §2.3-2.4, §12.8).

Open one with :func:`open_ledger` (a SQLite path, default ``./orthospec-ledger.sqlite`` or
``$ORTHOSPEC_LEDGER``; or a ``postgresql+psycopg://`` URL for a team server). The schema is
migrated by Alembic when the ledger is opened.
"""

from __future__ import annotations

import os

from .audit import (
    MARGIN,
    NORMAL,
    TIGHTENED,
    FamilyState,
    family_of,
    inspection_fractions,
    is_marginal,
)
from .history import Change, Diff, History, HistoryEntry
from .store import (
    DEFAULT_LEDGER,
    ENV_LEDGER,
    ROLES,
    Ledger,
    Problem,
    RunInfo,
    VerifyReport,
    default_ledger,
    open_ledger,
)

__all__ = [
    "DEFAULT_LEDGER",
    "ENV_LEDGER",
    "MARGIN",
    "NORMAL",
    "ROLES",
    "TIGHTENED",
    "Change",
    "Diff",
    "FamilyState",
    "History",
    "HistoryEntry",
    "Ledger",
    "Problem",
    "RunInfo",
    "VerifyReport",
    "audit_state",
    "default_ledger",
    "family_of",
    "head_for_check",
    "inspection_fractions",
    "is_marginal",
    "open_ledger",
    "sample_fraction",
]


def audit_state(ledger: Ledger | str | None, project: str, family: str) -> str:
    """``"normal"`` or ``"tightened"`` for a project's QCR family (ledger object, path or URL)."""
    if isinstance(ledger, Ledger):
        return ledger.audit_state(project, family)
    with open_ledger(ledger, create=False) as led:
        return led.audit_state(project, family)


def sample_fraction(ledger: Ledger | str | None, project: str, family: str, normal: float = 0.10,
                    tightened: float = 0.20) -> float:
    """Share of items the next check of this family should sample (``orthospec sample`` reads it)."""
    if isinstance(ledger, Ledger):
        return ledger.sample_fraction(project, family, normal, tightened)
    with open_ledger(ledger, create=False) as led:
        return led.sample_fraction(project, family, normal, tightened)


def head_for_check(
    target: str | None, *, allowed_signers: str | os.PathLike[str] | None = None
) -> dict[str, object]:
    """Open (or create) the ledger a check will record into, refuse it when it does not verify,
    and return its chain head ``{"seq", "hash"}`` for qcr.json (``ledger_head``).

    Meant to run *before* the check, so a bad ledger fails before any output is written.
    """
    from ..errors import LedgerError

    with open_ledger(target, allowed_signers=allowed_signers) as led:
        rep = led.verify()
        if not rep.ok:
            raise LedgerError(
                f"ledger {led.display} does not verify ({rep.problems[0]}); "
                "run `orthospec ledger verify` before recording more runs"
            )
        seq, head = led.head()
    return {"seq": seq, "hash": head}
