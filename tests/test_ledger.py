"""The QCR ledger library on a real SQLite file and a real PostgreSQL server (same tests)."""

from __future__ import annotations

import copy
import hashlib
import threading
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.config import Config
from alembic.runtime.migration import MigrationContext

import pg
from checking import MINI_CHECKER
from conftest import DATA, IMAGES, MANIFEST, MANUAL
from orthospec.api import check
from orthospec.errors import LedgerError
from orthospec.ledger import (
    TIGHTENED,
    audit_state,
    family_of,
    inspection_fractions,
    is_marginal,
    open_ledger,
    sample_fraction,
    store,
)
from orthospec.ledger import models as m
from orthospec.ledger.audit import RunRecords, audit_states
from orthospec.ledger.history import classify
from orthospec.qcr import all_records, dumps

IMAGES_OK = """\
image_id,file,block,roll,flying_height,std_dn
I1,images/i1.tif,B1,0.5,1000,30
I2,images/i2.tif,B1,1.0,1000,40
I3,images/i3.tif,B2,1.5,1100,35
"""


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def ledger_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A fresh, empty ledger: a SQLite file, or a new database on the test PostgreSQL server."""
    if request.param == "sqlite":
        return str(tmp_path / "ledger.sqlite")
    return pg.server().new_database()


@pytest.fixture(scope="module")
def docs(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, Any]]:
    """Three QCR documents of project P1: the failing delivery, a redelivery, a re-check of it.

    Module-scoped (the checks are the slow part); tests never mutate them.
    """
    base = tmp_path_factory.mktemp("ledger-docs")
    roots = []
    for name, images in (("d1", IMAGES), ("d2", IMAGES_OK)):
        root = base / name
        (root / "tables").mkdir(parents=True)
        (root / "delivery.yaml").write_text(MANIFEST, encoding="utf-8")
        (root / "tables" / "images.csv").write_text(images, encoding="utf-8")
        (root / "tables" / "manual.csv").write_text(MANUAL, encoding="utf-8")
        roots.append(root)
    profile = DATA / "profiles" / "mini.yaml"
    checker = base / "checker.yaml"  # the checker's manual verdict and waiver (docs/CHECKER.md)
    checker.write_text(MINI_CHECKER, encoding="utf-8")
    return [check(roots[0], profile, date="2026-01-01", checker=checker).document,
            check(roots[1], profile, date="2026-01-10", checker=checker).document,
            check(roots[1], profile, date="2026-01-11", checker=checker).document]


def _engine(url: str) -> sa.Engine:
    from orthospec.ledger.db import to_url

    return sa.create_engine(to_url(url))


def test_upgrade_of_empty_database_gives_the_expected_tables(ledger_url: str) -> None:
    with open_ledger(ledger_url) as led:
        assert led.verify().ok
    eng = _engine(ledger_url)
    try:
        with eng.connect() as conn:
            tables = set(sa.inspect(conn).get_table_names())
            assert tables == {*m.TABLES, "alembic_version"}
            ctx = MigrationContext.configure(conn)
            assert ctx.get_current_revision() == m.SCHEMA_REVISION
            # the migration builds exactly what models.py describes (columns, types, indexes)
            assert compare_metadata(ctx, m.metadata) == []
            head = conn.execute(sa.select(m.head)).mappings().all()
            assert [dict(h) for h in head] == [{"id": 1, "seq": 0, "hash": m.GENESIS}]
    finally:
        eng.dispose()
    with open_ledger(ledger_url) as led:  # re-opening at head is a no-op
        assert led.runs() == []
    # the migration also goes down cleanly (and up again on the next open)
    eng = _engine(ledger_url)
    try:
        with eng.begin() as conn:
            cfg = Config()
            cfg.set_main_option("script_location", str(Path(store.__file__).with_name("migrations")))
            cfg.attributes["connection"] = conn
            command.downgrade(cfg, "base")
        with eng.connect() as conn:
            assert set(sa.inspect(conn).get_table_names()) <= {"alembic_version"}
    finally:
        eng.dispose()
    with open_ledger(ledger_url) as led:
        assert led.verify().ok and led.verify().entries == 0


def test_record_keeps_every_qcr_and_the_document(
    ledger_url: str, docs: list[dict[str, Any]]
) -> None:
    doc = docs[0]
    with open_ledger(ledger_url) as led:
        rid = led.record(doc)
        run = led.run(rid)
        assert (run.profile_id, run.profile_version, run.profile_sha256) == (
            doc["profile"]["id"],
            doc["profile"]["version"],
            doc["profile"]["sha256"],
        )
        assert (run.project_id, run.delivery_id, run.verdict, run.date, run.operator) == (
            "P1",
            doc["delivery"]["id"],
            doc["verdict"],
            "2026-01-01",
            doc["operator"],
        )
        assert run.manifest_sha256 == doc["delivery"]["manifest_sha256"]
        assert dict(run.files) == {f["path"]: f["sha256"] for f in doc["delivery"]["files"]}
        rows = led.qcrs(rid)
        records = list(all_records(doc))
        assert len(rows) == run.n_records == len(records)
        for row, rec in zip(rows, records, strict=True):
            assert (row["rule"], row["item"], row["verdict"]) == (
                rec["rule"],
                rec["item"],
                rec["verdict"],
            )
            assert row["measured"] == rec["measured"]["value"]
            assert row["requirement_text"] == rec["requirement"]["text"]
            assert row["clause_section"] == rec["clause"]["section"]
            assert row["family"] == family_of(rec)
        # the stored document is qcr.json itself: same content, same checksum as the written file
        assert led.document(rid) == doc
        stored = _engine(ledger_url)
        try:
            with stored.connect() as conn:
                sha = conn.execute(sa.select(m.runs.c.document_sha256)).scalar_one()
        finally:
            stored.dispose()
        assert sha == hashlib.sha256(dumps(doc).encode()).hexdigest()


def test_signoff_is_shown_with_the_document(ledger_url: str, docs: list[dict[str, Any]]) -> None:
    with open_ledger(ledger_url) as led:
        rid = led.record(docs[0])
        led.signoff(
            rid,
            by="Ann Super",
            role="supervisor",
            note="seen",
            date="2026-01-02",
            manual={"R-VIS": "fail"},
            acknowledge_rejection=True,
        )
        led.signoff(
            rid, by="Ian Spector", role="inspector", date="2026-01-03", acknowledge_rejection=True
        )
        doc = led.document_with_signoffs(rid)
        assert doc["records"] == docs[0]["records"]
        assert doc["signoffs"] == [
            {
                "by": "Ann Super",
                "role": "supervisor",
                "date": "2026-01-02",
                "note": "[signed acknowledging the REJECTED verdict] seen",
                "manual": {"R-VIS": "fail"},
                "key": None,
            },
            {
                "by": "Ian Spector",
                "role": "inspector",
                "date": "2026-01-03",
                "note": "[signed acknowledging the REJECTED verdict]",
                "manual": {},
                "key": None,
            },
        ]
        # a signed manual verdict overrides the table's for diff/history/audit state
        assert led.effective_verdicts(rid)[("R-VIS", "delivery")] == "fail"
        with pytest.raises(LedgerError, match="no manual rule R-ROLL"):
            led.signoff(rid, by="X", manual={"R-ROLL": "pass"})
        with pytest.raises(LedgerError, match="no run 99"):
            led.signoff(99, by="X")
        with pytest.raises(LedgerError, match="role 'boss'"):
            led.signoff(rid, by="X", role="boss")
        assert len(led.signoffs(rid)) == 2  # refused sign-offs wrote nothing
        assert led.verify().ok


def test_history_rounds_and_diff(ledger_url: str, docs: list[dict[str, Any]]) -> None:
    with open_ledger(ledger_url) as led:
        ids = [led.record(d) for d in docs]
        h = led.history("P1")
        assert [(e.kind, e.round) for e in h.entries] == [
            ("delivery", 1),
            ("redelivery", 2),
            ("recheck", 2),
        ]
        assert [e.run.verdict for e in h.entries] == [d["verdict"] for d in docs]
        assert h.rules["R-FH"] == {ids[0]: "fail", ids[1]: "pass", ids[2]: "pass"}
        d = led.diff(ids[0], ids[1])
        by_key = {(c.rule, c.item): c for c in d.changes}
        assert by_key[("R-FH", "I2")].status == "fixed"
        assert by_key[("R-ROLLUP", "delivery")].status == "fixed"
        assert ("R-ROLL", "I1") not in by_key  # pass -> pass is no change
        assert led.diff(ids[1], ids[2]).changes == ()  # a re-check of the same content
        back = led.diff(ids[1], ids[0])
        assert {c.status for c in back.changes if c.rule == "R-FH"} == {"newly_failing"}
        with pytest.raises(LedgerError, match="no run 42"):
            led.diff(ids[0], 42)


def test_round_before_recording_is_the_round_recorded(
    ledger_url: str, docs: list[dict[str, Any]]
) -> None:
    """The row a report shows for a run not yet recorded (check time) has the kind and round the
    ledger gives that run once recorded; keyed on content, not on the delivery id (all three
    documents say D1: the second has different images, the third is a re-check of it)."""
    assert {d["delivery"]["id"] for d in docs} == {"D1"}
    with open_ledger(ledger_url) as led:
        for n, doc in enumerate(docs, start=1):
            before = led.history_before_recording(doc)
            assert [r["run"] for r in before] == [*range(1, n), "new"] and before[-1]["current"]
            rid = led.record(doc)
            after = led.report_document(rid)["history"]
            assert [(r["kind"], r["round"]) for r in after] == [
                (r["kind"], r["round"]) for r in before
            ]
            assert after[-1]["current"] and after[-1]["run"] == rid
        assert [(r["kind"], r["round"]) for r in after] == [
            ("delivery", 1),
            ("redelivery", 2),
            ("recheck", 2),
        ]


@pytest.mark.parametrize(
    ("before", "after", "status"),
    [
        ("fail", "pass", "fixed"),
        ("missing", "waived", "fixed"),
        ("pass", "fail", "newly_failing"),
        (None, "error", "newly_failing"),
        ("fail", "fail", "still_failing"),
        ("fail", "missing", "still_failing"),
        ("pass", "pass", None),
        ("pass", "warn", "changed"),
        (None, "pass", "added"),
        ("fail", None, "removed"),
    ],
)
def test_classify(before: str | None, after: str | None, status: str | None) -> None:
    assert classify(before, after) == status


@pytest.mark.parametrize(
    ("value", "req", "marginal"),
    [
        (2.4, {"op": "<=", "value": 2.5}, True),  # 4 % below the tolerance
        (2.0, {"op": "<=", "value": 2.5}, False),
        (2.6, {"op": "<=", "value": 2.5}, True),  # just above (a fail elsewhere, still marginal)
        (20.5, {"op": ">=", "value": 20}, True),
        (26.0, {"op": "between", "min": 25.6, "max": 51.2}, True),
        (30.0, {"op": "between", "min": 25.6, "max": 51.2}, False),
        ("pass", {"op": "==", "value": "pass"}, False),
        (True, {"op": "<=", "value": 1}, False),
        (None, {"op": "<=", "value": 1}, False),
    ],
)
def test_is_marginal(value: Any, req: dict[str, Any], marginal: bool) -> None:
    assert is_marginal(value, req) is marginal


def _rec(
    rule: str, item: str, verdict: str, value: float | None = 1.0, family: str = "geo"
) -> dict[str, Any]:
    return {
        "rule": rule,
        "item": item,
        "verdict": verdict,
        "family": family,
        "measured": value,
        "requirement": {"op": "<=", "value": 2.5},
    }


def test_audit_state_machine() -> None:
    runs = [
        RunRecords(1, [_rec("A", "B1", "pass"), _rec("C", "x", "pass", family="meta")]),
        RunRecords(2, [_rec("A", "B1", "pass", 2.45)]),  # marginal pass
        RunRecords(3, [_rec("A", "B1", "fail", 3.0), _rec("A", "B2", "pass")]),
        RunRecords(4, [_rec("A", "B1", "not_applicable", None)]),  # says nothing
        RunRecords(5, [_rec("A", "B1", "pass"), _rec("A", "B2", "pass")]),
    ]
    states = [audit_states(runs[:n]) for n in range(1, 6)]
    assert [s["geo"].state for s in states] == [
        "normal",
        "tightened",
        "tightened",
        "tightened",
        "normal",
    ]
    assert states[2]["geo"].since_run == 2 and states[2]["geo"].suspect_items == ("B1",)
    assert "1 failing" in states[2]["geo"].reason
    assert states[4]["geo"].since_run == 5 and "back from tightened" in states[4]["geo"].reason
    assert states[4]["meta"].state == "normal" and states[4]["meta"].last_run == 1
    # a signed-off manual fail counts like any failure
    signed = [RunRecords(1, [_rec("M", "D1", "pass", None)], manual={"M": "fail"})]
    assert audit_states(signed)["geo"].state == TIGHTENED


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("Normal (10%) Tightened (100%)", {"normal": 0.10, "tightened": 1.0}),  # JRC Table 6 row 12
        ("Normal (100%)", {"normal": 1.0}),
        ("Normal (first few) Tightened (trail)", {}),
        (None, {}),
    ],
)
def test_inspection_fractions(text: str | None, expected: dict[str, float]) -> None:
    assert inspection_fractions(text) == expected


def test_family_of() -> None:
    assert (
        family_of({"rule": "R", "audit": {"family": "metadata"}, "clause": {"section": "8.4"}})
        == "metadata"
    )
    assert (
        family_of({"rule": "R", "audit": {"inspection": "Normal"}, "clause": {"section": "8.4"}})
        == "§8.4"
    )
    assert family_of({"rule": "R", "clause": {"document": "X"}}) == "R"


def test_audit_state_from_the_ledger(ledger_url: str, docs: list[dict[str, Any]]) -> None:
    with open_ledger(ledger_url) as led:
        assert led.audit_state("P1", "§5.3") == "normal"  # nothing recorded yet
        led.record(docs[0])  # R-FH (§5.3) fails on I2
        assert led.audit_state("P1", "§5.3") == "tightened"
        assert led.sample_fraction("P1", "§5.3") == 0.20
        assert led.suspect_items("P1", "§5.3") == ("I2",)
        assert led.audit_state("P2", "§5.3") == "normal"  # per project
        led.record(docs[1])  # fixed
        assert led.audit_state("P1", "§5.3") == "normal"
    assert audit_state(ledger_url, "P1", "§5.3") == "normal"  # module-level, by path/URL
    assert sample_fraction(ledger_url, "P1", "§5.3", 0.1, 0.5) == 0.1
    assert sample_fraction(ledger_url, "P1", "§12.3", 0.1, 0.5) == 0.1


def _tamper(url: str, sql: str) -> None:
    eng = _engine(url)
    try:
        with eng.begin() as conn:
            n = conn.execute(sa.text(sql)).rowcount
            assert n >= 1, sql
    finally:
        eng.dispose()


@pytest.mark.parametrize(
    ("sql", "table", "what"),
    [
        (
            "UPDATE qcrs SET verdict = 'pass' WHERE run_id = 1 AND verdict = 'fail'",
            "runs",
            "hash mismatch",
        ),
        ("DELETE FROM qcrs WHERE run_id = 2 AND ordinal = 0", "qcrs", "QCR rows"),
        ("UPDATE runs SET verdict = 'accepted' WHERE id = 1", "runs", "hash mismatch"),
        (
            "UPDATE runs SET document = replace(document, 'rejected', 'accepted') WHERE id = 1",
            "runs",
            "document_sha256",
        ),
        (
            "UPDATE run_files SET sha256 = "
            "'0000000000000000000000000000000000000000000000000000000000000000' WHERE run_id = 3",
            "runs",
            "hash mismatch",
        ),
        ("DELETE FROM signoffs WHERE id = 1", "runs", "prev_hash"),
        ("UPDATE signoffs SET by_name = 'Mallory' WHERE id = 1", "signoffs", "hash mismatch"),
        ("DELETE FROM ledger_head", "ledger_head", "head rows"),
    ],
)
def test_verify_detects_edits_and_deletions(
    ledger_url: str, docs: list[dict[str, Any]], sql: str, table: str, what: str
) -> None:
    with open_ledger(ledger_url) as led:
        for d in docs:
            led.record(d)
        led.signoff(2, by="Ann", date="2026-01-12")
        led.record(docs[2])
        assert led.verify().ok
    _tamper(ledger_url, sql)
    with open_ledger(ledger_url) as led:
        rep = led.verify()
    assert not rep.ok
    assert any(p.table == table and what in p.message for p in rep.problems), rep.problems


@pytest.mark.parametrize("victim", ["middle", "newest"])
def test_verify_detects_deleted_runs(
    ledger_url: str, docs: list[dict[str, Any]], victim: str
) -> None:
    with open_ledger(ledger_url) as led:
        ids = [led.record(d) for d in docs]
    rid = ids[1] if victim == "middle" else ids[2]
    for t in ("qcrs", "run_files"):
        _tamper(ledger_url, f"DELETE FROM {t} WHERE run_id = {rid}")
    _tamper(ledger_url, f"DELETE FROM runs WHERE id = {rid}")
    with open_ledger(ledger_url) as led:
        rep = led.verify()
    assert not rep.ok
    expected = "runs" if victim == "middle" else "ledger_head"
    assert any(p.table == expected for p in rep.problems), rep.problems


def test_concurrent_writers_keep_one_chain(ledger_url: str, docs: list[dict[str, Any]]) -> None:
    open_ledger(ledger_url).close()
    errors: list[BaseException] = []

    def write(k: int) -> None:
        try:
            with open_ledger(ledger_url) as led:
                for _ in range(3):
                    led.record(docs[k % 3])
        except BaseException as exc:  # surfaced by the assertion below
            errors.append(exc)

    threads = [threading.Thread(target=write, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    with open_ledger(ledger_url) as led:
        rep = led.verify()
        assert rep.ok and rep.runs == 12
        assert [r.seq for r in led.runs()] == list(range(1, 13))


def test_open_errors(tmp_path: Path) -> None:
    with pytest.raises(LedgerError, match="no ledger at"):
        open_ledger(tmp_path / "missing.sqlite", create=False)
    assert not (tmp_path / "missing.sqlite").exists()
    with pytest.raises(LedgerError, match="unsupported database"):
        open_ledger("mysql://x@localhost/db")
    with pytest.raises(LedgerError, match="cannot open"):
        open_ledger("postgresql+psycopg://nobody@127.0.0.1:1/none")
    with open_ledger(tmp_path / "l.sqlite") as led:
        with pytest.raises(LedgerError, match="schema 'x'"):
            led.record({"schema": "x"})
        with pytest.raises(LedgerError, match="missing 'delivery'"):
            led.record({"schema": "orthospec.qcr/1"})
        assert led.verify().entries == 0


def test_a_failed_write_records_nothing(ledger_url: str, docs: list[dict[str, Any]]) -> None:
    """The run row is inserted before its files: a duplicate file path fails the write mid-way."""
    bad = copy.deepcopy(docs[1])
    bad["delivery"]["files"].append(dict(bad["delivery"]["files"][0]))
    with open_ledger(ledger_url) as led:
        led.record(docs[0])
        before = led.verify()
        with pytest.raises(LedgerError, match="write failed, nothing recorded"):
            led.record(bad)
        after = led.verify()
        assert after.ok and (after.entries, after.head_hash) == (before.entries, before.head_hash)
        assert [r.id for r in led.runs()] == [1]
        assert led.record(docs[1]) == 2 and led.verify().ok
