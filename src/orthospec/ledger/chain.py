"""Tamper evidence: canonical content of a ledger entry and its chained SHA-256.

An entry's hash is ``sha256(canonical_json({"kind", "content", "prev"}))`` where ``content`` is
every stored column of the entry (and, for a run, its file and QCR rows) and ``prev`` is the hash
of the entry before it. Editing any column, deleting any row or reordering entries breaks the
chain at that point; the head row catches removal of the newest entries.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from typing import Any


def canonical(obj: Any) -> str:
    """Sorted-key, compact JSON: the same content gives the same text on every database."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def sha256_text(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def run_hash(run: Mapping[str, Any], files: Sequence[Mapping[str, Any]],
             qcrs: Sequence[Mapping[str, Any]], prev: str) -> str:
    """Hash of a run row (without its own ``hash``), its files (by path) and QCRs (by ordinal)."""
    content = {
        "run": {k: v for k, v in run.items() if k != "hash"},
        "files": sorted(({k: v for k, v in f.items() if k != "run_id"} for f in files),
                        key=lambda f: f["path"]),
        "qcrs": sorted(({k: v for k, v in q.items() if k != "run_id"} for q in qcrs),
                       key=lambda q: q["ordinal"]),
    }
    return sha256_text(canonical({"kind": "run", "content": content, "prev": prev}))


def signoff_hash(signoff: Mapping[str, Any], prev: str) -> str:
    """Hash of a sign-off row; it embeds the signed run's hash, binding the two."""
    content = {k: v for k, v in signoff.items() if k != "hash"}
    return sha256_text(canonical({"kind": "signoff", "content": content, "prev": prev}))
