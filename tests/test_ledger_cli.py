"""Ledger commands end to end: check --ledger, history, diff, signoff, ledger verify/state/runs.

Same tests on a SQLite file and on a PostgreSQL server started by the test run (tests/pg.py).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa
from click.testing import CliRunner, Result
from tests.checking import LEDGER_CHECKER

import pg
from orthospec.cli.main import cli
from orthospec.ledger import open_ledger
from orthospec.ledger.db import to_url
from orthospec.measures.sampling import select_sample

PROFILE = """\
orthospec_profile: 1
id: ledger-test
version: 1.0.0
title: Ledger scenario profile
source: {title: JRC, seed: 002_7421c4ca450e31c6.txt}
parameters:
  tolerance_xy: {unit: m, required: true, description: tol}
  max_roll: {unit: deg, default: 3}
rules:
  - id: R-ROLL
    title: roll within limits
    clause: {document: JRC EUR 23638 EN, section: "5.2.4"}
    quote: "Roll and drift"
    scope: image
    measure: images.roll
    requirement: {op: "<=", value: max_roll, unit: deg}
    consequence: reject_block
    audit: {family: orientation, inspection: "Normal (first few) Tightened (trail)"}
  - id: R-FH
    title: flying height recorded
    clause: {document: JRC EUR 23638 EN, section: "5.3"}
    quote: "For each photo: Flight identifier, Film roll and Exposure number, Flying height"
    scope: image
    measure: images.flying_height
    requirement: {op: present}
    consequence: reject_item
    audit: {family: flight-data, inspection: "Normal (100%)"}
  - id: R-COUNT
    title: images per block
    clause: {document: JRC EUR 23638 EN, section: "12.7"}
    quote: "A block is normally considered to be a geometrically homogeneous group of image products"
    scope: block
    measure: images.count_per_block
    requirement: {op: ">=", value: 2}
    consequence: reject_block
  - id: R-VIS
    title: visual check
    clause: {document: JRC EUR 23638 EN, section: "6.3"}
    quote: "These checks are usually visual and qualitative"
    scope: delivery
    measure: manual.R-VIS
    manual: true
    requirement: {op: "==", value: pass}
    consequence: return_delivery
"""

MANIFEST = """\
orthospec_delivery: 1
id: {id}
project: {{id: P1, name: Ledger project, crs: "EPSG:25832"}}
contractor: {{name: ACME Mapping}}
operator: {{name: Jane Doe}}
sensor: {{type: aerial, digital: true}}
product: {{gsd: {{value: 0.25, unit: m}}}}
tender: {{reference: ITT-1, parameters: {{tolerance_xy: {{value: 0.5, unit: m}}}}}}
blocks: [{{id: B1}}, {{id: B2}}]
tables: {{images: tables/images.csv, manual_checks: tables/manual.csv}}
"""
MANUAL = "check,item,inspector,date,verdict\nR-VIS,*,Joe Bloggs,2026-01-01,pass\n"
#: the checker's file of each delivery (docs/CHECKER.md): the ITT value in force and the verdict of
#: the manual rule (the delivery's own table above and its tender.parameters are only the
#: contractor's statements); written next to, never inside, the delivery
CHECKER = LEDGER_CHECKER


def checker_of(root: Path) -> Path:
    return root.parent / f"{root.name}.checker.yaml"


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def ledger_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return str(tmp_path / "ledger.sqlite")
    return pg.server().new_database()


@pytest.fixture
def profile(tmp_path: Path) -> Path:
    p = tmp_path / "ledger-test.yaml"
    p.write_text(PROFILE, encoding="utf-8")
    return p


def write_delivery(root: Path, delivery_id: str, rolls: dict[str, float], n: int = 20) -> Path:
    """n images in two blocks and four film rolls; ``rolls`` sets the roll angle of some images."""
    (root / "tables").mkdir(parents=True)
    (root / "delivery.yaml").write_text(MANIFEST.format(id=delivery_id), encoding="utf-8")
    lines = ["image_id,file,block,film_roll,roll,flying_height,std_dn"]
    for i in range(1, n + 1):
        iid = f"I{i}"
        block = "B1" if i <= n // 2 else "B2"
        lines.append(
            f"{iid},images/{iid.lower()}.tif,{block},F{(i - 1) * 4 // n + 1},"
            f"{rolls.get(iid, 0.5)},1000,30"
        )
    (root / "tables" / "images.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    (root / "tables" / "manual.csv").write_text(MANUAL, encoding="utf-8")
    checker_of(root).write_text(CHECKER.format(id=delivery_id), encoding="utf-8")
    return root


def run(*args: str) -> Result:
    return CliRunner().invoke(cli(), list(args), catch_exceptions=False)


def check(delivery: str, *args: str) -> Result:
    """``orthospec check DELIVERY ARGS --checker <the delivery's checker file>``."""
    return run("check", delivery, *args, "--checker", str(checker_of(Path(delivery))))


def test_three_rounds_until_accepted(tmp_path: Path, profile: Path, ledger_url: str) -> None:
    """JRC §12.8: fail, partial fix (tightened audit), pass; history shows the sequence."""
    rounds = [("D1", {"I3": 5.0, "I14": 6.0}), ("D1-R1", {"I14": 4.0}), ("D1-R2", {})]
    outputs = []
    for k, (did, rolls) in enumerate(rounds, start=1):
        deliv = write_delivery(tmp_path / did, did, rolls)
        res = check(
            str(deliv),
            "-p",
            str(profile),
            "--format",
            "json",
            "--out",
            str(tmp_path / "out" / did),
            "--date",
            f"2026-0{k}-01",
            "--ledger",
            ledger_url,
        )
        assert f"recorded run #{k} in ledger" in res.output, res.output
        assert res.exit_code == (1 if k < 3 else 0)
        outputs.append(json.loads((tmp_path / "out" / did / "qcr.json").read_text()))

        with open_ledger(ledger_url, create=False) as led:
            state = led.audit_state("P1", "orientation")
            if k == 2:
                # the redelivery still fails R-ROLL on I14: the orientation family stays tightened,
                # the next sample is the larger one and takes the whole suspect film roll
                assert state == "tightened"
                assert led.suspect_items("P1", "orientation") == ("I14",)
                frac = led.sample_fraction("P1", "orientation")
                assert frac == 0.20 and led.sample_fraction("P1", "flight-data") == 0.10
                ids = [f"I{i}" for i in range(1, 21)]
                rolls_of = {i: f"F{(n - 1) * 4 // 20 + 1}" for n, i in enumerate(ids, start=1)}
                x, y = np.arange(20.0) % 5, np.arange(20.0) // 5
                suspect_rolls = {rolls_of[i] for i in led.suspect_items("P1", "orientation")}
                kw = {"seed": 7, "round": 2, "batches": [rolls_of[i] for i in ids]}
                tight = select_sample(ids, x, y, fraction=frac, problem_batches=suspect_rolls, **kw)
                normal = select_sample(ids, x, y, fraction=0.10, **kw)
                assert len(tight.ids) > len(normal.ids)
                assert {i for i in ids if rolls_of[i] in suspect_rolls} <= set(tight.ids)
            else:
                assert state == ("tightened" if k == 1 else "normal")

    state = run("ledger", "state", "P1", "--ledger", ledger_url)
    assert state.exit_code == 0
    assert "orientation" in state.output and "normal" in state.output

    hist = run("history", "P1", "--ledger", ledger_url)
    assert hist.exit_code == 0, hist.output
    lines = hist.output.splitlines()
    runs_lines = [ln for ln in lines if ln.lstrip().startswith("#")]
    assert [ln.split()[2:4] for ln in runs_lines[:3]] == [
        ["1", "delivery"],
        ["2", "redelivery"],
        ["3", "redelivery"],
    ]
    assert [ln.split()[5] for ln in runs_lines[:3]] == ["rejected", "rejected", "accepted"]
    roll_row = next(ln for ln in lines if ln.startswith("R-ROLL"))
    assert roll_row.split()[1:] == ["FAIL", "FAIL", "pass"]
    b1 = next(ln for ln in lines if ln.startswith("B1"))
    b2 = next(ln for ln in lines if ln.startswith("B2"))
    assert b1.split()[1:] == ["REJ", "pass", "pass"] and b2.split()[1:] == ["REJ", "REJ", "pass"]
    as_json = json.loads(run("history", "--json", "--ledger", ledger_url).output)
    assert [r["verdict"] for r in as_json[0]["runs"]] == [o["verdict"] for o in outputs]

    d12 = run("diff", "1", "2", "--ledger", ledger_url)
    assert d12.exit_code == 0
    assert "fixed:\n  R-ROLL [I3]: fail -> pass" in d12.output
    assert "still failing:\n  R-ROLL [I14]: fail -> fail" in d12.output
    d23 = json.loads(run("diff", "#2", "#3", "--json", "--ledger", ledger_url).output)
    assert [(c["rule"], c["item"], c["status"]) for c in d23["changes"]] == [
        ("R-ROLL", "I14", "fixed")
    ]

    signed = run(
        "signoff",
        "3",
        "--by",
        "Ann Super",
        "--role",
        "supervisor",
        "--note",
        "accepted",
        "--manual",
        "R-VIS=pass",
        "--date",
        "2026-03-02",
        "--ledger",
        ledger_url,
    )
    assert signed.exit_code == 0 and "signed run #3 as supervisor" in signed.output
    with open_ledger(ledger_url, create=False) as led:
        doc = led.document_with_signoffs(3)
    assert doc["records"] == outputs[2]["records"]
    assert doc["signoffs"] == [
        {
            "by": "Ann Super",
            "role": "supervisor",
            "date": "2026-03-02",
            "note": "accepted",
            "manual": {"R-VIS": "pass"},
            "key": None,
        }
    ]

    ok = run("ledger", "verify", "--ledger", ledger_url)
    assert ok.exit_code == 0 and "intact, 4 entries (3 runs, 1 sign-offs)" in ok.output
    listed = json.loads(run("ledger", "runs", "P1", "--json", "--ledger", ledger_url).output)
    assert [r["delivery"] for r in listed] == ["D1", "D1-R1", "D1-R2"]


def test_verify_exit_codes(tmp_path: Path, profile: Path, ledger_url: str) -> None:
    deliv = write_delivery(tmp_path / "d", "D1", {"I2": 9.0})
    for _ in range(2):
        check(
            str(deliv),
            "-p",
            str(profile),
            "--format",
            "json",
            "--out",
            str(tmp_path / "o"),
            "--ledger",
            ledger_url,
        )
    ok = run("ledger", "verify", "--ledger", ledger_url)
    assert ok.exit_code == 0
    head = ok.output.split("head ")[-1].strip()
    assert (
        run("ledger", "verify", "--expect-head", head[:16], "--ledger", ledger_url).exit_code == 0
    )
    eng = sa.create_engine(to_url(ledger_url))
    with eng.begin() as conn:
        conn.execute(sa.text("UPDATE qcrs SET verdict = 'pass' WHERE run_id = 1 AND item = 'I2'"))
    eng.dispose()
    bad = run("ledger", "verify", "--ledger", ledger_url)
    assert bad.exit_code == 1
    assert "runs run 1 (seq 1): content hash mismatch" in bad.output
    assert "run 2" not in bad.output  # the later run is intact; only its link would be rewritten


def test_cli_errors(tmp_path: Path) -> None:
    missing = str(tmp_path / "nope.sqlite")
    res = CliRunner().invoke(cli(), ["history", "--ledger", missing])
    assert res.exit_code != 0 and "no ledger at" in str(res.exception)
    assert not Path(missing).exists()
    res = CliRunner().invoke(
        cli(), ["signoff", "1", "--by", "X", "--manual", "R-VIS=maybe", "--ledger", missing]
    )
    assert res.exit_code == 2 and "RULE=pass or RULE=fail" in res.output
    res = CliRunner().invoke(cli(), ["diff", "one", "2", "--ledger", missing])
    assert res.exit_code == 2 and "a run id is a number" in res.output


def _in_transaction(url: str) -> bool:
    """Whether another session holds an open write transaction on the ledger."""
    if "://" not in url:
        return Path(url + "-journal").exists()  # rollback journal of an uncommitted write
    eng = sa.create_engine(to_url(url))
    try:
        with eng.connect() as conn:
            n = conn.execute(
                sa.text(
                    "SELECT count(*) FROM pg_stat_activity WHERE datname = current_database() "
                    "AND state = 'idle in transaction'"
                )
            ).scalar_one()
    finally:
        eng.dispose()
    return n >= 1


#: `orthospec` in a child process that, at the commit of a ledger write, writes its pid to the marker
#: file (argv[1]) and sleeps, so the test can kill it inside the open write transaction (the hook lives
#: here, not in the product: a SQLAlchemy event on every engine of that process)
_PAUSE_BEFORE_COMMIT = """
import os, sys, time
from pathlib import Path
from sqlalchemy import event
from sqlalchemy.engine import Engine

MARKER = Path(sys.argv[1])

@event.listens_for(Engine, "commit")
def _pause(conn):
    if conn.get_execution_options().get("ledger_write"):
        MARKER.write_text(str(os.getpid()))
        time.sleep(60)

from orthospec.cli.main import main
sys.argv = ["orthospec", *sys.argv[2:]]
main()
"""


@pytest.mark.slow
def test_check_killed_mid_write_leaves_the_ledger_intact(
    tmp_path: Path, profile: Path, ledger_url: str
) -> None:
    small = write_delivery(tmp_path / "small", "D0", {})
    assert (
        check(
            str(small),
            "-p",
            str(profile),
            "--format",
            "json",
            "--out",
            str(tmp_path / "o0"),
            "--ledger",
            ledger_url,
        ).exit_code
        == 0
    )
    with open_ledger(ledger_url, create=False) as led:
        before = led.verify()
    big = write_delivery(tmp_path / "big", "D-BIG", {"I7": 8.0}, n=3000)
    marker = tmp_path / "in-transaction"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            _PAUSE_BEFORE_COMMIT,
            str(marker),
            "check",
            str(big),
            "-p",
            str(profile),
            "--format",
            "json",
            "--out",
            str(tmp_path / "o1"),
            "--ledger",
            ledger_url,
            "--checker",
            str(checker_of(big)),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 60
        while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert marker.exists(), proc.communicate(timeout=5)
        assert int(marker.read_text()) == proc.pid  # the pause ran in that process
        assert _in_transaction(ledger_url)  # ... with its rows written, uncommitted
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    assert (tmp_path / "o1" / "qcr.json").exists()  # outputs were written before recording

    with open_ledger(ledger_url, create=False) as led:
        after = led.verify()
        assert after.ok, after.problems
        assert (after.entries, after.head_hash) == (before.entries, before.head_hash)
        assert [r.delivery_id for r in led.runs()] == ["D0"]
    eng = sa.create_engine(to_url(ledger_url))
    with eng.connect() as conn:
        assert (
            conn.execute(sa.text("SELECT count(*) FROM qcrs WHERE run_id <> 1")).scalar_one() == 0
        )
    eng.dispose()
    # the ledger is writable again: the killed writer's lock is gone
    res = check(
        str(small),
        "-p",
        str(profile),
        "--format",
        "json",
        "--out",
        str(tmp_path / "o2"),
        "--ledger",
        ledger_url,
    )
    assert "recorded run #2" in res.output
    with open_ledger(ledger_url, create=False) as led:
        assert led.verify().ok and led.runs()[-1].delivery_id == "D0"
