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
from collections.abc import Callable, Iterable, Mapping
from functools import partial
from pathlib import Path
from typing import Any

from sqlalchemy import Connection, Engine, func, select, update
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
from .names import display_name, same_person
from .rows import rows_with_text
from .runs import RecordedRun, RunInfo, lineage, stated_project
from .signing import (
    ENV_ALLOWED,
    ENV_KEY,
    Signature,
    allowed_signers_from_env,
    run_statement,
    sign,
    signoff_statement,
)
from .verify import Problem, VerifyReport, verify_chain

__all__ = [
    "DEFAULT_LEDGER",
    "ENV_LEDGER",
    "ROLES",
    "Ledger",
    "Problem",
    "VerifyReport",
    "default_ledger",
    "open_ledger",
]

ROLES = ("supervisor", "inspector", "auditor", "operator")


def _now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="seconds")


class Ledger:
    """An open ledger. Use :func:`open_ledger`; close it (or use ``with``) when done."""

    def __init__(
        self, engine: Engine, display: str, *, allowed_signers: Path | None = None
    ) -> None:
        self.engine = engine
        self.display = display
        #: the buyer's register of signing keys (:mod:`.signing`): when set, every new run and
        #: sign-off must be signed by a key listed in it, and `verify` checks each signature by it
        self.allowed_signers = allowed_signers

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

    def record(
        self,
        document: Mapping[str, Any],
        *,
        recorded_at: str | None = None,
        key: Path | None = None,
        before_commit: Callable[[RecordedRun], None] | None = None,
    ) -> int:
        """Record one check run (its qcr.json document) and return the new run id.

        One transaction. The QCR rows are made from the document's compact columns a batch at a
        time, inserted (executemany) and fed to the chain hash batch by batch: memory stays bounded
        by the batch, whatever the number of check points. The run row goes in first (the QCR
        rows refer to it) and gets its count and hash at the end, once every row is hashed.

        ``key``: the checker's SSH key; the run is signed with it (the SHA-256 of its qcr.json) and
        its checker *is* that key (:mod:`.signing`). Required when the ledger has an allowed-signers
        file. ``before_commit(run)``: called with the run's id and chain hash (the head that includes
        it) before the transaction commits, so a report can print its own entry; if it raises,
        nothing is recorded.
        """
        # dumps: the exact qcr.json text (its sha256 matches the file's); every QCR version it reads
        from ..qcr import SCHEMA_IDS, dumps

        if not isinstance(document, Mapping) or document.get("schema") not in SCHEMA_IDS:
            got = (
                document.get("schema") if isinstance(document, Mapping) else type(document).__name__
            )
            raise LedgerError(
                f"not a QCR document: schema {got!r}, expected one of "
                f"{', '.join(map(repr, SCHEMA_IDS))} (qcr.json)"
            )
        try:
            d = document["delivery"]
            p = document["profile"]
            project = str((d.get("project") or {}).get("id") or "")
            doc_text = dumps(dict(document))
            rollup = document.get("rollup") or {}
            summary = {
                "counts": document.get("summary", {}),
                "rejected": rollup.get("rejected", {}),
                "reasons": rollup.get("reasons", []),
            }
            files = [
                {
                    "path": str(f["path"]),
                    "sha256": str(f["sha256"]),
                    "bytes": None if f.get("bytes") is None else int(f["bytes"]),
                }
                for f in d.get("files", [])
            ]
            fields: dict[str, Any] = {
                "date": str(document["date"]),
                "project_id": project,
                "delivery_id": str(d["id"]),
                "delivery_path": d.get("path"),
                "manifest_sha256": str(d["manifest_sha256"]),
                "profile_id": str(p["id"]),
                "profile_version": str(p["version"]),
                "profile_sha256": str(p["sha256"]),
                "verdict": str(document["verdict"]),
                "fail_on": str(document.get("fail_on", V.FAIL)),
                "operator": document.get("operator"),
                "n_records": 0,
                "summary": canonical(summary),
                "document": doc_text,
                "document_sha256": sha256_text(doc_text),
            }
        except (KeyError, TypeError, AttributeError) as exc:
            raise LedgerError(
                f"not a QCR document (missing {exc}); expected qcr.json structure"
            ) from None
        if not project:
            raise LedgerError(
                f"delivery {d.get('id')!r}: manifest has no project.id; "
                "the ledger files runs by project"
            )
        sig = self._sign(run_statement(fields["document_sha256"]), key, what="the run")
        fields.update(
            signer=sig.principal if sig else None,
            key_fingerprint=sig.fingerprint if sig else None,
            signature=sig.armored if sig else None,
        )
        stated = stated_project(document)
        rows = rows_with_text(document)
        with write_transaction(self.engine, self.display) as (conn, seq, prev):
            run_id = (
                int(conn.execute(select(func.coalesce(func.max(m.runs.c.id), 0))).scalar_one()) + 1
            )
            shas = [str(f["sha256"]) for f in files]  # str already: typed for the checker
            audit_key, continues = resolve_audit_key(conn, stated, project, shas)
            row: dict[str, Any] = {
                "id": run_id,
                "seq": seq + 1,
                "recorded_at": recorded_at or _now(),
                **fields,
                "audit_key": audit_key,
                "continues_run": continues,
                "prev_hash": prev,
            }
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
            conn.execute(
                update(m.runs).where(m.runs.c.id == run_id).values(n_records=n, hash=row["hash"])
            )
            conn.execute(
                update(m.head).where(m.head.c.id == 1).values(seq=seq + 1, hash=row["hash"])
            )
            if before_commit is not None:
                before_commit(RecordedRun(run_id, seq + 1, row["hash"], audit_key))
        append_anchor(seq + 1, row["hash"])
        return run_id

    def _sign(self, message: bytes, key: Path | None, *, what: str) -> Signature | None:
        """Sign an entry with ``key``; no key is refused when the ledger has an allowed-signers file."""
        if key is None:
            if self.allowed_signers is not None:
                raise LedgerError(
                    f"{what} must be signed: the allowed-signers file {self.allowed_signers} is set, "
                    f"so every run and sign-off is signed with its maker's key (--key or "
                    f"${ENV_KEY})"
                )
            return None
        return sign(message, key, allowed_signers=self.allowed_signers)

    def signoff(
        self,
        run_id: int,
        *,
        by: str | None = None,
        role: str = "supervisor",
        date: str | None = None,
        note: str | None = None,
        manual: Mapping[str, str] | None = None,
        recorded_at: str | None = None,
        acknowledge_rejection: bool = False,
        key: Path | None = None,
    ) -> int:
        """Countersign a run (JRC §2.4), optionally with manual-check verdicts; returns its id.

        With ``key`` the sign-off is signed and its signer is that key (and, with an allowed-signers
        file, the principal registered for it: ``by`` may then be left out, and must name the same
        person when given). Refused, with the reason: the run's own checker countersigning it (JRC
        §2.4 asks for an independent countersignature): the key that signed the run, or a name that
        is the run's ``--operator``, the checker named in its checker file or its signer, compared
        as :mod:`.names` does (zero-width characters, look-alike letters, spacing do not make another
        person); the same person signing the same run in the same role again without new manual
        verdicts; a date before the run; a rejected run without ``acknowledge_rejection`` (recorded
        in the note, so it is part of the hashed entry).
        """
        day, verdicts = _signoff_arguments(role, date, manual, by)
        run = self.run(run_id)
        if acknowledge_rejection and run.verdict == V.REJECTED:
            note = ACK_PREFIX + (f" {note}" if note else "")
        content: dict[str, Any] = {
            "run_hash": run.hash,
            "date": day,
            "role": role,
            "note": note,
            "manual": canonical(dict(sorted(verdicts.items()))),
        }
        # the signature covers what is vouched for; the name is the key's registered principal when
        # there is a register (verify checks the row's name against it), else the name typed
        sig = self._sign(signoff_statement(content), key, what="the sign-off")
        principal = sig.principal if sig is not None else None
        if by is not None and principal is not None and not same_person(by, principal):
            raise LedgerError(
                f"--by {by!r} is not the owner of the key {key}: the allowed-signers file "
                f"{self.allowed_signers} registers it to {principal!r}"
            )
        if principal is None and by is None:
            raise LedgerError("sign-off needs the name of the person signing (--by)")
        content["by_name"] = display_name(principal if principal is not None else str(by))
        name = content["by_name"]
        with write_transaction(self.engine, self.display) as (conn, seq, prev):
            cur = conn.execute(
                select(m.runs.c.hash).where(m.runs.c.id == run_id)
            ).scalar_one_or_none()
            if cur != run.hash:
                raise LedgerError(f"run {run_id} changed while it was being signed; sign again")
            if verdicts:
                _refuse_unknown_manual(conn, run_id, verdicts)
            if day < run.date:
                raise LedgerError(
                    f"sign-off date {day} is before run {run_id} ({run.date}): "
                    "a run cannot be countersigned before it was made"
                )
            if role != "operator":
                self._refuse_own_run(conn, run, name, sig, role)
            if run.verdict == V.REJECTED and not acknowledge_rejection:
                raise LedgerError(
                    f"run {run_id} was REJECTED; signing it records that you accept that "
                    "verdict: repeat with --acknowledge-rejection (CLI) to sign anyway"
                )
            _refuse_duplicate(conn, run_id, name, sig, role, verdicts)
            sid = (
                int(conn.execute(select(func.coalesce(func.max(m.signoffs.c.id), 0))).scalar_one())
                + 1
            )
            row: dict[str, Any] = {
                "id": sid,
                "seq": seq + 1,
                "run_id": run_id,
                "recorded_at": recorded_at or _now(),
                **content,
                "key_fingerprint": sig.fingerprint if sig else None,
                "signature": sig.armored if sig else None,
                "prev_hash": prev,
            }
            row["hash"] = signoff_hash(row, prev)
            conn.execute(m.signoffs.insert(), row)
            conn.execute(
                update(m.head).where(m.head.c.id == 1).values(seq=seq + 1, hash=row["hash"])
            )
        append_anchor(seq + 1, row["hash"])
        return sid

    def _refuse_own_run(
        self, conn: Connection, run: RunInfo, name: str, sig: Signature | None, role: str
    ) -> None:
        """JRC §2.4: the run's checker (its key, or a name it goes by) cannot countersign it."""
        why = f"cannot countersign it as {role}: JRC §2.4 asks for an independent countersignature"
        if sig is not None and run.key_fingerprint and sig.fingerprint == run.key_fingerprint:
            raise LedgerError(
                f"the key {sig.fingerprint} signed check run {run.id} (its checker) and {why}"
            )
        doc = conn.execute(select(m.runs.c.document).where(m.runs.c.id == run.id)).scalar_one()
        checker = json.loads(doc).get("checker") or {}
        for who, as_what in (
            (run.operator, "ran check run"),
            (run.signer, "signed check run"),
            (checker.get("name"), "is the checker named in the checker file of run"),
        ):
            if isinstance(who, str) and same_person(who, name):
                shown = f"{name!r}" if name == who else f"{name!r} (the same name as {who!r})"
                raise LedgerError(f"{shown} {as_what} {run.id} and {why}")

    # --- reading -----------------------------------------------------------------------------

    def runs(
        self, project: str | None = None, *, ids: Iterable[int] | None = None
    ) -> list[RunInfo]:
        """Runs oldest first (chain order): all, or one audit trail (``project``: an audit key or,
        for runs recorded before audit keys, a manifest project id; :func:`.runs.lineage`), or
        those with the given ids."""
        cols = [c for c in m.runs.c if c.name != "document"]
        q = select(*cols).order_by(m.runs.c.seq)
        if ids is not None:
            q = q.where(m.runs.c.id.in_(list(ids)))
        with self._read() as conn:
            rows = conn.execute(q).mappings().all()
            if project is not None:
                keep = {r.id for r in lineage([_run_info(r, []) for r in rows], project)}
                rows = [r for r in rows if r["id"] in keep]
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
        """One name per audit trail: the audit key of its first run, sorted."""
        runs = self.runs()
        seen: set[int] = set()
        out = []
        for r in runs:
            if r.id not in seen:
                seen.update(x.id for x in lineage(runs, r.audit))
                out.append(r.audit)
        return sorted(out)

    def audit_key_for(self, stated: str | None, project: str, shas: Iterable[str]) -> str:
        """The audit key a delivery gets when recorded now (what the checker states, else the key of
        the run whose content it continues, else its manifest project id): `sample` reads it."""
        with self._read() as conn:
            return resolve_audit_key(conn, stated, project, list(shas))[0]

    def document(self, run_id: int) -> dict[str, Any]:
        """The qcr.json document exactly as the run produced it."""
        with self._read() as conn:
            doc = conn.execute(
                select(m.runs.c.document).where(m.runs.c.id == run_id)
            ).scalar_one_or_none()
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
        return [
            {
                "id": r["id"],
                "run": r["run_id"],
                "by": r["by_name"],
                "role": r["role"],
                "date": r["date"],
                "note": r["note"],
                "manual": json.loads(r["manual"]),
                "recorded_at": r["recorded_at"],
                "key": r["key_fingerprint"],
            }
            for r in rows
        ]

    def report_document(self, run_id: int, *, heads: Iterable[str] = ()) -> dict[str, Any]:
        """What a report of ``run_id`` shows: its document, sign-offs and the project's sequence of
        deliveries, redeliveries and verdicts up to that run (JRC §12.8: redeliver until acceptable).
        ``heads``: ledger heads printed earlier (e.g. on the run's own report): a chain that no longer
        holds one of them is listed in ``ledger.problems``, and the report says TAMPERED."""
        from .signed import after_signoff

        doc = self.document_with_signoffs(run_id, heads=heads)
        run = self.run(run_id)
        signed = after_signoff(doc, self.signoffs(run_id))
        if signed is not None:
            doc["after_signoff"] = signed
        entries = [e for e in self.history(run.audit).entries if e.run.seq <= run.seq]
        doc["history"] = history_rows(entries, current_run=run_id)
        return doc

    def document_with_signoffs(self, run_id: int, *, heads: Iterable[str] = ()) -> dict[str, Any]:
        """The stored qcr document plus ``signoffs`` [{by, role, date, note, manual, key}] and ``ledger``
        (the run's entry and signer, the head, what ``verify`` found) for reports."""
        doc = self.document(run_id)
        doc["signoffs"] = [
            {k: s[k] for k in ("by", "role", "date", "note", "manual", "key")}
            for s in self.signoffs(run_id)
        ]
        seq, head = self.head()
        rep = self.verify(heads=heads)
        run = self.run(run_id)
        doc["ledger"] = {
            "run": run_id,
            "hash": run.hash,
            "head": head,
            "head_seq": seq,
            "signer": run.signer,
            "key": run.key_fingerprint,
            "problems": [str(p) for p in rep.problems],
        }
        return doc

    def qcrs(self, run_id: int) -> list[dict[str, Any]]:
        """The run's QCR rows (ordinal order); ``measured``/``requirement`` decoded from JSON."""
        with self._read() as conn:
            rows = (
                conn.execute(
                    select(m.qcrs).where(m.qcrs.c.run_id == run_id).order_by(m.qcrs.c.ordinal)
                )
                .mappings()
                .all()
            )
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
        return {
            (
                q["rule"],
                "delivery" if q["scope"] == "delivery" and q["item"] == did else q["item"],
            ): manual.get(q["rule"], q["verdict"])
            for q in self.qcrs(run_id)
        }

    # --- history and diff ---------------------------------------------------------------------

    def history(self, project: str | None = None) -> History:
        """Deliveries, redeliveries and re-checks with verdicts per run, rule and block, of one audit
        trail (``project``: its audit key, :meth:`runs`) or of every run."""
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
        key = self.audit_key_for(
            stated_project(doc), project, (f["sha256"] for f in doc["delivery"].get("files", []))
        )
        return history_rows_before_recording(self.history(key).entries, doc)

    def diff(self, run_a: int, run_b: int) -> Diff:
        """Per (rule, item): fixed, newly failing, still failing, changed, added, removed."""
        self.run(run_a), self.run(run_b)  # a clear error for an unknown id
        return diff_verdicts(
            run_a, run_b, self.effective_verdicts(run_a), self.effective_verdicts(run_b)
        )

    # --- audit state -------------------------------------------------------------------------

    def audit_states(self, project: str, *, margin: float = MARGIN) -> dict[str, FamilyState]:
        """Normal/Tightened state of every QCR family the project's runs touched."""
        runs = self.runs(project)
        ids = [r.id for r in runs]
        cols = (
            m.qcrs.c.run_id,
            m.qcrs.c.rule,
            m.qcrs.c.item,
            m.qcrs.c.verdict,
            m.qcrs.c.family,
            m.qcrs.c.measured,
            m.qcrs.c.requirement,
        )
        per_run: dict[int, list[Mapping[str, Any]]] = {i: [] for i in ids}
        if ids:
            with self._read() as conn:
                for row in conn.execute(
                    select(*cols)
                    .where(m.qcrs.c.run_id.in_(ids))
                    .order_by(m.qcrs.c.run_id, m.qcrs.c.ordinal)
                ).mappings():
                    per_run[row["run_id"]].append(row)
        manual: dict[int, dict[str, str]] = {}
        for s in self.signoffs():
            if s["run"] in per_run:
                manual.setdefault(s["run"], {}).update(s["manual"])
        return audit_states(
            (RunRecords(i, per_run[i], manual.get(i, {}), partial(self._reasons, i)) for i in ids),
            margin=margin,
        )

    def _reasons(self, run_id: int) -> dict[tuple[str, str], str]:
        """The reason codes of a run's non-pass records, by (rule, item), from its stored document
        (the QCR rows keep no reason column: a ledger written before reason codes reads the same)."""
        doc = self.document(run_id)
        return {
            (str(r.get("rule")), str(r.get("item"))): str(r["reason"])
            for r in doc.get("records") or ()
            if isinstance(r, dict) and r.get("reason")
        }

    def audit_state(self, project: str, family: str, *, margin: float = MARGIN) -> str:
        """``"normal"`` or ``"tightened"``; a family never checked is normal."""
        st = self.audit_states(project, margin=margin).get(family)
        return st.state if st is not None else NORMAL

    def sample_fraction(
        self,
        project: str,
        family: str,
        normal: float = 0.10,
        tightened: float = 0.20,
        *,
        margin: float = MARGIN,
    ) -> float:
        """Share of items to sample next for this family: larger while it is tightened."""
        return (
            tightened if self.audit_state(project, family, margin=margin) == TIGHTENED else normal
        )

    def suspect_items(
        self, project: str, family: str, *, margin: float = MARGIN
    ) -> tuple[str, ...]:
        """Items that failed or were marginal in the family's last run: the tightened trail."""
        st = self.audit_states(project, margin=margin).get(family)
        return st.suspect_items if st is not None and st.state == TIGHTENED else ()

    # --- verification ------------------------------------------------------------------------

    def head(self) -> tuple[int, str]:
        """(seq, hash) of the chain head row: the anchor a report prints and `verify --head` checks."""
        with self._read() as conn:
            row = conn.execute(
                select(m.head.c.seq, m.head.c.hash).where(m.head.c.id == 1)
            ).one_or_none()
        if row is None:
            raise LedgerError(
                f"{self.display}: the chain head row is missing; run `orthospec ledger verify`"
            )
        return int(row.seq), str(row.hash)

    def verify(self, head: str | None = None, *, heads: Iterable[str] = ()) -> VerifyReport:
        """Recompute every hash and link; list each edited, deleted or reordered row (:mod:`.verify`).

        ``head`` (and each of ``heads``): a chain hash noted outside the ledger earlier (printed on
        every report and in qcr.json); the chain must still contain it.
        """
        return verify_chain(self.engine, head, heads=heads, allowed_signers=self.allowed_signers)


#: how an acknowledged rejection is recorded at the start of a sign-off note (hashed with it)
ACK_PREFIX = "[signed acknowledging the REJECTED verdict]"


def _signoff_arguments(
    role: str, date: str | None, manual: Mapping[str, str] | None, by: str | None
) -> tuple[str, dict[str, str]]:
    """A sign-off's day (today when not given) and manual verdicts, refused when malformed."""
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
    if by is not None and not display_name(by):
        raise LedgerError("sign-off needs the name of the person signing (--by)")
    return day, verdicts


def _refuse_unknown_manual(conn: Connection, run_id: int, verdicts: Mapping[str, str]) -> None:
    """Manual verdicts may name only the run's manual rules."""
    manual_rules = set(
        conn.execute(
            select(m.qcrs.c.rule).where(m.qcrs.c.run_id == run_id, m.qcrs.c.manual.is_(True))
        ).scalars()
    )
    unknown = sorted(set(verdicts) - manual_rules)
    if unknown:
        raise LedgerError(
            f"run {run_id} has no manual rule {', '.join(unknown)}; manual rules of this run: "
            f"{', '.join(sorted(manual_rules)) or 'none'}"
        )


def _refuse_duplicate(
    conn: Connection,
    run_id: int,
    name: str,
    sig: Signature | None,
    role: str,
    verdicts: Mapping[str, str],
) -> None:
    """The same person (by name or key) signing the same run in the same role again, with no new
    manual verdict, is refused."""
    earlier = conn.execute(
        select(
            m.signoffs.c.by_name,
            m.signoffs.c.role,
            m.signoffs.c.manual,
            m.signoffs.c.date,
            m.signoffs.c.key_fingerprint,
        ).where(m.signoffs.c.run_id == run_id)
    ).all()
    for e in earlier:
        same = same_person(e.by_name, name) or (
            sig is not None
            and e.key_fingerprint is not None
            and e.key_fingerprint == sig.fingerprint
        )
        if same and e.role == role:
            signed = json.loads(e.manual)
            if not verdicts or all(signed.get(k) == v for k, v in verdicts.items()):
                raise LedgerError(
                    f"{name} already signed run {run_id} as {role} on {e.date}: "
                    "a duplicate sign-off is refused"
                )


def _run_info(r: Mapping[str, Any], files: list[tuple[str, str]]) -> RunInfo:
    return RunInfo(
        id=r["id"],
        seq=r["seq"],
        recorded_at=r["recorded_at"],
        date=r["date"],
        project_id=r["project_id"],
        delivery_id=r["delivery_id"],
        delivery_path=r["delivery_path"],
        manifest_sha256=r["manifest_sha256"],
        profile_id=r["profile_id"],
        profile_version=r["profile_version"],
        profile_sha256=r["profile_sha256"],
        verdict=r["verdict"],
        fail_on=r["fail_on"],
        operator=r["operator"],
        n_records=r["n_records"],
        summary=json.loads(r["summary"]),
        hash=r["hash"],
        files=tuple(sorted(files)),
        audit_key=r.get("audit_key"),
        continues_run=r.get("continues_run"),
        signer=r.get("signer"),
        key_fingerprint=r.get("key_fingerprint"),
    )


#: SHA-256 of an empty file: shared by unrelated deliveries, never a sign of continuity
_EMPTY = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"


def resolve_audit_key(
    conn: Connection, stated: str | None, project: str, shas: list[str]
) -> tuple[str, int | None]:
    """(audit key, run continued) of a delivery about to be recorded (issue 25 item 6).

    The run it continues: the latest recorded run sharing the most file contents with it (SHA-256,
    whatever the paths), at least half of the smaller of the two file sets. The key: what the
    checker states; else the continued run's key; else the manifest's project id (the contractor's
    word, used only when nothing else ties the delivery to an audit trail)."""
    mine = sorted(set(shas) - {_EMPTY})
    shared: dict[int, int] = {}
    for i in range(0, len(mine), 500):
        part = mine[i : i + 500]
        q = (
            select(m.run_files.c.run_id, func.count(func.distinct(m.run_files.c.sha256)))
            .where(m.run_files.c.sha256.in_(part))
            .group_by(m.run_files.c.run_id)
        )
        for rid, n in conn.execute(q):
            shared[int(rid)] = shared.get(int(rid), 0) + int(n)
    best: tuple[int, int, str] | None = None  # (shared, seq, key) of the continued run
    cont: int | None = None
    if shared:
        counted = (
            select(m.run_files.c.run_id, func.count(func.distinct(m.run_files.c.sha256)))
            .where(m.run_files.c.run_id.in_(list(shared)), m.run_files.c.sha256 != _EMPTY)
            .group_by(m.run_files.c.run_id)
        )
        sizes: dict[Any, Any] = dict(conn.execute(counted).all())
        info = {
            int(r.id): r
            for r in conn.execute(
                select(m.runs.c.id, m.runs.c.seq, m.runs.c.audit_key, m.runs.c.project_id).where(
                    m.runs.c.id.in_(list(shared))
                )
            )
        }
        for rid, n in shared.items():
            r = info.get(rid)
            if r is None or 2 * n < min(len(mine), int(sizes.get(rid, 0))):
                continue
            cand = (n, int(r.seq), str(r.audit_key or r.project_id))
            if best is None or cand[:2] > best[:2]:
                best, cont = cand, rid
    if stated:
        return stated, cont
    if best is not None:
        return best[2], cont
    return project, None


def open_ledger(
    target: str | os.PathLike[str] | None = None,
    *,
    create: bool = True,
    allowed_signers: str | os.PathLike[str] | None = None,
) -> Ledger:
    """Open (creating and migrating as needed) the ledger at a path or SQLAlchemy URL.

    ``create=False`` refuses to create a missing SQLite file (read-only commands use it so a
    typo in a path is an error, not a new empty ledger). ``allowed_signers``: the allowed-signers
    file (default ``$ORTHOSPEC_ALLOWED_SIGNERS``; :mod:`.signing`).
    """
    signers = Path(allowed_signers) if allowed_signers is not None else allowed_signers_from_env()
    if signers is not None and not signers.is_file():
        raise LedgerError(
            f"allowed-signers file {signers}: no such file (--allowed-signers or ${ENV_ALLOWED})"
        )
    engine, display = connect(target, create=create)
    try:
        ensure_schema(engine, display)
    except (OperationalError, DBAPIError) as exc:
        engine.dispose()
        raise LedgerError(f"ledger {display}: cannot open: {str(exc.orig).strip()}") from None
    except BaseException:
        engine.dispose()
        raise
    return Ledger(engine, display, allowed_signers=signers)
