"""Three rounds through the CLI: the ledger's history and the signed PDF show the sequence (JRC §12.8)."""

import pdfplumber
from click.testing import CliRunner
from tests.conftest import MANIFEST

from orthospec.cli.main import cli


def run(*args):
    return CliRunner().invoke(cli(), list(map(str, args)))


def delivery(make_delivery, name, did, rolls):
    rows = "\n".join(f"I{i},f{i}.tif,B1,{r},1000,30,{i * 100},{(i % 4) * 100}" for i, r in enumerate(rolls))
    return make_delivery(name, manifest=MANIFEST.replace("id: D1", f"id: {did}").replace(
        "waivers: [{rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}]\n", ""),
        images="image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n" + rows + "\n")


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
        res = run("check", root, "-p", mini_profile, "--out", tmp_path / f"o{n}", "--ledger", ledger,
                  "--date", f"2026-0{n}-01", "--format", "json")
        codes.append(res.exit_code)
        assert f"recorded run #{n}" in res.output
        if n == 2:  # after a failing round the family is tightened: a larger sample with the suspect image
            s = run("sample", root, "-p", mini_profile, "--seed", 1, "--fraction", 0.1, "--ledger", ledger,
                    "--out", tmp_path / "s2.csv")
            assert "audit level tightened" in s.output
            assert any(line.startswith("I7,") for line in (tmp_path / "s2.csv").read_text().splitlines())
    assert codes == [1, 1, 0]  # 15 %, then 10 % of the images fail (> 5 %, §12.3), then none
    hist = run("history", "P1", "--ledger", ledger)
    assert hist.exit_code == 0
    out = hist.output
    assert out.index("D1") < out.index("D2") < out.index("D3")
    assert "redelivery" in out
    sign = run("signoff", 3, "--by", "Maria Rossi", "--role", "supervisor", "--note", "accepted after 2nd redelivery",
               "--ledger", ledger)
    assert sign.exit_code == 0, sign.output
    rep = run("report", "--ledger", ledger, "--run", 3, "--format", "pdf", "--out", tmp_path / "rep")
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
