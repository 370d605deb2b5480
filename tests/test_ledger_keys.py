"""A countersignature that means something (issue 29 item 5, JRC §2.4 independent supervisor).

People in the ledger are keys (real ``ssh-keygen`` keys and signatures, an allowed-signers
register), names are compared as one person however typed, and the report of run N carries the
head that includes run N, so a chain rebuilt to rewrite run N is caught against that report.
Real SQLite ledgers, real checks of small deliveries, real PDFs read back.
"""

from __future__ import annotations

import json
import shutil
import sqlite3
import subprocess
from pathlib import Path

import pdfplumber
import pytest
import sqlalchemy as sa
from click.testing import CliRunner
from tests.conftest import MANIFEST

from orthospec.cli.main import cli
from orthospec.errors import LedgerError
from orthospec.ledger import models as m
from orthospec.ledger import open_ledger
from orthospec.ledger.chain import sha256_text, signoff_hash
from orthospec.ledger.db import to_url
from orthospec.ledger.names import display_name, same_person
from orthospec.ledger.verify import rehash_run

DATA = Path(__file__).parent / "data"
GOOD = "image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n" + "\n".join(
    f"I{i},f{i}.tif,B1,0.5,1000,30,{i * 100},{(i % 4) * 100}" for i in range(20)) + "\n"
NO_WAIVER = "waivers: [{rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}]\n"
CHECKER = (
    "orthospec_checker: 1\nchecker: {name: Eva External, role: external QC}\n"
    "delivery: {id: D1}\nmanual_checks:\n"
    "  - {check: R-VIS, item: '*', date: 2026-02-28, verdict: pass, note: haze-free}\n"
)

#: the four ways the run's checker "A. Auditor" countersigned its own run before (issue 29 item 5)
TRICKS = {
    "zero-width space": "A.\u200b Auditor",
    "soft hyphen": "A. Au\u00additor",
    "Cyrillic A": "\u0410. Auditor",
    "no space": "A.Auditor",
}


def run(*args: object):
    return CliRunner().invoke(cli(), [str(a) for a in args])


def keygen(folder: Path, name: str) -> Path:
    key = folder / name
    subprocess.run(
        ["ssh-keygen", "-q", "-t", "ed25519", "-N", "", "-C", name, "-f", str(key)], check=True
    )
    return key


def register(path: Path, people: dict[str, Path]) -> Path:
    """An allowed-signers file: principal -> public key (ssh-keygen(1) ALLOWED SIGNERS)."""
    lines = []
    for who, key in people.items():
        kind, blob = Path(f"{key}.pub").read_text(encoding="utf-8").split()[:2]
        lines.append(f'"{who}" {kind} {blob}')
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.fixture
def delivery(make_delivery, tmp_path: Path) -> dict[str, Path]:
    root = make_delivery(
        "d",
        manifest=MANIFEST.replace(NO_WAIVER, ""),
        images=GOOD,
        manual="check,item,inspector,date,verdict\n",
    )
    checker = tmp_path / "checker.yaml"
    checker.write_text(CHECKER, encoding="utf-8")
    return {"root": root, "checker": checker, "ledger": tmp_path / "ledger.sqlite", "tmp": tmp_path}


def check(d: dict[str, Path], mini_profile: Path, n: int, *extra: object, fmt: str = "json"):
    return run(
        "check",
        d["root"],
        "-p",
        mini_profile,
        "--param",
        "tolerance_xy=0.5",
        "--out",
        d["tmp"] / f"o{n}",
        "--checker",
        d["checker"],
        "--ledger",
        d["ledger"],
        "--date",
        f"2026-03-0{n}",
        "--format",
        fmt,
        *extra,
    )


def page1(pdf: Path) -> str:
    with pdfplumber.open(pdf) as doc:
        return " ".join((doc.pages[0].extract_text() or "").split())


# --- names --------------------------------------------------------------------------------------


@pytest.mark.parametrize("trick", list(TRICKS.values()), ids=list(TRICKS))
def test_the_four_name_tricks_are_the_same_person(trick: str) -> None:
    assert same_person("A. Auditor", trick)
    assert display_name(trick) in (
        "A. Auditor",
        "A.Auditor",
        "\u0410. Auditor",
    )  # invisible ones gone


@pytest.mark.parametrize(
    ("a", "b"),
    [
        ("A. Auditor", "auditor, a."),
        ("A. Auditor", "Ａ. Ａuditor"),  # word order, full-width
        ("Ivan Petrov", "lvan Petrov"),
        ("Olga Ek", "0lga Ek"),
        ("Mary Rao", "rnary Rao"),  # I/l, 0/O, rn/m
    ],
)
def test_look_alike_names_are_the_same_person(a: str, b: str) -> None:
    assert same_person(a, b)


@pytest.mark.parametrize(
    ("a", "b"),
    [
        ("A. Auditor", "B. Auditor"),
        ("A. Auditor", "Anna Auditor"),
        ("Maria Rossi", "Mario Rossi"),
        ("A. Auditor", ""),
        ("\u200b", "\u200b"),
    ],
)
def test_different_people_stay_different(a: str, b: str) -> None:
    assert not same_person(a, b)


def test_the_checker_cannot_countersign_under_a_tricked_name(delivery, mini_profile) -> None:
    res = check(delivery, mini_profile, 1, "--operator", "A. Auditor")
    assert res.exit_code == 0, res.output
    with open_ledger(delivery["ledger"]) as led:
        for trick in TRICKS.values():
            with pytest.raises(LedgerError, match="independent countersignature"):
                led.signoff(1, by=trick, date="2026-03-02")
        sid = led.signoff(1, by="Maria Rossi", date="2026-03-02")
        assert led.signoffs(1)[-1]["id"] == sid and led.verify().ok


def test_the_checker_named_in_the_checker_file_cannot_countersign_a_run_without_operator(
    delivery, mini_profile
) -> None:
    res = check(delivery, mini_profile, 1)  # no --operator: the checker file names Eva External
    assert res.exit_code == 0, res.output
    for name in ("Eva External", "Eva\u2060External", "EVA EXTERNAL"):
        refused = run(
            "signoff", 1, "--by", name, "--date", "2026-03-02", "--ledger", delivery["ledger"]
        )
        assert refused.exit_code != 0
        assert "checker named in the checker file" in str(refused.exception), refused.output
    ok = run(
        "signoff", 1, "--by", "Maria Rossi", "--date", "2026-03-02", "--ledger", delivery["ledger"]
    )
    assert ok.exit_code == 0 and "unsigned (a typed name, no key)" in ok.output, ok.output


# --- keys ---------------------------------------------------------------------------------------


def test_the_key_that_signed_the_run_cannot_countersign_it_under_any_name(
    delivery, mini_profile
) -> None:
    auditor = keygen(delivery["tmp"], "auditor")
    res = check(delivery, mini_profile, 1, "--key", auditor)  # no register: the key is the identity
    assert res.exit_code == 0, res.output
    refused = run(
        "signoff",
        1,
        "--key",
        auditor,
        "--by",
        "Zoe Other",
        "--date",
        "2026-03-02",
        "--ledger",
        delivery["ledger"],
    )
    assert refused.exit_code != 0 and "signed check run 1 (its checker)" in str(refused.exception)
    rossi = keygen(delivery["tmp"], "rossi")
    ok = run(
        "signoff",
        1,
        "--key",
        rossi,
        "--by",
        "Maria Rossi",
        "--date",
        "2026-03-02",
        "--ledger",
        delivery["ledger"],
    )
    assert ok.exit_code == 0 and "signed by key SHA256:" in ok.output, ok.output
    with open_ledger(delivery["ledger"], create=False) as led:
        assert led.verify().ok
        assert led.run(1).key_fingerprint != led.signoffs(1)[0]["key"] is not None


def test_with_a_register_every_entry_is_signed_by_a_registered_key(
    delivery, mini_profile, monkeypatch
) -> None:
    tmp = delivery["tmp"]
    auditor, rossi, stranger = keygen(tmp, "auditor"), keygen(tmp, "rossi"), keygen(tmp, "stranger")
    monkeypatch.setenv(
        "ORTHOSPEC_ALLOWED_SIGNERS",
        str(register(tmp / "allowed", {"A. Auditor": auditor, "Maria Rossi": rossi})),
    )
    unsigned = check(delivery, mini_profile, 1, "--operator", "A. Auditor")
    assert isinstance(unsigned.exception, LedgerError) and "must be signed" in str(
        unsigned.exception
    )
    outsider = check(delivery, mini_profile, 1, "--key", stranger)
    assert isinstance(outsider.exception, LedgerError)
    assert "not in the allowed-signers file" in str(outsider.exception)
    assert not (tmp / "o1" / "qcr.json").exists()  # refused before anything was written
    res = check(delivery, mini_profile, 1, "--key", auditor)
    assert res.exit_code == 0, res.output
    with open_ledger(delivery["ledger"], create=False) as led:
        assert led.run(1).signer == "A. Auditor"
        # the register names the key's owner: claiming another name with it is refused
        with pytest.raises(LedgerError, match="not the owner of the key"):
            led.signoff(1, key=rossi, by="Someone Else", date="2026-03-02")
        with pytest.raises(LedgerError, match="its checker"):
            led.signoff(1, key=auditor, date="2026-03-02")
        led.signoff(1, key=rossi, date="2026-03-02")
        assert led.signoffs(1)[0]["by"] == "Maria Rossi" and led.verify().ok
    # an editor renames the countersigner to the checker and rebuilds the chain: the chain is
    # consistent again, but the signature is not the named person's
    with sqlite3.connect(delivery["ledger"]) as con:
        con.execute("UPDATE signoffs SET by_name = 'A. Auditor'")
    rebuild(delivery["ledger"])
    bad = run("ledger", "verify", "--ledger", delivery["ledger"])
    assert bad.exit_code == 1 and "signature of A. Auditor does not verify" in bad.output, (
        bad.output
    )


# --- the run's own head in its report -----------------------------------------------------------


def rebuild(ledger: Path) -> None:
    """What someone with write access does after editing rows: recompute every hash and link in
    chain order (document checksums, run and sign-off hashes, the head), so the chain verifies."""
    eng = sa.create_engine(to_url(ledger))
    with eng.begin() as conn:
        runs = {
            r["id"]: dict(r)
            for r in conn.execute(
                sa.select(*[c for c in m.runs.c if c.name != "document"])
            ).mappings()
        }
        signs = [dict(s) for s in conn.execute(sa.select(m.signoffs)).mappings()]
        entries = sorted(
            [("run", r) for r in runs.values()] + [("signoff", s) for s in signs],
            key=lambda e: e[1]["seq"],
        )
        prev = m.GENESIS
        for kind, row in entries:
            row["prev_hash"] = prev
            if kind == "run":
                doc = conn.execute(
                    sa.select(m.runs.c.document).where(m.runs.c.id == row["id"])
                ).scalar_one()
                row["document_sha256"] = sha256_text(doc)
                row["hash"] = rehash_run(conn, row)[0]
                conn.execute(
                    sa.update(m.runs)
                    .where(m.runs.c.id == row["id"])
                    .values(
                        prev_hash=prev, document_sha256=row["document_sha256"], hash=row["hash"]
                    )
                )
            else:
                row["run_hash"] = runs[row["run_id"]]["hash"]
                row["hash"] = signoff_hash(row, prev)
                conn.execute(
                    sa.update(m.signoffs)
                    .where(m.signoffs.c.id == row["id"])
                    .values(prev_hash=prev, run_hash=row["run_hash"], hash=row["hash"])
                )
            prev = row["hash"]
        conn.execute(sa.update(m.head).values(hash=prev))
    eng.dispose()


def rewrite_verdict(ledger: Path, run_id: int, verdict: str) -> None:
    with sqlite3.connect(ledger) as con:
        doc = json.loads(
            con.execute("SELECT document FROM runs WHERE id = ?", (run_id,)).fetchone()[0]
        )
        doc["verdict"] = verdict
        con.execute(
            "UPDATE runs SET document = ?, verdict = ? WHERE id = ?",
            (json.dumps(doc), verdict, run_id),
        )


def test_a_chain_rebuilt_to_rewrite_run_n_is_caught_against_run_ns_own_report(
    delivery, mini_profile
) -> None:
    delivery["checker"].write_text(
        CHECKER.replace("verdict: pass", "verdict: fail"), encoding="utf-8"
    )
    assert (
        check(delivery, mini_profile, 1, "--operator", "A. Auditor", fmt="json,pdf").exit_code == 1
    )
    res = check(delivery, mini_profile, 2, "--operator", "A. Auditor", fmt="json,pdf")
    assert res.exit_code == 1 and "recorded run #2" in res.output, res.output
    own = delivery["tmp"] / "o2" / "report.pdf"
    with open_ledger(delivery["ledger"], create=False) as led:
        run2 = led.run(2).hash
        assert led.head()[1] == run2
    assert run2 in page1(own).replace(" ", "")  # the report of run 2 prints run 2's own entry
    ledger = delivery["ledger"]
    rewrite_verdict(ledger, 2, "accepted")
    rebuild(ledger)
    plain = run("ledger", "verify", "--ledger", ledger)
    assert plain.exit_code == 0, plain.output  # the rebuilt chain is consistent in itself
    caught = run("ledger", "verify", "--ledger", ledger, "--against", own)
    assert caught.exit_code == 1 and "TAMPERED" in caught.output and run2[:16] in caught.output, (
        caught.output
    )
    rep = run(
        "report",
        "--ledger",
        ledger,
        "--run",
        2,
        "--format",
        "pdf",
        "--out",
        delivery["tmp"] / "r2",
        "--against",
        own,
    )
    assert rep.exit_code == 0 and "TAMPERED" in rep.output, rep.output
    assert "LEDGER TAMPERED" in page1(delivery["tmp"] / "r2" / "report.pdf")


def test_a_signed_run_rewritten_and_rebuilt_fails_its_signature(delivery, mini_profile) -> None:
    delivery["checker"].write_text(
        CHECKER.replace("verdict: pass", "verdict: fail"), encoding="utf-8"
    )
    key = keygen(delivery["tmp"], "auditor")
    assert check(delivery, mini_profile, 1, "--key", key).exit_code == 1
    rewrite_verdict(delivery["ledger"], 1, "accepted")
    rebuild(delivery["ledger"])
    bad = run("ledger", "verify", "--ledger", delivery["ledger"])
    assert bad.exit_code == 1 and "runs run 1 (seq 1): signature of" in bad.output, bad.output
    rep = run(
        "report",
        "--ledger",
        delivery["ledger"],
        "--run",
        1,
        "--format",
        "html",
        "--out",
        delivery["tmp"] / "r1",
    )
    assert rep.exit_code == 0 and "TAMPERED" in rep.output


# --- ledgers recorded before keys ---------------------------------------------------------------


def test_a_ledger_recorded_before_keys_migrates_and_still_verifies(tmp_path: Path) -> None:
    """tests/data/ledger-0001.sqlite was recorded by orthospec at 95a2ffd (schema 0001: two runs of a
    small delivery by "Carl Checker", a sign-off by "Maria Rossi"). Its entries keep their hashes,
    show as unsigned, keep their project as audit trail, and the chain goes on with signed entries."""
    old = tmp_path / "old.sqlite"
    shutil.copyfile(DATA / "ledger-0001.sqlite", old)
    with sqlite3.connect(old) as con:
        before = con.execute(
            "SELECT seq, hash FROM runs UNION SELECT seq, hash FROM signoffs ORDER BY 1"
        ).fetchall()
        assert con.execute("SELECT version_num FROM alembic_version").fetchone() == ("0001",)
    with open_ledger(old, create=False) as led:
        rep = led.verify()
        assert rep.ok and rep.entries == 3, rep.problems
        runs = led.runs()
        assert [(r.audit, r.signer, r.key_fingerprint) for r in runs] == [("P1", None, None)] * 2
        assert [s["key"] for s in led.signoffs()] == [None]
        with pytest.raises(LedgerError, match="independent countersignature"):
            led.signoff(2, by="Carl\u00adChecker", date="2026-03-07", acknowledge_rejection=True)
        key = keygen(tmp_path, "inspector")
        led.signoff(
            1,
            key=key,
            by="Ian Spector",
            role="inspector",
            date="2026-03-07",
            acknowledge_rejection=True,
        )
        assert led.verify().ok
    with sqlite3.connect(old) as con:
        after = con.execute(
            "SELECT seq, hash FROM runs UNION SELECT seq, hash FROM signoffs ORDER BY 1"
        ).fetchall()
        assert con.execute("SELECT version_num FROM alembic_version").fetchone() == ("0002",)
    assert after[:3] == before and len(after) == 4
