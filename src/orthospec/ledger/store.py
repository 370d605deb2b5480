"""The QCR ledger: recording check runs and sign-offs, and reading them back (SQLAlchemy 2 + Alembic).

JRC §2.4 asks that QCRs be dated, identify the item and the operator, and may be countersigned;
§12.8 asks that redeliveries be re-checked "until the products are finally acceptable". The
ledger keeps that trail: every ``check`` run (profile, delivery, file checksums, every QCR),
sign-offs, and a hash chain over all of it (:mod:`.chain`, checked by :mod:`.verify`). Opening
the database, its schema and its write transactions are :mod:`.db`.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from collections.abc import Iterable, Mapping
from typing import Any

from sqlalchemy import Engine, func, select, update
from sqlalchemy.exc import DBAPIError, OperationalError

from .. import verdicts as V
from ..errors import LedgerError
from . import models as m
from .anchor import append_anchor
from .audit import MARGIN, NORMAL, TIGHTENED, FamilyState, RunRecords, audit_states
from .chain import RunHasher, canonical, sha256_text, signoff_hash
from .db import (
    DEFAULT_LEDGER,
    ENV_LEDGER,
    connect,
    default_ledger,
    ensure_schema,
    next_batch,
    qcr_writer,
    write_transaction,
)
from .history import (
    Diff,
    History,
    build_history,
    diff_verdicts,
    history_rows,
    history_rows_before_recording,
)
from .rows import rows_with_text
from .runs import RunInfo
from .verify import Problem, VerifyReport, verify_chain

__all__ = ["DEFAULT_LEDGER", "ENV_LEDGER", "ROLES", "Ledger", "Problem", "VerifyReport", "default_ledger",
           "open_ledger"]

ROLES = ("supervisor", "inspector", "auditor", "operator")


def _now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")



class Ledger:
    """An open ledger. Use :func:`open_ledger`; close it (or use ``with``) when done."""

    def __init__(self, engine: Engine, display: str) -> None:
        self.engine = engine
        self.display = display

    # --- lifecycle ---------------------------------------------------------------------------

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Ledger:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

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
        with write_transaction(self.engine, self.display) as (conn, seq, prev):
            run_id = int(conn.execute(select(func.coalesce(func.max(m.runs.c.id), 0))).scalar_one()) + 1
            row: dict[str, Any] = {"id": run_id, "seq": seq + 1, "recorded_at": recorded_at or _now(),
                                   **fields, "prev_hash": prev}
            conn.execute(m.runs.insert(), {**row, "hash": ""})
            if files:
                conn.execute(m.run_files.insert(), [{"run_id": run_id, **f} for f in files])
            hasher = RunHasher(files, prev)
            insert = qcr_writer(conn, run_id, self.display)
            n = 0
            while batch := next_batch(rows):
                hasher.qcr_texts([text for _, text in batch])
                insert([values for values, _ in batch])
                n += len(batch)
            row["n_records"] = n
            row["hash"] = hasher.hexdigest(row)
            conn.execute(update(m.runs).where(m.runs.c.id == run_id).values(n_records=n, hash=row["hash"]))
            conn.execute(update(m.head).where(m.head.c.id == 1).values(seq=seq + 1, hash=row["hash"]))
        append_anchor(seq + 1, row["hash"])
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
        with write_transaction(self.engine, self.display) as (conn, seq, prev):
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
        append_anchor(seq + 1, row["hash"])
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
        """Recompute every hash and link; list each edited, deleted or reordered row (:mod:`.verify`).

        ``head`` (and each of ``heads``): a chain hash noted outside the ledger earlier (printed on
        every report and in qcr.json); the chain must still contain it.
        """
        return verify_chain(self.engine, head, heads=heads)


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




def open_ledger(target: str | os.PathLike[str] | None = None, *, create: bool = True) -> Ledger:
    """Open (creating and migrating as needed) the ledger at a path or SQLAlchemy URL.

    ``create=False`` refuses to create a missing SQLite file (read-only commands use it so a
    typo in a path is an error, not a new empty ledger).
    """
    engine, display = connect(target, create=create)
    try:
        ensure_schema(engine, display)
    except (OperationalError, DBAPIError) as exc:
        engine.dispose()
        raise LedgerError(f"ledger {display}: cannot open: {str(exc.orig).strip()}") from None
    except BaseException:
        engine.dispose()
        raise
    return Ledger(engine, display)
