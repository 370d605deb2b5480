"""Sign-off that counts and tamper evidence that holds (issue 13 items 4-5, issue 17 ledger).

Real SQLite ledgers, real checks of small deliveries, real PDFs read back with pdfplumber.
"""

from __future__ import annotations

import re
import sqlite3
from pathlib import Path

import pdfplumber
import pytest
from click.testing import CliRunner
from tests.conftest import MANIFEST

from orthospec.cli.main import cli
from orthospec.errors import LedgerError
from orthospec.ledger import open_ledger

GOOD = "image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n" + "\n".join(
    f"I{i},f{i}.tif,B1,0.5,1000,30,{i * 100},{(i % 4) * 100}" for i in range(20)) + "\n"
NO_WAIVER = "waivers: [{rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}]\n"


def run(*args: object):
    return CliRunner().invoke(cli(), [str(a) for a in args])


def page1(pdf: Path) -> str:
    with pdfplumber.open(pdf) as doc:
        return doc.pages[0].extract_text() or ""


@pytest.fixture
def unsigned(make_delivery, mini_profile, tmp_path: Path) -> dict[str, Path]:
    """One run, rejected only because the checker's file judged the manual check R-VIS fail (a
    manual check with no verdict at all leaves the check incomplete, not rejected: issue 26)."""
    root = make_delivery(
        "d",
        manifest=MANIFEST.replace(NO_WAIVER, ""),
        images=GOOD,
        manual="check,item,inspector,date,verdict\n",
    )
    ledger = tmp_path / "ledger.sqlite"
    checker = tmp_path / "checker.yaml"
    checker.write_text(
        "orthospec_checker: 1\nchecker: {name: Eva External, role: external QC}\n"
        "delivery: {id: D1}\nmanual_checks:\n"
        "  - {check: R-VIS, item: '*', date: 2026-02-28, verdict: fail, note: haze}\n",
        encoding="utf-8",
    )
    # the ITT value comes from the checker's side (--param), never from the delivery (docs/CHECKER.md)
    res = run(
        "check",
        root,
        "-p",
        mini_profile,
        "--param",
        "tolerance_xy=0.5",
        "--out",
        tmp_path / "o1",
        "--checker",
        checker,
        "--ledger",
        ledger,
        "--date",
        "2026-03-01",
        "--format",
        "json",
        "--operator",
        "Carl Checker",
    )
    assert res.exit_code == 1, res.output
    assert "recorded run #1" in res.output
    return {"ledger": ledger, "tmp": tmp_path}


def test_manual_verdicts_at_signoff_enter_page1_of_the_signed_report(
    unsigned: dict[str, Path],
) -> None:
    ledger, tmp = unsigned["ledger"], unsigned["tmp"]
    sign = run(
        "signoff",
        1,
        "--by",
        "Maria Rossi",
        "--manual",
        "R-VIS=pass",
        "--date",
        "2026-03-02",
        "--acknowledge-rejection",
        "--ledger",
        ledger,
    )
    assert sign.exit_code == 0, sign.output
    rep = run("report", "--ledger", ledger, "--run", 1, "--format", "pdf", "--out", tmp / "rep")
    assert rep.exit_code == 0, rep.output
    text = page1(tmp / "rep" / "report.pdf")
    flat = " ".join(text.split())
    assert "REJECTED" in flat  # the automatic verdict stands as check wrote it
    assert re.search(r"Verdict after sign-off: ACCEPTED", flat), flat
    assert re.search(r"R-VIS pass 1 Maria Rossi \(supervisor\) 2026-03-02", flat), flat
    assert "None" not in flat  # no --note: blank, never "None"


def test_signoff_refusals(unsigned: dict[str, Path]) -> None:
    ledger = unsigned["ledger"]
    with open_ledger(ledger) as led:
        with pytest.raises(LedgerError, match="REJECTED.*acknowledge"):
            led.signoff(1, by="Maria Rossi", date="2026-03-02")
        with pytest.raises(LedgerError, match="independent countersignature"):
            led.signoff(1, by="carl  checker", date="2026-03-02", acknowledge_rejection=True)
        with pytest.raises(LedgerError, match="before run 1"):
            led.signoff(1, by="Maria Rossi", date="2026-02-28", acknowledge_rejection=True)
        led.signoff(1, by="Maria Rossi", date="2026-03-02", acknowledge_rejection=True)
        with pytest.raises(LedgerError, match="duplicate"):
            led.signoff(1, by="Maria Rossi", date="2026-03-03", acknowledge_rejection=True)
        assert len(led.signoffs(1)) == 1 and led.verify().ok
        assert led.signoffs(1)[0]["note"].startswith("[signed acknowledging the REJECTED verdict]")


def test_deleted_newest_row_with_rewritten_head_is_caught_by_the_printed_head(
    unsigned: dict[str, Path],
) -> None:
    ledger, tmp = unsigned["ledger"], unsigned["tmp"]
    assert (
        run(
            "signoff",
            1,
            "--by",
            "Maria Rossi",
            "--date",
            "2026-03-02",
            "--acknowledge-rejection",
            "--ledger",
            ledger,
        ).exit_code
        == 0
    )
    rep = run("report", "--ledger", ledger, "--run", 1, "--format", "pdf", "--out", tmp / "rep")
    assert rep.exit_code == 0, rep.output
    flat = re.sub(r"\s+", "", page1(tmp / "rep" / "report.pdf"))
    printed = re.search(r"ledgerheadwhenrendered\(seq2\):([0-9a-f]{64})", flat)
    assert printed, flat
    head = printed.group(1)
    with sqlite3.connect(ledger) as con:  # what an editor does: drop the newest row, fix the head
        assert con.execute("SELECT hash FROM signoffs WHERE seq = 2").fetchone()[0] == head
        con.execute("DELETE FROM signoffs WHERE seq = 2")
        run_hash = con.execute("SELECT hash FROM runs WHERE seq = 1").fetchone()[0]
        con.execute("UPDATE ledger_head SET seq = 1, hash = ?", (run_hash,))
    plain = run("ledger", "verify", "--ledger", ledger)
    assert plain.exit_code == 0  # the chain alone cannot tell: this is what the anchor is for
    bad = run("ledger", "verify", "--ledger", ledger, "--head", head)
    assert bad.exit_code == 1 and "TAMPERED" in bad.output and head[:16] in bad.output, bad.output
    against = run("ledger", "verify", "--ledger", ledger, "--against", tmp / "rep" / "report.pdf")
    assert against.exit_code == 1 and "TAMPERED" in against.output, against.output
    # a head that is still in the chain verifies (the ledger may grow after a report)
    assert run("ledger", "verify", "--ledger", ledger, "--head", run_hash[:16]).exit_code == 0


def test_tampered_ledger_is_flagged_by_report_and_history(unsigned: dict[str, Path]) -> None:
    ledger, tmp = unsigned["ledger"], unsigned["tmp"]
    with sqlite3.connect(ledger) as con:
        con.execute("UPDATE runs SET operator = 'Mallory' WHERE id = 1")
    hist = run("history", "P1", "--ledger", ledger)
    assert "TAMPERED" in hist.output
    rep = run("report", "--ledger", ledger, "--run", 1, "--format", "pdf", "--out", tmp / "t")
    assert rep.exit_code == 0 and "TAMPERED" in rep.output
    assert "LEDGER TAMPERED" in page1(tmp / "t" / "report.pdf")


def test_truncated_ledger_does_not_verify_as_empty(unsigned: dict[str, Path]) -> None:
    ledger = unsigned["ledger"]
    ledger.write_bytes(b"")
    res = run("ledger", "verify", "--ledger", ledger)
    assert res.exit_code != 0 and "intact" not in res.output
    assert isinstance(res.exception, LedgerError) and "0 bytes" in str(res.exception)
    assert ledger.stat().st_size == 0  # and no fresh schema was written into it


def test_history_shows_changes_by_default(unsigned: dict[str, Path]) -> None:
    ledger = unsigned["ledger"]
    short = run("history", "P1", "--ledger", ledger)
    full = run("history", "P1", "--ledger", ledger, "--all")
    assert short.exit_code == 0 and full.exit_code == 0
    assert "R-VIS" in short.output  # missing in the run: shown
    passing = [
        line.split()[0]
        for line in full.output.splitlines()
        if line.startswith("R-") and line.split()[-1] == "pass"
    ]
    assert passing  # rules that passed in every run are listed with --all only
    for rid in passing:
        assert not re.search(rf"^{re.escape(rid)}\s", short.output, re.M)
    assert "--all shows them" in short.output


def test_anchor_file_catches_a_recomputed_chain(
    make_delivery, mini_profile, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With $ORTHOSPEC_LEDGER_ANCHOR every new head is appended outside the ledger; deleting the
    newest entry and rewriting the head row then fails `ledger verify` without any --head."""
    anchor = tmp_path / "anchor.txt"
    monkeypatch.setenv("ORTHOSPEC_LEDGER_ANCHOR", str(anchor))
    root = make_delivery("d", manifest=MANIFEST.replace(NO_WAIVER, ""), images=GOOD)
    ledger = tmp_path / "anchored.sqlite"
    for day in ("2026-03-01", "2026-03-02"):
        res = run(
            "check",
            root,
            "-p",
            mini_profile,
            "--param",
            "tolerance_xy=0.5",
            "--out",
            tmp_path / day,
            "--ledger",
            ledger,
            "--date",
            day,
            "--format",
            "json",
        )
        assert res.exit_code in (0, 1, 3), res.output
    lines = anchor.read_text(encoding="utf-8").splitlines()
    assert [ln.split()[0] for ln in lines] == ["1", "2"]
    assert run("ledger", "verify", "--ledger", ledger).exit_code == 0
    with sqlite3.connect(ledger) as con:
        first = con.execute("SELECT hash FROM runs WHERE seq = 1").fetchone()[0]
        con.execute("DELETE FROM qcrs WHERE run_id = 2")
        con.execute("DELETE FROM run_files WHERE run_id = 2")
        con.execute("DELETE FROM runs WHERE seq = 2")
        con.execute("UPDATE ledger_head SET seq = 1, hash = ?", (first,))
    bad = run("ledger", "verify", "--ledger", ledger)
    assert bad.exit_code == 1 and "anchor line 2" in bad.output, bad.output
