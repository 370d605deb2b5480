"""``ledger verify``: recompute every hash and link of the chain and list what does not match.

One pass over the ledger whatever its size: runs are read without their documents, then each
run's document and QCR rows on their own, the rows streamed in ordinal order a batch at a time.
"""

from __future__ import annotations

import io
import json
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Engine, select

from ..errors import LedgerError
from . import models as m
from .anchor import ENV_ANCHOR, read_anchors
from .chain import RunHasher, sha256_text, signoff_hash
from .db import BATCH
from .rows import QCR_COLUMNS, canonical_texts
from .signing import (
    check_signature,
    run_statement,
    signature_key,
    signoff_statement,
    verify_signature,
)


@dataclass(frozen=True)
class Problem:
    """One thing ``verify`` found wrong: which table, which row, what."""

    table: str
    key: str
    message: str

    def __str__(self) -> str:
        return f"{self.table} {self.key}: {self.message}"


@dataclass(frozen=True)
class VerifyReport:
    entries: int
    runs: int
    signoffs: int
    head_hash: str
    problems: tuple[Problem, ...]

    @property
    def ok(self) -> bool:
        return not self.problems


def verify_chain(engine: Engine, head: str | None = None, *, heads: Iterable[str] = (),
                 allowed_signers: Path | None = None) -> VerifyReport:
    """Recompute every hash and link and check every signature; list each edited, deleted or
    reordered row, and each signature that does not verify (by the allowed-signers file when
    given: the key must be registered to the name the entry records, at its recording date).

    ``head`` (and each of ``heads``): a chain hash noted outside the ledger earlier (printed on
    every report and in qcr.json). The chain must still contain it; a ledger whose newest
    entries were deleted and whose head row and links were rewritten to match is detected only
    this way. One pass over the ledger whatever the number of heads.

    Memory is bounded by one run's document and a batch of QCR rows: runs are read without
    their documents, then each run's document and rows on their own, rows streamed in order.
    """
    problems: list[Problem] = []
    who_checks: dict[tuple[str, str, str], list[tuple[str, str, bytes, str]]] = {}
    run_cols = [c for c in m.runs.c if c.name != "document"]
    with engine.connect() as conn:
        if conn.dialect.name == "postgresql":  # one snapshot for the whole pass (SQLite's read
            conn.execution_options(isolation_level="REPEATABLE READ")  # transaction is one)
        head_rows = conn.execute(select(m.head)).mappings().all()
        # the run rows without their documents (each read on its own below), the sign-offs
        runs = [dict(r) for r in conn.execute(select(*run_cols).order_by(m.runs.c.seq)).mappings()]
        signs = [
            dict(s) for s in conn.execute(select(m.signoffs).order_by(m.signoffs.c.seq)).mappings()
        ]
        run_ids = {r["id"] for r in runs}
        for table, t in (("run_files", m.run_files), ("qcrs", m.qcrs)):
            owners = conn.execute(select(t.c.run_id).distinct().order_by(t.c.run_id)).scalars()
            for rid in owners:
                if rid not in run_ids:
                    problems.append(Problem(table, f"run {rid}", "rows belong to no recorded run"))
        entries = sorted(
            [("run", r) for r in runs] + [("signoff", s) for s in signs], key=lambda e: e[1]["seq"]
        )
        run_hashes = {r["id"]: r["hash"] for r in runs}
        prev, expected_seq = m.GENESIS, 1
        for kind, row in entries:
            key = f"{kind} {row['id']} (seq {row['seq']})"
            table = "runs" if kind == "run" else "signoffs"
            if row["seq"] != expected_seq:
                problems.append(
                    Problem(
                        table,
                        key,
                        f"expected seq {expected_seq}: "
                        f"{row['seq'] - expected_seq} entr(y/ies) before it deleted",
                    )
                )
            if row["prev_hash"] != prev:
                problems.append(
                    Problem(
                        table,
                        key,
                        "prev_hash does not match the previous entry's hash "
                        "(an entry before it was deleted, edited or reordered)",
                    )
                )
            if kind == "run":
                h, n_qcrs, doc_ok = rehash_run(conn, row)
                if not doc_ok:
                    problems.append(Problem("runs", key, "document does not match document_sha256"))
                if n_qcrs != row["n_records"]:
                    problems.append(
                        Problem(
                            "qcrs", key, f"{n_qcrs} QCR rows, the run recorded {row['n_records']}"
                        )
                    )
            else:
                if run_hashes.get(row["run_id"]) != row["run_hash"]:
                    problems.append(
                        Problem(
                            "signoffs",
                            key,
                            f"signed run {row['run_id']} is missing or "
                            "its hash differs from the one signed",
                        )
                    )
                h = signoff_hash(row, row["prev_hash"])
            problems += _signature_problems(kind, table, key, row, who_checks)
            if h != row["hash"]:
                what = (
                    "its row, file or QCR rows were edited or deleted"
                    if kind == "run"
                    else "its row was edited"
                )
                problems.append(Problem(table, key, f"content hash mismatch: {what}"))
            prev, expected_seq = row["hash"], row["seq"] + 1
    if allowed_signers is not None:
        problems += _identity_problems(who_checks, allowed_signers)
    hashes = {row["hash"] for _k, row in entries}
    noted = ([head] if head is not None else []) + list(heads)
    problems += _head_problems(head_rows, hashes, prev, expected_seq - 1, noted)
    return VerifyReport(len(entries), len(runs), len(signs), prev, tuple(problems))


def _head_problems(
    head_rows: Sequence[Any], hashes: set[str], prev: str, last_seq: int, noted_heads: list[str]
) -> list[Problem]:
    """The head row ends the chain; every head in the anchor file and every head noted earlier
    (``noted_heads``) is in it."""
    problems: list[Problem] = []
    if len(head_rows) != 1:
        problems.append(Problem("ledger_head", "id 1", f"{len(head_rows)} head rows, expected 1"))
    else:
        hd = head_rows[0]
        if hd["seq"] != last_seq or hd["hash"] != prev:
            problems.append(
                Problem(
                    "ledger_head",
                    "id 1",
                    f"head says seq {hd['seq']} hash {hd['hash'][:12]}..., the chain ends at seq "
                    f"{last_seq} hash {prev[:12]}... (newest entries deleted or head edited)",
                )
            )
    anchors = read_anchors()
    for line, (a_seq, a_hash) in anchors:
        if a_hash not in hashes:
            problems.append(
                Problem(
                    "ledger_head",
                    f"anchor line {line}",
                    f"the head of seq {a_seq} ({a_hash[:16]}...) recorded in "
                    f"${ENV_ANCHOR} is not in the chain: entries were deleted or rewritten",
                )
            )
    for noted in noted_heads:
        want = noted.strip().lower()
        if len(want) < 12 or any(ch not in "0123456789abcdef" for ch in want):
            problems.append(
                Problem(
                    "ledger_head",
                    "anchor",
                    f"{noted!r} is not a chain hash (at least 12 "
                    "hex digits, as printed on a report)",
                )
            )
        elif not any(h.startswith(want) for h in hashes):
            problems.append(
                Problem(
                    "ledger_head",
                    "anchor",
                    f"the head {want[:16]}... noted earlier is not in the chain: entries up to it were deleted "
                    f"and the chain rewritten (the chain now ends at seq {last_seq} hash "
                    f"{prev[:12]}...)",
                )
            )
    return problems


def _signature_problems(
    kind: str,
    table: str,
    key: str,
    row: Mapping[str, Any],
    who_checks: dict[tuple[str, str, str], list[tuple[str, str, bytes, str]]],
) -> list[Problem]:
    """The signature of a run or sign-off row: made by the key the row records, valid for what the
    entry vouches for (:mod:`.signing`). Whether that key is the named person's is checked later, once
    per (name, key, day), from ``who_checks``."""
    armored = row.get("signature")
    if not armored:
        return []
    try:
        fingerprint, _ = signature_key(armored)
    except LedgerError as exc:
        return [Problem(table, key, f"signature unreadable: {exc}")]
    if fingerprint != row.get("key_fingerprint"):
        return [
            Problem(
                table,
                key,
                f"signature made by key {fingerprint}, the row records {row.get('key_fingerprint')}",
            )
        ]
    if kind == "run":
        message, who = run_statement(row["document_sha256"]), row.get("signer")
    else:
        message, who = signoff_statement(row), row.get("by_name")
    why = check_signature(message, armored)
    if why is not None:
        return [
            Problem(
                table,
                key,
                f"signature of {who or fingerprint} does not verify ({why}): the entry was "
                "changed after it was signed",
            )
        ]
    day = str(row.get("recorded_at") or "")[:10]
    who_checks.setdefault((str(who or ""), fingerprint, day), []).append(
        (table, key, message, armored)
    )
    return []


def _identity_problems(
    who_checks: Mapping[tuple[str, str, str], list[tuple[str, str, bytes, str]]],
    allowed_signers: Path,
) -> list[Problem]:
    """Each (name, key, day) of the signed entries against the allowed-signers file: one ssh-keygen
    run per combination (the signatures themselves are already checked), its verdict for all its entries."""
    out = []
    for (who, fingerprint, day), entries in who_checks.items():
        _table, _key, message, armored = entries[0]
        why = verify_signature(
            message,
            armored,
            principal=who or None,
            allowed_signers=allowed_signers,
            day=day or None,
        )
        if why is not None:
            out += [
                Problem(
                    table,
                    key,
                    f"signature of {who or fingerprint} does not verify against the allowed "
                    f"signers ({why}): the key {fingerprint} is not the one registered "
                    "for that name at that date",
                )
                for table, key, _m, _a in entries
            ]
    return out


def rehash_run(conn: Connection, run: Mapping[str, Any]) -> tuple[str, int, bool]:
    """(chain hash recomputed from the stored rows, QCR row count, document matches its sha256) of one
    run: the document read on its own, the QCR rows streamed in ordinal order a batch at a time."""
    rid = run["id"]
    document = conn.execute(select(m.runs.c.document).where(m.runs.c.id == rid)).scalar_one()
    doc_ok = sha256_text(document) == run["document_sha256"]
    files = [
        dict(f)
        for f in conn.execute(select(m.run_files).where(m.run_files.c.run_id == rid)).mappings()
    ]
    hasher = RunHasher(files, run["prev_hash"])
    cols = [m.qcrs.c[c] for c in QCR_COLUMNS]
    result = conn.execute(
        select(*cols)
        .where(m.qcrs.c.run_id == rid)
        .order_by(m.qcrs.c.ordinal)
        .execution_options(yield_per=BATCH)
    )  # PostgreSQL: a server-side cursor
    n = 0
    for part in result.partitions():
        hasher.qcr_texts(canonical_texts(part))
        n += len(part)
    full = {**run, "document": document}
    del document
    return hasher.hexdigest(full), n, doc_ok


_HEAD_TEXT = re.compile(r"ledger head[^0-9a-f]{0,80}?([0-9a-f]{64})", re.S)


def heads_in_file(path: Path) -> list[str]:
    """Ledger head hashes printed in a report (PDF metadata and page 1, HTML) or a qcr.json: what
    ``ledger verify --against`` and ``report --against`` check the chain still holds."""
    data = path.read_bytes()
    texts: list[str] = []
    if data[:5] == b"%PDF-":
        from pypdf import PdfReader

        reader = PdfReader(io.BytesIO(data))
        meta: Mapping[str, Any] = reader.metadata or {}
        texts.append(str(meta.get("/Subject") or ""))
        texts.append((reader.pages[0].extract_text() or "") if reader.pages else "")
    else:
        text = data.decode("utf-8", errors="replace")
        try:
            doc = json.loads(text)
        except ValueError:
            doc = None
        if isinstance(doc, dict):
            for key in ("ledger_head", "ledger"):
                v = doc.get(key)
                if isinstance(v, dict):
                    h = v.get("hash") if key == "ledger_head" else v.get("head")
                    if isinstance(h, str):
                        texts.append(f"ledger head {h}")
        texts.append(text)
    return list(dict.fromkeys(m for t in texts for m in _HEAD_TEXT.findall(t.replace("\n", ""))))
