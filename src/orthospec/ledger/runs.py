"""A recorded run as the store returns it, and the identity of delivered content.

Below store.py and history.py (both import it; history.py imports nothing else of the ledger),
so the round of a run is computed in one place whether the run is recorded
(``orthospec report --ledger --run N``) or about to be (``orthospec check --ledger``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from .chain import canonical, sha256_text


def content_key(manifest_sha256: str, files: Iterable[tuple[str, str]]) -> str:
    """Identity of what was delivered: the manifest's and every file's SHA-256 (not the delivery id:
    a redelivery may keep its id, JRC §12.8)."""
    return sha256_text(
        canonical([str(manifest_sha256), sorted((str(p), str(h)) for p, h in files)])
    )


def document_content_key(doc: Mapping[str, Any]) -> str:
    """``content_key`` of a QCR document not yet recorded (what ``Ledger.record`` will store)."""
    d = doc["delivery"]
    return content_key(d["manifest_sha256"], ((f["path"], f["sha256"]) for f in d.get("files", [])))


@dataclass(frozen=True)
class RunInfo:
    """One recorded check run (the row, without its QCRs and document)."""

    id: int
    seq: int
    recorded_at: str
    date: str
    project_id: str
    delivery_id: str
    delivery_path: str | None
    manifest_sha256: str
    profile_id: str
    profile_version: str
    profile_sha256: str
    verdict: str
    fail_on: str
    operator: str | None
    n_records: int
    summary: dict[str, Any]
    hash: str
    files: tuple[tuple[str, str], ...] = field(default=())  # (path, sha256)
    #: the key its audit state and rounds are kept under (None for runs recorded before schema 0002:
    #: their manifest project id stands in), and the earlier run whose content it continues
    audit_key: str | None = None
    continues_run: int | None = None
    #: who signed the run: the allowed-signers principal and the key (None: unsigned)
    signer: str | None = None
    key_fingerprint: str | None = None

    @property
    def content_key(self) -> str:
        """Identity of what was delivered: manifest and every file checksum."""
        return content_key(self.manifest_sha256, self.files)

    @property
    def audit(self) -> str:
        """The audit key, or for a run recorded before audit keys existed its manifest project id."""
        return self.audit_key or self.project_id


@dataclass(frozen=True)
class RecordedRun:
    """A run being recorded, as ``Ledger.record``'s ``before_commit`` sees it."""

    id: int
    seq: int
    hash: str  # its chain hash: the ledger head once it commits
    audit_key: str


def stated_project(doc: Mapping[str, Any]) -> str | None:
    """The contract / project id the checker states in the checker file (qcr.json ``checker.project``)."""
    chk = doc.get("checker") or {}
    v = chk.get("project") if isinstance(chk, Mapping) else None
    return str(v).strip() or None if v is not None else None


def lineage(runs: Sequence[RunInfo], key: str) -> list[RunInfo]:
    """The runs of one audit trail (oldest first): those kept under ``key`` and, transitively, every run
    under a key that a run of the trail continues by content, or that continues one of its runs;
    ``key`` may also be a manifest project id (the trails of the runs that carried it).

    A key is what the checker states, else what content continuity gave, else the manifest's
    project id: renaming ``project.id`` in a redelivery that continues earlier content, or under a
    checker file stating the contract, stays in the trail (issue 25 item 6)."""
    by_id = {r.id: r for r in runs}
    # a manifest project id names the trails of the runs that carried it (a lookup by what the
    # delivery says finds its trail; the trail itself is never split by it)
    keys, changed = {key} | {r.audit for r in runs if r.project_id == key}, True
    while changed:
        changed = False
        for r in runs:
            linked = by_id.get(r.continues_run) if r.continues_run is not None else None
            if r.audit in keys and linked is not None and linked.audit not in keys:
                keys.add(linked.audit)
                changed = True
            elif linked is not None and linked.audit in keys and r.audit not in keys:
                keys.add(r.audit)
                changed = True
    return [r for r in runs if r.audit in keys]
