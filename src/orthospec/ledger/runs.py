"""A recorded run as the store returns it, and the identity of delivered content.

Below store.py and history.py (both import it; history.py imports nothing else of the ledger),
so the round of a run is computed in one place whether the run is recorded
(``orthospec report --ledger --run N``) or about to be (``orthospec check --ledger``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from .chain import canonical, sha256_text


def content_key(manifest_sha256: str, files: Iterable[tuple[str, str]]) -> str:
    """Identity of what was delivered: the manifest's and every file's SHA-256 (not the delivery id:
    a redelivery may keep its id, JRC §12.8)."""
    return sha256_text(canonical([str(manifest_sha256), sorted((str(p), str(h)) for p, h in files)]))


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
    files: tuple[tuple[str, str], ...] = field(default=())   # (path, sha256)

    @property
    def content_key(self) -> str:
        """Identity of what was delivered: manifest and every file checksum."""
        return content_key(self.manifest_sha256, self.files)


