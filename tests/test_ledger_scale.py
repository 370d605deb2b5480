"""The ledger at scale: rows streamed in batches, the chain hash fed incrementally, same bytes.

The hash of a run must stay exactly what it was when the whole canonical text was built at once
(existing ledgers must still verify), so the reference here is written from the canonical form
chain.py documents, straight from ``all_records`` and ``json.dumps``, not through the ledger's code.
"""

from __future__ import annotations

import gc
import hashlib
import json
import sys
import tracemalloc
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

import pg
from checking import MINI_CHECKER
from conftest import DATA, IMAGES, MANIFEST, MANUAL
from orthospec.api import check
from orthospec.errors import LedgerError
from orthospec.ledger import models as m
from orthospec.ledger import open_ledger
from orthospec.ledger.audit import family_of
from orthospec.ledger.db import to_url
from orthospec.qcr import all_records, dumps, natural_key

RECORDED_AT = "2026-11-21T00:00:00+00:00"


# --- the reference: the canonical form, written out --------------------------------------------

def _json(x: Any) -> str:
    return json.dumps(x, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def reference_row(i: int, rec: dict[str, Any]) -> dict[str, Any]:
    """A QCR record's ledger row: the columns of models.qcrs, as the record gives them."""
    clause = rec.get("clause") or {}
    measured = rec.get("measured") or {}
    req = rec.get("requirement") or {}

    def s(x: Any) -> str | None:
        return None if x is None else str(x)

    return {
        "ordinal": i,
        "rule": str(rec["rule"]),
        "scope": str(rec["scope"]),
        "item": str(rec["item"]),
        "verdict": str(rec["verdict"]),
        "family": family_of(rec),
        "level": rec.get("level"),
        "consequence": rec.get("consequence"),
        "manual": bool(rec.get("manual", False)),
        "measure": rec.get("measure"),
        "measured": _json(measured.get("value")),
        "unit": measured.get("unit"),
        "requirement": _json(req),
        "requirement_text": req.get("text"),
        "clause_document": s(clause.get("document")),
        "clause_section": s(clause.get("section")),
        "clause_table": s(clause.get("table")),
        "clause_row": s(clause.get("row")),
        "message": rec.get("message"),
    }


def reference_hash(
    run: dict[str, Any], files: list[dict[str, Any]], qcrs: list[dict[str, Any]], prev: str
) -> str:
    """sha256 of canonical({"kind": "run", "content": {run, files by path, qcrs by ordinal}, "prev"})."""
    # columns added by schema 0002 (audit key, signature) enter only when set: older runs keep their hash
    added = {"audit_key", "continues_run", "signer", "key_fingerprint", "signature"}
    content = {
        "run": {k: v for k, v in run.items() if k != "hash" and not (k in added and v is None)},
        "files": sorted(
            ({k: v for k, v in f.items() if k != "run_id"} for f in files), key=lambda f: f["path"]
        ),
        "qcrs": sorted(
            ({k: v for k, v in q.items() if k != "run_id"} for q in qcrs),
            key=lambda q: q["ordinal"],
        ),
    }
    return hashlib.sha256(
        _json({"kind": "run", "content": content, "prev": prev}).encode("utf-8")
    ).hexdigest()


# --- documents ----------------------------------------------------------------------------------

ODD = [
    "Ünïcødé-文字-😀",
    'quote " and \\ backslash',
    "tab\tnew\nline\x01ctl",
    "ſ-ligature ﬁ",
    "",
    "x" * 300,
]


def synthetic_doc(n_points: int, *, delivery: str = "D-1", seed: int = 0) -> dict[str, Any]:
    """A qcr.json (version 3) document with every column form the compact records use: lists,
    ``{"all": v}``, ``{"ref": [rule, column]}``, per-item requirements, messages left for the
    reader to word (None), stored records merged among compact items, nested values, odd text."""
    items = sorted(
        [f"P{i:05d}" for i in range(n_points)] + [f"{t}-{k}" for k, t in enumerate(ODD)],
        key=natural_key,
    )
    stored_at = set(range(3, len(items), 37))  # failing records in full among the compact ones
    compact_items = [x for k, x in enumerate(items) if k not in stored_at]
    nc = len(compact_items)
    req_a = {"op": "<=", "value": 0.5, "unit": "m", "text": "≤ 0.5 m", "bounds": [1, {"a": None}]}
    req_b = {"op": "<=", "value": 0.25, "unit": "m", "text": '≤ 0.25 m "tight"'}
    measured: list[Any] = []
    for k in range(nc):
        measured.append(
            [0.1, 1e-7, 123456789.0, None, 2, -3.5e300, 0.30000000000000004][(k + seed) % 7]
        )
    messages: list[Any] = [
        None if k % 5 else ("" if k % 10 else f"note {ODD[k % len(ODD)]}") for k in range(nc)
    ]
    ev_table = [
        {"file": "tables/checkpoints.csv", "sha256": "a" * 64},
        {"file": "tables/ünï.csv", "sha256": "b" * 64, "rows": [1, 2, {"nested": [3, None]}]},
    ]
    rule = {"title": "T", "quote": "q", "manual": False}
    rules = [
        {
            **rule,
            "rule": "R-PTS",
            "scope": "checkpoint",
            "level": "mandatory",
            "consequence": "reject_block",
            "citation": {
                "document": "JRC EUR 23638 EN",
                "section": "12.4",
                "table": "T12",
                "row": 7,
            },
            "measure": "checkpoints.precision_xy",
            "unit": "m",
            "requirement": req_a,
        },
        {
            **rule,
            "rule": "R-ALL",
            "scope": "checkpoint",
            "level": "recommended",
            "consequence": None,
            "citation": {"document": "JRC", "section": "Definitions"},
            "measure": "m.x",
            "unit": None,
            "requirement": {"op": "==", "value": True, "text": "is true"},
        },
        {
            **rule,
            "rule": "R-AUDIT",
            "scope": "block",
            "level": "mandatory",
            "consequence": "return_delivery",
            "citation": {"document": "JRC"},
            "manual": True,
            "measure": "b.y",
            "unit": "%",
            "requirement": {"op": "between", "min": 0, "max": 100, "text": "0-100 %"},
            "audit": {"family": "Fam ü", "inspection": "Normal (10%)"},
        },
        {
            **rule,
            "rule": "R-STORED",
            "scope": "delivery",
            "level": "mandatory",
            "consequence": "return_delivery",
            "citation": {},
            "measure": "",
            "unit": "px",
            "requirement": {},
        },
    ]
    blocks = {
        "R-PTS": {
            "items": compact_items,
            "verdict": {"all": "pass"},
            "measured": measured,
            "requirement": [req_a if k % 3 else req_b for k in range(nc)],
            "evidence": {"entry": 0, "rows": list(range(1, nc + 1))},
            "message": messages,
        },
        "R-ALL": {
            "items": {"ref": ["R-PTS", "items"]},
            "verdict": {"all": "not_applicable"},
            "measured": {"all": None},
            "evidence": {"all": [1]},
            "message": {"all": "n/a: ʃ"},
        },
        "R-AUDIT": {
            "items": ["B1", "B2", "B10", "Bü"],
            "verdict": ["pass", "not_applicable", "pass", "pass"],
            "measured": [True, 7, {"nested": [1.5, None, "ü"]}, [1, [2, [3]]]],
            "evidence": [[0], [], [0, 1], [1]],
            "message": {"all": None},
        },
    }
    records = [
        {
            "rule": "R-PTS",
            "item": items[k],
            "verdict": "fail",
            "measured": 0.75 + k / 1000,
            "evidence": [{**ev_table[1], "rows": [k, {"deep": ["x", 1.25]}]}],
            "message": f"fail {k} ü",
        }
        for k in sorted(stored_at)
    ]
    records += [
        {
            "rule": "R-STORED",
            "item": delivery,
            "verdict": "missing",
            "measured": {"a": [None, 0.5]},
            "evidence": [],
            "message": 'missing "x"',
            "waiver": {"by": "ü"},
        },
        {
            "rule": "R-NO-SUMMARY",
            "title": "",
            "clause": {"section": 3},
            "quote": "",
            "scope": "image",
            "item": "I1",
            "level": None,
            "consequence": None,
            "manual": False,
            "verdict": "error",
            "measure": "",
            "measured": {"value": None, "unit": None},
            "requirement": {},
            "evidence": [],
            "message": None,
        },
    ]
    return {
        "schema": "orthospec.qcr/3",
        "date": "2026-11-21",
        "operator": "Ä. Operator",
        "profile": {"id": "jrc-v3", "version": "3.0", "sha256": "c" * 64},
        "delivery": {
            "id": delivery,
            "path": None,
            "manifest_sha256": "d" * 64,
            "project": {"id": "P-ü"},
            "files": [
                {"path": "tables/ünï.csv", "sha256": "b" * 64, "bytes": 12},
                {"path": "tables/checkpoints.csv", "sha256": "a" * 64, "bytes": None},
            ],
        },
        "verdict": "rejected",
        "fail_on": "fail",
        "summary": {"pass": nc, "fail": len(stored_at)},
        "rollup": {"rejected": {"block": ["B1"]}, "reasons": ["ü"]},
        "rules": rules,
        "records": records,
        "compact": blocks,
        "evidence": ev_table,
    }


@pytest.fixture(scope="module")
def real_doc(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A document `check` wrote (the mini profile over a small delivery)."""
    root = tmp_path_factory.mktemp("scale-doc") / "d1"
    (root / "tables").mkdir(parents=True)
    (root / "delivery.yaml").write_text(MANIFEST, encoding="utf-8")
    (root / "tables" / "images.csv").write_text(IMAGES, encoding="utf-8")
    (root / "tables" / "manual.csv").write_text(MANUAL, encoding="utf-8")
    checker = root.parent / "checker.yaml"
    checker.write_text(MINI_CHECKER, encoding="utf-8")
    return check(root, DATA / "profiles" / "mini.yaml", date="2026-01-01", checker=checker).document


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def ledger_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return str(tmp_path / "ledger.sqlite")
    return pg.server().new_database()


def _stored(
    url: str, run_id: int
) -> tuple[dict[str, Any], list[dict[str, Any]], list[dict[str, Any]]]:
    eng = sa.create_engine(to_url(url))
    try:
        with eng.connect() as conn:
            run = dict(
                conn.execute(sa.select(m.runs).where(m.runs.c.id == run_id)).mappings().one()
            )
            files = [
                dict(f)
                for f in conn.execute(
                    sa.select(m.run_files).where(m.run_files.c.run_id == run_id)
                ).mappings()
            ]
            qcrs = [
                dict(q)
                for q in conn.execute(
                    sa.select(m.qcrs).where(m.qcrs.c.run_id == run_id).order_by(m.qcrs.c.ordinal)
                ).mappings()
            ]
    finally:
        eng.dispose()
    return run, files, qcrs


# --- tests --------------------------------------------------------------------------------------


def test_synthetic_document_has_the_edge_cases() -> None:
    """The document exercises what it claims: a few hundred records, every column form, merging."""
    doc = synthetic_doc(300)
    recs = list(all_records(doc))
    assert 300 < len(recs) < 1000
    assert {r["verdict"] for r in recs} >= {"pass", "fail", "not_applicable", "missing", "error"}
    assert any(r["measured"]["value"] is None for r in recs) and any(
        r["message"] == "" for r in recs
    )
    assert any(isinstance(r["measured"]["value"], dict) for r in recs)
    assert any(not r["item"].isascii() for r in recs)
    # stored failing records sit among the compact ones in item order (the merge), not after them
    pts = [r["item"] for r in recs if r["rule"] == "R-PTS"]
    assert pts == sorted(pts, key=natural_key) and recs[3]["verdict"] == "fail"


@pytest.mark.parametrize("which", ["synthetic", "real"])
def test_run_hash_is_the_canonical_hash(
    ledger_url: str, real_doc: dict[str, Any], which: str
) -> None:
    """Rows and chain hash as the documented canonical form gives them, byte for byte, for two
    chained runs; the stored QCR rows are the records' rows, in document order."""
    docs = (
        [synthetic_doc(300), synthetic_doc(250, delivery="D-2", seed=3)]
        if which == "synthetic"
        else [real_doc, real_doc]
    )
    prev = m.GENESIS
    with open_ledger(ledger_url) as led:
        for doc in docs:
            rid = led.record(doc, recorded_at=RECORDED_AT)
            run, files, qcrs = _stored(ledger_url, rid)
            expected_rows = [reference_row(i, r) for i, r in enumerate(all_records(doc))]
            assert run["n_records"] == len(expected_rows) == len(qcrs)
            got_rows = [{k: v for k, v in q.items() if k != "run_id"} for q in qcrs]
            assert [_json(r) for r in got_rows] == [
                _json(r) for r in expected_rows
            ]  # types too (1 vs 1.0 vs true)
            assert run["document"] == dumps(doc)
            assert run["document_sha256"] == hashlib.sha256(dumps(doc).encode()).hexdigest()
            assert run["prev_hash"] == prev
            assert run["hash"] == reference_hash(run, files, expected_rows, prev)
            prev = run["hash"]
        rep = led.verify()
        assert rep.ok, rep.problems
        assert rep.head_hash == prev and led.head() == (2, prev)


@pytest.mark.parametrize(
    ("sql", "expected"),
    [
        # one character of a row in the third batch of 5,000
        ("UPDATE qcrs SET message = message || '.' WHERE ordinal = 11001", ["hash"]),
        # two rows swapped (their ordinals exchanged): same rows, another order
        (
            "UPDATE qcrs SET ordinal = -1 WHERE ordinal = 7000; UPDATE qcrs SET ordinal = 7000 WHERE ordinal = 12000; "
            "UPDATE qcrs SET ordinal = 12000 WHERE ordinal = -1",
            ["hash"],
        ),
        ("DELETE FROM qcrs WHERE ordinal = 9999", ["count", "hash"]),
    ],
)
def test_verify_streams_every_batch(tmp_path: Path, sql: str, expected: list[str]) -> None:
    """An edit, a reordering or a deletion anywhere in a run of several batches breaks its hash."""
    url = str(tmp_path / "l.sqlite")
    with open_ledger(url) as led:
        led.record(synthetic_doc(12_500), recorded_at=RECORDED_AT)
        assert led.verify().ok
    eng = sa.create_engine(to_url(url))
    with eng.begin() as conn:
        for statement in sql.split("; "):
            assert conn.exec_driver_sql(statement).rowcount == 1
    eng.dispose()
    with open_ledger(url) as led:
        problems = [str(p) for p in led.verify().problems]
    n = len(list(all_records(synthetic_doc(12_500))))
    wanted = {
        "count": f"qcrs run 1 (seq 1): {n - 1} QCR rows, the run recorded {n}",
        "hash": "runs run 1 (seq 1): content hash mismatch: its row, file or QCR rows were edited or deleted",
    }
    assert problems == [wanted[k] for k in expected]


def _peak(fn: Any) -> int:
    """Peak traced Python memory while ``fn`` runs, above what was allocated before it."""
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        fn()
        return tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


def test_record_and_verify_memory_does_not_grow_with_the_rows(tmp_path: Path) -> None:
    """Recording or verifying 4x the check points costs about the larger document text more, not
    a row object per record: the document is held as its text (and its UTF-8 bytes while the
    database takes it), the rows a batch at a time. Rows held at once would add over 1 KB per
    record (a dict of 19 columns and their texts), 30+ MB for the 30,000 more here."""
    peaks = {}
    text_sizes = {}
    for n in (10_000, 40_000):
        doc = synthetic_doc(n)
        text_sizes[n] = sys.getsizeof(dumps(doc))  # in memory: 4 bytes a character here (an emoji)
        url = str(tmp_path / f"l{n}.sqlite")
        with open_ledger(url) as led:
            rec = _peak(lambda led=led, doc=doc: led.record(doc, recorded_at=RECORDED_AT))
            ver = _peak(lambda led=led: led.verify())
            assert led.verify().ok
        peaks[n] = (rec, ver)
    extra_rows = 30_000
    doc_growth = text_sizes[40_000] - text_sizes[10_000]
    for k, what in enumerate(("record", "verify")):
        growth = peaks[40_000][k] - peaks[10_000][k]
        assert growth < 2 * doc_growth + 150 * extra_rows, (what, growth, doc_growth)


def test_a_document_broken_past_the_first_batch_records_nothing(ledger_url: str) -> None:
    """Rows are made while the transaction is open: a record that cannot be read after thousands
    of rows were inserted is the same error as before, and the ledger is left as it was."""
    doc = synthetic_doc(12_000)
    del doc["compact"]["R-AUDIT"]["items"]  # the third rule, after 12,000 rows of the first
    with open_ledger(ledger_url) as led:
        with pytest.raises(LedgerError, match=r"not a QCR document \(missing 'items'\)"):
            led.record(doc, recorded_at=RECORDED_AT)
        rep = led.verify()
        assert rep.ok and rep.entries == 0 and led.runs() == []
    eng = sa.create_engine(to_url(ledger_url))
    try:
        with eng.connect() as conn:
            assert conn.execute(sa.select(sa.func.count()).select_from(m.qcrs)).scalar_one() == 0
    finally:
        eng.dispose()
