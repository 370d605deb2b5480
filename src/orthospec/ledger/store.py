"""The QCR ledger store: SQLite file or PostgreSQL server, through SQLAlchemy 2 + Alembic.

JRC §2.4 asks that QCRs be dated, identify the item and the operator, and may be countersigned;
§12.8 asks that redeliveries be re-checked "until the products are finally acceptable". The
ledger keeps that trail: every ``check`` run (profile, delivery, file checksums, every QCR),
sign-offs, and a hash chain over all of it (see :mod:`.chain`).

Writes are one transaction each: the chain head row is locked first (``BEGIN IMMEDIATE`` on
SQLite, ``SELECT ... FOR UPDATE`` on PostgreSQL), so concurrent writers queue and a process
killed mid-write leaves the ledger exactly as it was.

Test hook: with ``ORTHOSPEC_LEDGER_PAUSE=<seconds>`` a write sleeps just before its commit, after
touching the file named by ``ORTHOSPEC_LEDGER_PAUSE_MARKER`` (if set), so a test can kill it there.
"""

from __future__ import annotations

import datetime as dt
import itertools
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Engine, create_engine, event, func, select, text, update
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, DBAPIError, NoSuchModuleError, OperationalError

from .. import verdicts as V
from ..errors import LedgerError
from . import models as m
from .audit import MARGIN, NORMAL, TIGHTENED, FamilyState, RunRecords, audit_states
from .chain import RunHasher, canonical, sha256_text, signoff_hash
from .history import (
    Diff,
    History,
    build_history,
    diff_verdicts,
    history_rows,
    history_rows_before_recording,
)
from .rows import QCR_COLUMNS, Row, canonical_texts, rows_with_text
from .runs import RunInfo

#: the file used when neither ``--ledger`` nor ``ORTHOSPEC_LEDGER`` names one
DEFAULT_LEDGER = "orthospec-ledger.sqlite"
ENV_LEDGER = "ORTHOSPEC_LEDGER"
#: an append-only file outside the ledger that receives every new chain head ("seq hash" lines);
#: `verify` then checks that each head in it is still in the chain (an external anchor)
ENV_ANCHOR = "ORTHOSPEC_LEDGER_ANCHOR"
ROLES = ("supervisor", "inspector", "auditor", "operator")
_PG_LOCK_KEY = 0x6F72_7468  # advisory lock serialising schema upgrades on a shared server


def default_ledger() -> str:
    """``$ORTHOSPEC_LEDGER`` if set, else ``./orthospec-ledger.sqlite``."""
    return os.environ.get(ENV_LEDGER) or DEFAULT_LEDGER


def to_url(target: str | os.PathLike[str]) -> str:
    """A SQLAlchemy URL for a path or URL; ``postgresql://`` is served by psycopg 3."""
    s = os.fspath(target)
    if "://" not in s:
        return f"sqlite:///{Path(s).expanduser().absolute().as_posix()}"
    if s.startswith(("postgresql://", "postgres://")):
        return "postgresql+psycopg://" + s.split("://", 1)[1]
    return s


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


def _now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


def _maybe_pause() -> None:
    """Test hook: hold the open write transaction so a test can kill the process inside it."""
    seconds = os.environ.get("ORTHOSPEC_LEDGER_PAUSE")
    if not seconds:
        return
    marker = os.environ.get("ORTHOSPEC_LEDGER_PAUSE_MARKER")
    if marker:
        Path(marker).write_text(str(os.getpid()), encoding="utf-8")
    time.sleep(float(seconds))


class Ledger:
    """An open ledger. Use :func:`open_ledger`; close it (or use ``with``) when done."""

    def __init__(self, engine: Engine, display: str) -> None:
        self.engine = engine
        self.display = display
        self._writer = engine.execution_options(ledger_write=True)

    # --- lifecycle ---------------------------------------------------------------------------

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Ledger:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _write(self) -> Iterator[tuple[Connection, int, str]]:
        """A write transaction holding the chain head: yields (conn, head seq, head hash)."""
        try:
            with self._writer.begin() as conn:
                row = conn.execute(select(m.head.c.seq, m.head.c.hash).where(m.head.c.id == 1)
                                   .with_for_update()).one_or_none()
                if row is None:
                    raise LedgerError(f"{self.display}: the chain head row is missing; "
                                      "run `orthospec ledger verify`")
                yield conn, int(row.seq), str(row.hash)
        except DBAPIError as exc:
            raise LedgerError(f"{self.display}: write failed, nothing recorded: "
                              f"{str(exc.orig).strip()}") from None

    def _read(self) -> Any:
        return self.engine.connect()

    # --- writing -----------------------------------------------------------------------------

    def record(self, document: Mapping[str, Any], *, recorded_at: str | None = None) -> int:
        """Record one check run (its qcr.json document) and return the new run id.

        One transaction. The QCR rows are made from the document's compact columns a batch at a
        time, inserted (executemany) and fed to the chain hash batch by batch: memory stays bounded
        by the batch, whatever the number of check points. The run row goes in first (the QCR
        rows refer to it) and gets its count and hash at the end, once every row is hashed.
        """
        # dumps: the exact qcr.json text (its sha256 matches the file's); every QCR version it reads
        from ..qcr import SCHEMA_IDS, dumps

        if not isinstance(document, Mapping) or document.get("schema") not in SCHEMA_IDS:
            got = document.get("schema") if isinstance(document, Mapping) else type(document).__name__
            raise LedgerError(f"not a QCR document: schema {got!r}, expected one of "
                              f"{', '.join(map(repr, SCHEMA_IDS))} (qcr.json)")
        try:
            d = document["delivery"]
            p = document["profile"]
            project = str((d.get("project") or {}).get("id") or "")
            doc_text = dumps(dict(document))
            rollup = document.get("rollup") or {}
            summary = {"counts": document.get("summary", {}), "rejected": rollup.get("rejected", {}),
                       "reasons": rollup.get("reasons", [])}
            files = [{"path": str(f["path"]), "sha256": str(f["sha256"]),
                      "bytes": None if f.get("bytes") is None else int(f["bytes"])}
                     for f in d.get("files", [])]
            fields: dict[str, Any] = {
                "date": str(document["date"]), "project_id": project, "delivery_id": str(d["id"]),
                "delivery_path": d.get("path"), "manifest_sha256": str(d["manifest_sha256"]),
                "profile_id": str(p["id"]), "profile_version": str(p["version"]),
                "profile_sha256": str(p["sha256"]), "verdict": str(document["verdict"]),
                "fail_on": str(document.get("fail_on", V.FAIL)), "operator": document.get("operator"),
                "n_records": 0, "summary": canonical(summary), "document": doc_text,
                "document_sha256": sha256_text(doc_text),
            }
        except (KeyError, TypeError, AttributeError) as exc:
            raise LedgerError(f"not a QCR document (missing {exc}); expected qcr.json structure") from None
        if not project:
            raise LedgerError(f"delivery {d.get('id')!r}: manifest has no project.id; "
                              "the ledger files runs by project")
        rows = rows_with_text(document)
        with self._write() as (conn, seq, prev):
            run_id = int(conn.execute(select(func.coalesce(func.max(m.runs.c.id), 0))).scalar_one()) + 1
            row: dict[str, Any] = {"id": run_id, "seq": seq + 1, "recorded_at": recorded_at or _now(),
                                   **fields, "prev_hash": prev}
            conn.execute(m.runs.insert(), {**row, "hash": ""})
            if files:
                conn.execute(m.run_files.insert(), [{"run_id": run_id, **f} for f in files])
            hasher = RunHasher(files, prev)
            insert = _qcr_writer(conn, run_id, self.display)
            n = 0
            while batch := _next_batch(rows):
                hasher.qcr_texts([text for _, text in batch])
                insert([values for values, _ in batch])
                n += len(batch)
            row["n_records"] = n
            row["hash"] = hasher.hexdigest(row)
            conn.execute(update(m.runs).where(m.runs.c.id == run_id).values(n_records=n, hash=row["hash"]))
            conn.execute(update(m.head).where(m.head.c.id == 1).values(seq=seq + 1, hash=row["hash"]))
            _maybe_pause()
        _anchor(seq + 1, row["hash"])
        return run_id

    def signoff(self, run_id: int, *, by: str, role: str = "supervisor", date: str | None = None,
                note: str | None = None, manual: Mapping[str, str] | None = None,
                recorded_at: str | None = None, acknowledge_rejection: bool = False) -> int:
        """Countersign a run (JRC §2.4), optionally with manual-check verdicts; returns its id.

        Refused, with the reason: the run's own checker countersigning it (JRC §2.4 asks for an
        independent countersignature), the same person signing the same run in the same role again
        without new manual verdicts, a date before the run, and a rejected run without
        ``acknowledge_rejection`` (recorded in the note, so it is part of the hashed entry).
        """
        if not by.strip():
            raise LedgerError("sign-off needs the name of the person signing (--by)")
        if role not in ROLES:
            raise LedgerError(f"sign-off role {role!r}: expected one of {', '.join(ROLES)}")
        day = date or dt.date.today().isoformat()
        try:
            dt.date.fromisoformat(day)
        except ValueError:
            raise LedgerError(f"sign-off date {day!r}: expected YYYY-MM-DD") from None
        verdicts = dict(manual or {})
        bad = {k: v for k, v in verdicts.items() if v not in (V.PASS, V.FAIL)}
        if bad:
            raise LedgerError(f"manual verdicts {bad}: each must be 'pass' or 'fail'")
        with self._write() as (conn, seq, prev):
            run = conn.execute(select(m.runs.c.hash, m.runs.c.date, m.runs.c.operator, m.runs.c.verdict)
                               .where(m.runs.c.id == run_id)).one_or_none()
            if run is None:
                raise LedgerError(f"{self.display}: no run {run_id}")
            if verdicts:
                manual_rules = set(conn.execute(
                    select(m.qcrs.c.rule).where(m.qcrs.c.run_id == run_id, m.qcrs.c.manual.is_(True))
                ).scalars())
                unknown = sorted(set(verdicts) - manual_rules)
                if unknown:
                    raise LedgerError(
                        f"run {run_id} has no manual rule {', '.join(unknown)}; manual rules of this run: "
                        f"{', '.join(sorted(manual_rules)) or 'none'}")
            if day < run.date:
                raise LedgerError(f"sign-off date {day} is before run {run_id} ({run.date}): "
                                  "a run cannot be countersigned before it was made")
            if run.operator and _same_person(run.operator, by) and role != "operator":
                raise LedgerError(f"{by.strip()} ran check run {run_id} (its checker) and cannot countersign "
                                  f"it as {role}: JRC §2.4 asks for an independent countersignature")
            if run.verdict == V.REJECTED and not acknowledge_rejection:
                raise LedgerError(f"run {run_id} was REJECTED; signing it records that you accept that "
                                  "verdict: repeat with --acknowledge-rejection (CLI) to sign anyway")
            earlier = conn.execute(select(m.signoffs.c.by_name, m.signoffs.c.role, m.signoffs.c.manual,
                                          m.signoffs.c.date)
                                   .where(m.signoffs.c.run_id == run_id)).all()
            for e in earlier:
                if _same_person(e.by_name, by) and e.role == role:
                    signed = json.loads(e.manual)
                    if not verdicts or all(signed.get(k) == v for k, v in verdicts.items()):
                        raise LedgerError(f"{by.strip()} already signed run {run_id} as {role} on {e.date}: "
                                          "a duplicate sign-off is refused")
            if acknowledge_rejection and run.verdict == V.REJECTED:
                note = ACK_PREFIX + (f" {note}" if note else "")
            sid = int(conn.execute(select(func.coalesce(func.max(m.signoffs.c.id), 0))).scalar_one()) + 1
            row: dict[str, Any] = {
                "id": sid, "seq": seq + 1, "run_id": run_id, "run_hash": run.hash,
                "recorded_at": recorded_at or _now(), "date": day, "by_name": by.strip(), "role": role,
                "note": note, "manual": canonical(dict(sorted(verdicts.items()))), "prev_hash": prev,
            }
            row["hash"] = signoff_hash(row, prev)
            conn.execute(m.signoffs.insert(), row)
            conn.execute(update(m.head).where(m.head.c.id == 1).values(seq=seq + 1, hash=row["hash"]))
            _maybe_pause()
        _anchor(seq + 1, row["hash"])
        return sid

    # --- reading -----------------------------------------------------------------------------

    def runs(self, project: str | None = None, *, ids: Iterable[int] | None = None) -> list[RunInfo]:
        """Runs oldest first (chain order), optionally of one project or with given ids."""
        cols = [c for c in m.runs.c if c.name != "document"]
        q = select(*cols).order_by(m.runs.c.seq)
        if project is not None:
            q = q.where(m.runs.c.project_id == project)
        if ids is not None:
            q = q.where(m.runs.c.id.in_(list(ids)))
        with self._read() as conn:
            rows = conn.execute(q).mappings().all()
            ids = [r["id"] for r in rows]
            files: dict[int, list[tuple[str, str]]] = {}
            if ids:
                for f in conn.execute(select(m.run_files).where(m.run_files.c.run_id.in_(ids))):
                    files.setdefault(f.run_id, []).append((f.path, f.sha256))
        return [_run_info(r, files.get(r["id"], [])) for r in rows]

    def run(self, run_id: int) -> RunInfo:
        for r in self.runs(ids=[run_id]):
            return r
        raise LedgerError(f"{self.display}: no run {run_id} (see `orthospec ledger runs`)")

    def projects(self) -> list[str]:
        with self._read() as conn:
            return list(conn.execute(select(m.runs.c.project_id).distinct()
                                     .order_by(m.runs.c.project_id)).scalars())

    def document(self, run_id: int) -> dict[str, Any]:
        """The qcr.json document exactly as the run produced it."""
        with self._read() as conn:
            doc = conn.execute(select(m.runs.c.document).where(m.runs.c.id == run_id)).scalar_one_or_none()
        if doc is None:
            raise LedgerError(f"{self.display}: no run {run_id} (see `orthospec ledger runs`)")
        return json.loads(doc)

    def signoffs(self, run_id: int | None = None) -> list[dict[str, Any]]:
        """Sign-offs ({id, run, by, role, date, note, manual, recorded_at}) in chain order."""
        q = select(m.signoffs).order_by(m.signoffs.c.seq)
        if run_id is not None:
            q = q.where(m.signoffs.c.run_id == run_id)
        with self._read() as conn:
            rows = conn.execute(q).mappings().all()
        return [{"id": r["id"], "run": r["run_id"], "by": r["by_name"], "role": r["role"],
                 "date": r["date"], "note": r["note"], "manual": json.loads(r["manual"]),
                 "recorded_at": r["recorded_at"]} for r in rows]

    def report_document(self, run_id: int) -> dict[str, Any]:
        """What a report of ``run_id`` shows: its document, sign-offs and the project's sequence of
        deliveries, redeliveries and verdicts up to that run (JRC §12.8: redeliver until acceptable)."""
        from .signed import after_signoff

        doc = self.document_with_signoffs(run_id)
        run = self.run(run_id)
        signed = after_signoff(doc, self.signoffs(run_id))
        if signed is not None:
            doc["after_signoff"] = signed
        entries = [e for e in self.history(run.project_id).entries if e.run.seq <= run.seq]
        doc["history"] = history_rows(entries, current_run=run_id)
        return doc

    def document_with_signoffs(self, run_id: int) -> dict[str, Any]:
        """The stored qcr document plus ``signoffs`` [{by, role, date, note, manual}] for reports."""
        doc = self.document(run_id)
        doc["signoffs"] = [{k: s[k] for k in ("by", "role", "date", "note", "manual")}
                           for s in self.signoffs(run_id)]
        seq, head = self.head()
        rep = self.verify()
        doc["ledger"] = {"run": run_id, "hash": self.run(run_id).hash, "head": head, "head_seq": seq,
                         "problems": [str(p) for p in rep.problems]}
        return doc

    def qcrs(self, run_id: int) -> list[dict[str, Any]]:
        """The run's QCR rows (ordinal order); ``measured``/``requirement`` decoded from JSON."""
        with self._read() as conn:
            rows = conn.execute(select(m.qcrs).where(m.qcrs.c.run_id == run_id)
                                .order_by(m.qcrs.c.ordinal)).mappings().all()
        out = []
        for r in rows:
            d = dict(r)
            d["measured"] = json.loads(d["measured"])
            d["requirement"] = json.loads(d["requirement"])
            out.append(d)
        return out

    def manual_verdicts(self, run_id: int) -> dict[str, str]:
        """Manual verdicts signed off for a run; a later sign-off overrides an earlier one."""
        out: dict[str, str] = {}
        for s in self.signoffs(run_id):
            out.update(s["manual"])
        return out

    def effective_verdicts(self, run_id: int) -> dict[tuple[str, str], str]:
        """(rule, item) -> verdict, with signed-off manual verdicts applied.

        Delivery-scope records about the delivery itself are keyed ``(rule, "delivery")``: a
        redelivery usually carries a new delivery id, yet it answers the same requirement. Other
        delivery-scope items (e.g. a parameter name) keep their own stable key.
        """
        manual = self.manual_verdicts(run_id)
        did = self.run(run_id).delivery_id
        return {(q["rule"], "delivery" if q["scope"] == "delivery" and q["item"] == did else q["item"]):
                manual.get(q["rule"], q["verdict"]) for q in self.qcrs(run_id)}

    # --- history and diff ---------------------------------------------------------------------

    def history(self, project: str | None = None) -> History:
        """Deliveries, redeliveries and re-checks with verdicts per run, rule and block."""
        runs = self.runs(project)
        ids = [r.id for r in runs]
        qrows: dict[int, list[Mapping[str, Any]]] = {i: [] for i in ids}
        if ids:
            cols = (m.qcrs.c.run_id, m.qcrs.c.rule, m.qcrs.c.item, m.qcrs.c.scope, m.qcrs.c.verdict)
            with self._read() as conn:
                for row in conn.execute(select(*cols).where(m.qcrs.c.run_id.in_(ids))).mappings():
                    qrows[row["run_id"]].append(row)
        manual: dict[int, dict[str, str]] = {}
        counts: dict[int, int] = {}
        for s in self.signoffs():
            manual.setdefault(s["run"], {}).update(s["manual"])
            counts[s["run"]] = counts.get(s["run"], 0) + 1
        return build_history(project, runs, qrows, manual, counts)

    def history_before_recording(self, doc: Mapping[str, Any]) -> list[dict[str, Any]]:
        """The JRC §12.8 sequence a report rendered *before* ``record(doc)`` shows: the project's
        recorded runs, then this run (``"run": "new"``) with the round it will be recorded with."""
        project = str((doc["delivery"].get("project") or {}).get("id") or "")
        return history_rows_before_recording(self.history(project).entries, doc)

    def diff(self, run_a: int, run_b: int) -> Diff:
        """Per (rule, item): fixed, newly failing, still failing, changed, added, removed."""
        self.run(run_a), self.run(run_b)  # a clear error for an unknown id
        return diff_verdicts(run_a, run_b, self.effective_verdicts(run_a), self.effective_verdicts(run_b))

    # --- audit state -------------------------------------------------------------------------

    def audit_states(self, project: str, *, margin: float = MARGIN) -> dict[str, FamilyState]:
        """Normal/Tightened state of every QCR family the project's runs touched."""
        runs = self.runs(project)
        ids = [r.id for r in runs]
        cols = (m.qcrs.c.run_id, m.qcrs.c.rule, m.qcrs.c.item, m.qcrs.c.verdict, m.qcrs.c.family,
                m.qcrs.c.measured, m.qcrs.c.requirement)
        per_run: dict[int, list[Mapping[str, Any]]] = {i: [] for i in ids}
        if ids:
            with self._read() as conn:
                for row in conn.execute(select(*cols).where(m.qcrs.c.run_id.in_(ids))
                                        .order_by(m.qcrs.c.run_id, m.qcrs.c.ordinal)).mappings():
                    per_run[row["run_id"]].append(row)
        manual: dict[int, dict[str, str]] = {}
        for s in self.signoffs():
            if s["run"] in per_run:
                manual.setdefault(s["run"], {}).update(s["manual"])
        return audit_states((RunRecords(i, per_run[i], manual.get(i, {})) for i in ids), margin=margin)

    def audit_state(self, project: str, family: str, *, margin: float = MARGIN) -> str:
        """``"normal"`` or ``"tightened"``; a family never checked is normal."""
        st = self.audit_states(project, margin=margin).get(family)
        return st.state if st is not None else NORMAL

    def sample_fraction(self, project: str, family: str, normal: float = 0.10,
                        tightened: float = 0.20, *, margin: float = MARGIN) -> float:
        """Share of items to sample next for this family: larger while it is tightened."""
        return tightened if self.audit_state(project, family, margin=margin) == TIGHTENED else normal

    def suspect_items(self, project: str, family: str, *, margin: float = MARGIN) -> tuple[str, ...]:
        """Items that failed or were marginal in the family's last run: the tightened trail."""
        st = self.audit_states(project, margin=margin).get(family)
        return st.suspect_items if st is not None and st.state == TIGHTENED else ()

    # --- verification ------------------------------------------------------------------------

    def head(self) -> tuple[int, str]:
        """(seq, hash) of the chain head row: the anchor a report prints and `verify --head` checks."""
        with self._read() as conn:
            row = conn.execute(select(m.head.c.seq, m.head.c.hash).where(m.head.c.id == 1)).one_or_none()
        if row is None:
            raise LedgerError(f"{self.display}: the chain head row is missing; run `orthospec ledger verify`")
        return int(row.seq), str(row.hash)

    def verify(self, head: str | None = None, *, heads: Iterable[str] = ()) -> VerifyReport:
        """Recompute every hash and link; list each edited, deleted or reordered row.

        ``head`` (and each of ``heads``): a chain hash noted outside the ledger earlier (printed on
        every report and in qcr.json). The chain must still contain it; a ledger whose newest
        entries were deleted and whose head row and links were rewritten to match is detected only
        this way. One pass over the ledger whatever the number of heads.

        Memory is bounded by one run's document and a batch of QCR rows: runs are read without
        their documents, then each run's document and rows on their own, rows streamed in order.
        """
        problems: list[Problem] = []
        run_cols = [c for c in m.runs.c if c.name != "document"]
        with self._read() as conn:
            if conn.dialect.name == "postgresql":  # one snapshot for the whole pass (SQLite's read
                conn.execution_options(isolation_level="REPEATABLE READ")  # transaction is one)
            head_rows = conn.execute(select(m.head)).mappings().all()
            # the run rows without their documents (each read on its own below), the sign-offs
            runs = [dict(r) for r in conn.execute(select(*run_cols).order_by(m.runs.c.seq)).mappings()]
            signs = [dict(s) for s in conn.execute(select(m.signoffs).order_by(m.signoffs.c.seq)).mappings()]
            run_ids = {r["id"] for r in runs}
            for table, t in (("run_files", m.run_files), ("qcrs", m.qcrs)):
                owners = conn.execute(select(t.c.run_id).distinct().order_by(t.c.run_id)).scalars()
                for rid in owners:
                    if rid not in run_ids:
                        problems.append(Problem(table, f"run {rid}", "rows belong to no recorded run"))
            entries = sorted([("run", r) for r in runs] + [("signoff", s) for s in signs],
                             key=lambda e: e[1]["seq"])
            run_hashes = {r["id"]: r["hash"] for r in runs}
            prev, expected_seq = m.GENESIS, 1
            for kind, row in entries:
                key = f"{kind} {row['id']} (seq {row['seq']})"
                table = "runs" if kind == "run" else "signoffs"
                if row["seq"] != expected_seq:
                    problems.append(Problem(table, key, f"expected seq {expected_seq}: "
                                            f"{row['seq'] - expected_seq} entr(y/ies) before it deleted"))
                if row["prev_hash"] != prev:
                    problems.append(Problem(table, key, "prev_hash does not match the previous entry's hash "
                                            "(an entry before it was deleted, edited or reordered)"))
                if kind == "run":
                    h, n_qcrs, doc_ok = _rehash_run(conn, row)
                    if not doc_ok:
                        problems.append(Problem("runs", key, "document does not match document_sha256"))
                    if n_qcrs != row["n_records"]:
                        problems.append(Problem("qcrs", key, f"{n_qcrs} QCR rows, the run recorded "
                                                f"{row['n_records']}"))
                else:
                    if run_hashes.get(row["run_id"]) != row["run_hash"]:
                        problems.append(Problem("signoffs", key, f"signed run {row['run_id']} is missing or "
                                                "its hash differs from the one signed"))
                    h = signoff_hash(row, row["prev_hash"])
                if h != row["hash"]:
                    what = ("its row, file or QCR rows were edited or deleted" if kind == "run"
                            else "its row was edited")
                    problems.append(Problem(table, key, f"content hash mismatch: {what}"))
                prev, expected_seq = row["hash"], row["seq"] + 1
        if len(head_rows) != 1:
            problems.append(Problem("ledger_head", "id 1", f"{len(head_rows)} head rows, expected 1"))
        else:
            hd = head_rows[0]
            if hd["seq"] != expected_seq - 1 or hd["hash"] != prev:
                problems.append(Problem(
                    "ledger_head", "id 1",
                    f"head says seq {hd['seq']} hash {hd['hash'][:12]}..., the chain ends at seq "
                    f"{expected_seq - 1} hash {prev[:12]}... (newest entries deleted or head edited)"))
        anchors = _read_anchors()
        hashes = {row["hash"] for _k, row in entries}
        for line, (a_seq, a_hash) in anchors:
            if a_hash not in hashes:
                problems.append(Problem("ledger_head", f"anchor line {line}",
                                        f"the head of seq {a_seq} ({a_hash[:16]}...) recorded in "
                                        f"${ENV_ANCHOR} is not in the chain: entries were deleted or rewritten"))
        for noted in ([head] if head is not None else []) + list(heads):
            want = noted.strip().lower()
            if len(want) < 12 or any(ch not in "0123456789abcdef" for ch in want):
                problems.append(Problem("ledger_head", "anchor", f"{noted!r} is not a chain hash (at least 12 "
                                        "hex digits, as printed on a report)"))
            elif not any(h.startswith(want) for h in hashes):
                problems.append(Problem(
                    "ledger_head", "anchor",
                    f"the head {want[:16]}... noted earlier is not in the chain: entries up to it were deleted "
                    f"and the chain rewritten (the chain now ends at seq {expected_seq - 1} hash {prev[:12]}...)"))
        return VerifyReport(len(entries), len(runs), len(signs), prev, tuple(problems))


#: QCR rows per executemany and per hash update (a few MB of rows at a time)
BATCH = 5000


def _next_batch(rows: Iterator[Row]) -> list[Row]:
    """The next rows of ``rows_with_text`` (empty at the end); a malformed document is a LedgerError."""
    try:
        return list(itertools.islice(rows, BATCH))
    except (KeyError, TypeError, AttributeError) as exc:
        raise LedgerError(f"not a QCR document (missing {exc}); expected qcr.json structure") from None


def _qcr_writer(conn: Connection, run_id: int, display: str) -> Callable[[list[tuple[Any, ...]]], None]:
    """Writes a batch of QCR rows (value tuples in :data:`QCR_COLUMNS` order) of run ``run_id`` in
    the open transaction: PostgreSQL by COPY (one stream, not a statement per row), SQLite by
    executemany of one INSERT with positional parameters (they bind faster than named ones)."""
    q = conn.dialect.identifier_preparer.quote
    columns = f"{q('run_id')}, {', '.join(q(c) for c in QCR_COLUMNS)}"
    if conn.dialect.name == "postgresql":
        import psycopg

        copy = f"COPY {q(m.qcrs.name)} ({columns}) FROM STDIN"
        dbapi: Any = conn.connection.dbapi_connection  # the transaction's own connection

        def write_pg(batch: list[tuple[Any, ...]]) -> None:
            try:
                with dbapi.cursor() as cur, cur.copy(copy) as out:
                    for values in batch:
                        out.write_row((run_id, *values))
            except psycopg.Error as exc:
                raise LedgerError(f"{display}: write failed, nothing recorded: {str(exc).strip()}") from None

        return write_pg
    insert = f"INSERT INTO {q(m.qcrs.name)} ({columns}) VALUES ({int(run_id)}, {', '.join('?' for _ in QCR_COLUMNS)})"

    def write_sqlite(batch: list[tuple[Any, ...]]) -> None:
        conn.exec_driver_sql(insert, batch)

    return write_sqlite


def _rehash_run(conn: Connection, run: Mapping[str, Any]) -> tuple[str, int, bool]:
    """(chain hash recomputed from the stored rows, QCR row count, document matches its sha256) of one
    run: the document read on its own, the QCR rows streamed in ordinal order a batch at a time."""
    rid = run["id"]
    document = conn.execute(select(m.runs.c.document).where(m.runs.c.id == rid)).scalar_one()
    doc_ok = sha256_text(document) == run["document_sha256"]
    files = [dict(f) for f in conn.execute(select(m.run_files).where(m.run_files.c.run_id == rid)).mappings()]
    hasher = RunHasher(files, run["prev_hash"])
    cols = [m.qcrs.c[c] for c in QCR_COLUMNS]
    result = conn.execute(select(*cols).where(m.qcrs.c.run_id == rid).order_by(m.qcrs.c.ordinal)
                          .execution_options(yield_per=BATCH))  # PostgreSQL: a server-side cursor
    n = 0
    for part in result.partitions():
        hasher.qcr_texts(canonical_texts(part))
        n += len(part)
    full = {**run, "document": document}
    del document
    return hasher.hexdigest(full), n, doc_ok


def _anchor(seq: int, head: str) -> None:
    """Append the new head to the anchor file named by $ORTHOSPEC_LEDGER_ANCHOR (if set)."""
    path = os.environ.get(ENV_ANCHOR)
    if not path:
        return
    try:
        with open(path, "a", encoding="utf-8") as fh:
            fh.write(f"{seq} {head}\n")
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        raise LedgerError(f"recorded, but the head could not be appended to ${ENV_ANCHOR} {path}: {exc}") from None


def _read_anchors() -> list[tuple[int, tuple[int, str]]]:
    """(line number, (seq, hash)) of the anchor file; a missing file is an error when the variable is set."""
    path = os.environ.get(ENV_ANCHOR)
    if not path:
        return []
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        return []  # nothing recorded yet with this anchor
    except OSError as exc:
        raise LedgerError(f"${ENV_ANCHOR} {path}: cannot read: {exc}") from None
    out = []
    for n, line in enumerate(text.splitlines(), start=1):
        parts = line.split()
        if len(parts) != 2 or not parts[0].isdigit() or len(parts[1]) != 64:
            raise LedgerError(f"${ENV_ANCHOR} {path}:{n}: expected 'SEQ HASH', got {line[:80]!r}")
        out.append((n, (int(parts[0]), parts[1].lower())))
    return out


#: how an acknowledged rejection is recorded at the start of a sign-off note (hashed with it)
ACK_PREFIX = "[signed acknowledging the REJECTED verdict]"


def _same_person(a: str, b: str) -> bool:
    return " ".join(a.split()).casefold() == " ".join(b.split()).casefold()


def _run_info(r: Mapping[str, Any], files: list[tuple[str, str]]) -> RunInfo:
    return RunInfo(
        id=r["id"], seq=r["seq"], recorded_at=r["recorded_at"], date=r["date"], project_id=r["project_id"],
        delivery_id=r["delivery_id"], delivery_path=r["delivery_path"], manifest_sha256=r["manifest_sha256"],
        profile_id=r["profile_id"], profile_version=r["profile_version"], profile_sha256=r["profile_sha256"],
        verdict=r["verdict"], fail_on=r["fail_on"], operator=r["operator"], n_records=r["n_records"],
        summary=json.loads(r["summary"]), hash=r["hash"], files=tuple(sorted(files)))


# --- opening --------------------------------------------------------------------------------

def _sqlite_events(engine: Engine) -> None:
    """Own the transactions: BEGIN IMMEDIATE for writes (takes the write lock up front)."""

    @event.listens_for(engine, "connect")
    def _connect(dbapi_conn: Any, _rec: Any) -> None:
        dbapi_conn.isolation_level = None
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA foreign_keys=ON")
        cur.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: Connection) -> None:
        write = conn.get_execution_options().get("ledger_write", False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")


def upgrade(conn: Connection) -> None:
    """Apply the package's Alembic migrations up to head on an open connection."""
    from alembic import command
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(Path(__file__).with_name("migrations")))
    cfg.attributes["connection"] = conn
    command.upgrade(cfg, "head")


def current_revision(conn: Connection) -> str | None:
    from alembic.runtime.migration import MigrationContext

    return MigrationContext.configure(conn).get_current_revision()


def open_ledger(target: str | os.PathLike[str] | None = None, *, create: bool = True) -> Ledger:
    """Open (creating and migrating as needed) the ledger at a path or SQLAlchemy URL.

    ``create=False`` refuses to create a missing SQLite file (read-only commands use it so a
    typo in a path is an error, not a new empty ledger).
    """
    raw = os.fspath(target) if target is not None else default_ledger()
    try:
        url = make_url(to_url(raw))
    except ArgumentError:
        raise LedgerError(f"ledger {raw!r}: not a path or SQLAlchemy URL") from None
    display = url.render_as_string(hide_password=True) if url.drivername != "sqlite" else raw
    if url.drivername.startswith("sqlite"):
        path = Path(url.database or "")
        if not url.database or url.database == ":memory:":
            raise LedgerError(f"ledger {raw!r}: an in-memory SQLite ledger would keep nothing")
        if path.is_file() and path.stat().st_size == 0:
            raise LedgerError(f"ledger {raw}: empty file (0 bytes). A truncated ledger is not a new one: "
                              "restore it from a backup, or remove the file to start a new ledger")
        if not path.exists():
            if not create:
                raise LedgerError(f"no ledger at {raw} (record a run first with "
                                  f"`orthospec check ... --ledger {raw}`)")
            path.parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, connect_args={"timeout": 60})
        _sqlite_events(engine)
    elif url.drivername.startswith("postgresql"):
        try:
            engine = create_engine(url, pool_pre_ping=True)
        except (NoSuchModuleError, ModuleNotFoundError) as exc:
            raise LedgerError(f"ledger {display}: PostgreSQL driver missing ({exc}); "
                              "install orthospec[postgres]") from None
    else:
        raise LedgerError(f"ledger {display}: unsupported database {url.drivername!r}; "
                          "use a SQLite path or a postgresql+psycopg:// URL")
    ledger = Ledger(engine, display)
    try:
        _ensure_schema(ledger)
    except (OperationalError, DBAPIError) as exc:
        engine.dispose()
        raise LedgerError(f"ledger {display}: cannot open: {str(exc.orig).strip()}") from None
    except BaseException:
        engine.dispose()
        raise
    return ledger


def _ensure_schema(ledger: Ledger) -> None:
    with ledger.engine.connect() as conn:
        rev = current_revision(conn)
        conn.rollback()
    if rev == m.SCHEMA_REVISION:
        return
    if rev is not None and not rev.isdigit():
        raise LedgerError(f"ledger {ledger.display}: unknown schema revision {rev!r}")
    if rev is not None and int(rev) > int(m.SCHEMA_REVISION):
        raise LedgerError(f"ledger {ledger.display}: schema revision {rev} is newer than this "
                          f"orthospec ({m.SCHEMA_REVISION}); upgrade orthospec")
    with ledger._writer.begin() as conn:
        if conn.dialect.name == "postgresql":
            conn.execute(text("SELECT pg_advisory_xact_lock(:k)"), {"k": _PG_LOCK_KEY})
        upgrade(conn)
