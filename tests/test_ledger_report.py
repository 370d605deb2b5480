"""Three rounds through the CLI: the ledger's history and the signed PDF show the sequence (JRC §12.8)."""

import re

import pdfplumber
from click.testing import CliRunner
from tests.checking import LEDGER_CHECKER
from tests.conftest import MANIFEST

from orthospec.cli.main import cli

#: the checker's file for delivery ID (docs/CHECKER.md): the ITT value in force and the verdict of
#: the mini profile's manual rule (the delivery's own manual_checks and tender.parameters are the
#: contractor's statements, not values in force)
CHECKER = LEDGER_CHECKER


def run(*args):
    return CliRunner().invoke(cli(), list(map(str, args)))


def delivery(make_delivery, name, did, rolls):
    rows = "\n".join(
        f"I{i},f{i}.tif,B1,{r},1000,30,{i * 100},{(i % 4) * 100}" for i, r in enumerate(rolls)
    )
    return make_delivery(
        name,
        manifest=MANIFEST.replace("id: D1", f"id: {did}").replace(
            "waivers: [{rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}]\n",
            "",
        ),
        images="image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n"
        + rows
        + "\n",
    )


def checker_file(tmp_path, did):
    p = tmp_path / f"checker-{did}.yaml"
    p.write_text(CHECKER.format(id=did), encoding="utf-8")
    return p


def test_three_rounds_history_signoff_and_pdf(make_delivery, mini_profile, tmp_path):
    ledger = tmp_path / "ledger.sqlite"
    bad = [0.5] * 20
    bad[3] = bad[7] = bad[11] = 5.0
    partial = [0.5] * 20
    partial[7] = partial[11] = 5.0
    good = [0.5] * 20
    codes = []
    for n, (did, rolls) in enumerate((("D1", bad), ("D2", partial), ("D3", good)), start=1):
        root = delivery(make_delivery, f"r{n}", did, rolls)
        res = run(
            "check",
            root,
            "-p",
            mini_profile,
            "--out",
            tmp_path / f"o{n}",
            "--ledger",
            ledger,
            "--date",
            f"2026-0{n}-01",
            "--format",
            "json",
            "--checker",
            checker_file(tmp_path, did),
        )
        codes.append(res.exit_code)
        assert f"recorded run #{n}" in res.output
        if (
            n == 2
        ):  # after a failing round the family is tightened: a larger sample with the suspect image
            s = run(
                "sample",
                root,
                "-p",
                mini_profile,
                "--seed",
                1,
                "--fraction",
                0.1,
                "--ledger",
                ledger,
                "--out",
                tmp_path / "s2.csv",
            )
            assert "audit level tightened" in s.output
            assert any(
                line.startswith("I7,") for line in (tmp_path / "s2.csv").read_text().splitlines()
            )
    assert codes == [1, 1, 0]  # 15 %, then 10 % of the images fail (> 5 %, §12.3), then none
    hist = run("history", "P1", "--ledger", ledger)
    assert hist.exit_code == 0
    out = hist.output
    assert out.index("D1") < out.index("D2") < out.index("D3")
    assert "redelivery" in out
    sign = run(
        "signoff",
        3,
        "--by",
        "Maria Rossi",
        "--role",
        "supervisor",
        "--note",
        "accepted after 2nd redelivery",
        "--ledger",
        ledger,
    )
    assert sign.exit_code == 0, sign.output
    rep = run(
        "report", "--ledger", ledger, "--run", 3, "--format", "pdf", "--out", tmp_path / "rep"
    )
    assert rep.exit_code == 0, rep.output
    with pdfplumber.open(tmp_path / "rep" / "report.pdf") as pdf:
        text = "\n".join(p.extract_text() or "" for p in pdf.pages[:3])
    assert "Delivery history" in text
    assert "Maria Rossi" in text
    for did in ("D1", "D2", "D3"):
        assert did in text
    assert run("ledger", "verify", "--ledger", ledger).exit_code == 0


def test_report_needs_json_or_ledger_run(tmp_path):
    assert run("report").exit_code == 2
    assert run("report", "--run", 1).exit_code == 2


def _this_run(pdf):
    """(run, round, kind, delivery) of the history row marked "(this report)" in a report PDF."""
    with pdfplumber.open(pdf) as doc:
        text = "\n".join(p.extract_text() or "" for p in doc.pages)
    # "(this report)" may wrap inside its cell: "3 (this 1 delivery 2026-01-01 D1 ...\nreport)"
    rows = re.findall(
        r"(\S+) \(this(?: report\))? (\d+) (delivery|redelivery|recheck) \S+ (\S+)", text
    )
    assert len(rows) == 1, text
    run_, rnd, kind, did = rows[0]
    return run_, int(rnd), kind, did


def test_round_at_check_time_equals_the_ledger_report(make_delivery, mini_profile, tmp_path):
    """Issue 15: the PDF archived at check time states the same JRC §12.8 round as
    `orthospec report --ledger --run N` does later, for a delivery, a re-check of the same content
    and a redelivery of different content under the same delivery id (the round is content-keyed:
    "Redelivery of products will be followed by a further independent check on a new sample")."""
    ledger = tmp_path / "ledger.sqlite"
    checker = checker_file(tmp_path, "D1")
    first = delivery(make_delivery, "first", "D1", [0.5] * 19 + [5.0])
    fixed = delivery(make_delivery, "fixed", "D1", [0.5] * 20)  # same id, one image corrected
    expected = [(first, 1, "delivery"), (first, 1, "recheck"), (fixed, 2, "redelivery")]
    for n, (root, rnd, kind) in enumerate(expected, start=1):
        out = tmp_path / f"check{n}"
        res = run(
            "check",
            root,
            "-p",
            mini_profile,
            "--out",
            out,
            "--ledger",
            ledger,
            "--checker",
            checker,
            "--date",
            f"2026-0{n}-01",
            "--format",
            "json,pdf",
        )
        assert f"recorded run #{n}" in res.output, res.output
        at_check = _this_run(out / "report.pdf")
        assert at_check == (
            str(n),
            rnd,
            kind,
            "D1",
        )  # the run's own id: it is recorded as it is written
        rep = run(
            "report",
            "--ledger",
            ledger,
            "--run",
            n,
            "--format",
            "pdf",
            "--out",
            tmp_path / f"rep{n}",
        )
        assert rep.exit_code == 0, rep.output
        assert _this_run(tmp_path / f"rep{n}" / "report.pdf") == (str(n), rnd, kind, "D1")
