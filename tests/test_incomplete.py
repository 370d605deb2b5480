"""The `incomplete` consequence and overall verdict (issue 26 "What to build" 1).

The checker's own faults (too few or bad check points, a short sample, a manual check not signed)
never reject the contractor's products (JRC §12.5 "relocated", §12.6 blunders removed, §12.7
"acquisition of further points", §12.3/§12.8 "The Commission will check"): the check stays open,
verdict `incomplete`, exit code 3, never ACCEPTED, with a line saying what the checker must add. A
real failure elsewhere still rejects. Every expectation below follows from the edit the test makes
(how many points it removed, which rule it signed), never from pinned output.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml
from click.testing import CliRunner
from tests.checking import (
    CHECKERS,
    DATE,
    EXAMPLES,
    check_with,
    read_table,
    records,
    resigned,
    write_table,
)
from tests.checking import copy_example as _copy

from orthospec import verdicts as V
from orthospec.cli.main import cli as main
from orthospec.ledger.signed import after_signoff
from orthospec.qcr_model import QcrDocument

PARAMS = ["tolerance_xy=0.5", "map_crs=EPSG:25832"]

#: a profile of two block rules: the count is the checker's (incomplete), the RMSE the contractor's
COUNT_PROFILE = """\
orthospec_profile: 1
id: incomplete-test
version: 1.0.0
title: check point count is the checker's, RMSE the contractor's
source: {title: JRC, seed: 002_7421c4ca450e31c6.txt}
parameters:
  tolerance_xy: {unit: m, required: true, description: ITT tolerance}
  min_checkpoints: {unit: "1", default: 20, description: Table 12}
rules:
  - id: T-MIN-CP
    title: At least 20 check points per block
    clause: {document: JRC EUR 23638 EN, section: "12.4", table: "12"}
    quote: "Generally a minimum number of 20 well-distributed Check Points per site is necessary"
    scope: block
    measure: checkpoints.n
    requirement: {op: ">=", value: min_checkpoints, unit: "1"}
    consequence: incomplete
  - id: T-RMSEY
    title: Block RMSEy within the tolerance
    clause: {document: JRC EUR 23638 EN, section: "12.7"}
    quote: "The planimetric threshold will be applied independently in X, and Y."
    scope: block
    measure: checkpoints.rmse_y
    requirement: {op: "<=", value: tolerance_xy, unit: m}
    consequence: reject_block
"""


def _keep_points(d: Path, block: str, n: int) -> int:
    """Keep the first ``n`` check points of ``block`` (the checker measured fewer); returns how many
    were there before."""
    header, rows = read_table(d, "checkpoints")
    mine = [r for r in rows if r["block"] == block]
    keep = {r["point_id"] for r in mine[:n]}
    write_table(
        d, "checkpoints", header, [r for r in rows if r["block"] != block or r["point_id"] in keep]
    )
    return len(mine)


def _profile(tmp_path: Path) -> Path:
    p = tmp_path / "incomplete-test.yaml"
    p.write_text(COUNT_PROFILE, encoding="utf-8")
    return p


def _unsigned(example: str, tmp_path: Path) -> Path:
    """The example's checker folder (its check point measurements, ITT values) with no manual verdict."""
    return resigned(CHECKERS / example, EXAMPLES / example, tmp_path / "unsigned", manual_checks=[])


def _mandatory_manual_missing(doc: dict[str, Any]) -> set[str]:
    return {
        r["rule"]
        for r in records(doc)
        if r.get("manual") and r["level"] == "mandatory" and r["verdict"] == V.MISSING
    }


# --- the roll-up ----------------------------------------------------------------------------------


def test_too_few_checkpoints_is_incomplete_not_a_rejected_block(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    before = _keep_points(d, "B01", 14)
    assert before >= 20  # the example had enough: the shortfall is the edit's
    res = check_with(d, _profile(tmp_path), params=["tolerance_xy=0.5"], date=DATE)
    doc = res.document
    assert doc["verdict"] == V.INCOMPLETE and not res.accepted
    assert doc["rollup"]["reasons"] == [] and doc["rollup"]["rejected"] == {}
    todo = doc["rollup"]["incomplete"]
    assert len(todo) == 1 and todo[0].startswith("B01: 6 more check points ("), todo  # 20 - 14
    assert "T-MIN-CP" in todo[0] and "§12.4" in todo[0]
    # the record itself stays a failure of the rule (what was measured is not hidden)
    rec = {(r["rule"], r["item"]): r for r in records(doc)}
    assert (
        rec[("T-MIN-CP", "B01")]["verdict"] == V.FAIL
        and rec[("T-MIN-CP", "B01")]["consequence"] == "incomplete"
    )
    QcrDocument.model_validate(json.loads(json.dumps(doc)))


def test_a_real_failure_still_rejects_and_the_open_work_is_listed(tmp_path: Path) -> None:
    # aerial-fail: B02's RMSEy 0.641 m > 0.5 m; B03 has fewer than 20 check points (its README)
    d = _copy("aerial-fail", tmp_path)
    chk = resigned(
        CHECKERS / "aerial-fail", d, tmp_path / "chk"
    )  # the external check points (issue 29)
    n_b03 = sum(r["block"] == "B03" for r in read_table(chk.parent, "checkpoints")[1])
    assert n_b03 < 20
    res = check_with(d, _profile(tmp_path), checker=chk, params=["tolerance_xy=0.5"], date=DATE)
    doc = res.document
    assert doc["verdict"] == V.REJECTED
    assert doc["rollup"]["rejected"] == {"block": ["B02"]}
    assert any("T-RMSEY" in r for r in doc["rollup"]["reasons"])
    assert not any("T-MIN-CP" in r for r in doc["rollup"]["reasons"])
    want = f"B03: {20 - n_b03} more check points ("  # issue 26's own example: "B03: 6 more check points"
    assert [t[: len(want)] for t in doc["rollup"]["incomplete"]] == [want]


def test_enough_points_and_a_pass_is_accepted(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    res = check_with(d, _profile(tmp_path), params=["tolerance_xy=0.5"], date=DATE)
    assert res.document["verdict"] == V.ACCEPTED and res.document["rollup"]["incomplete"] == []


def test_unsigned_manual_checks_leave_the_check_incomplete() -> None:
    """Without the checker's file every mandatory manual rule is `missing`: the checker has not
    signed them (JRC §2: the contractor's manual_checks are evidence). Nothing else fails in
    aerial-pass, so the check is incomplete, one line per unsigned mandatory manual rule."""
    res = check_with(EXAMPLES / "aerial-pass", "jrc-v3", params=PARAMS, date=DATE)
    doc = res.document
    unsigned = _mandatory_manual_missing(doc)
    assert unsigned and doc["verdict"] == V.INCOMPLETE and doc["rollup"]["reasons"] == []
    todo = doc["rollup"]["incomplete"]
    # and, without the checker's folder, its own check point measurements (issue 29)
    external = [t for t in todo if "JRC-12.4-EXTERNAL-CHECKPOINTS" in t]
    assert len(external) == 1 and "the checker measured no check points of its own" in external[0]
    todo = [t for t in todo if t not in external]
    assert {t.split(":", 1)[0] for t in todo} == unsigned
    assert all("sign the manual check" in t for t in todo)


def test_unsigned_manual_checks_do_not_hide_a_rejection(tmp_path: Path) -> None:
    res = check_with(
        EXAMPLES / "aerial-fail", "jrc-v3", checker=_unsigned("aerial-fail", tmp_path), date=DATE
    )
    doc = res.document
    assert doc["verdict"] == V.REJECTED
    assert any("JRC-12.7-RMSEY" in r for r in doc["rollup"]["reasons"])
    # besides the unsigned checks, the checker's open work the example documents (expected.yaml)
    exp = yaml.safe_load((EXAMPLES / "aerial-fail" / "expected.yaml").read_text(encoding="utf-8"))
    documented = {x["item"] for x in exp["jrc_v3"]["incomplete"]}
    assert {t.split(":", 1)[0] for t in doc["rollup"]["incomplete"]} == _mandatory_manual_missing(
        doc
    ) | documented


def test_a_manual_check_signed_fail_still_rejects(tmp_path: Path) -> None:
    """Only the *unsigned* manual check is the checker's open work: signed fail, its consequence holds."""
    d = _copy("aerial-pass", tmp_path)
    chk = resigned(CHECKERS / "aerial-pass.yaml", d, tmp_path / "chk.yaml")
    doc = yaml.safe_load(chk.read_text(encoding="utf-8"))
    entry = next(e for e in doc["manual_checks"] if e["check"] == "JRC-5.3-IDQA")
    entry["verdict"] = "fail"
    chk.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    res = check_with(d, "jrc-v3", checker=chk, date=DATE)
    assert res.document["verdict"] == V.REJECTED
    assert any(r.startswith("JRC-5.3-IDQA") for r in res.document["rollup"]["reasons"])


# --- what each output says --------------------------------------------------------------------------


def test_cli_exit_code_3_terminal_junit_html(tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = CliRunner().invoke(
        main(),
        [
            "check",
            str(EXAMPLES / "aerial-pass"),
            "-p",
            "jrc-v3",
            *[a for p in PARAMS for a in ("--param", p)],
            "--out",
            str(out),
            "--format",
            "terminal,json,junit,html",
            "--date",
            DATE,
        ],
    )
    assert res.exit_code == 3, res.output
    assert "verdict: INCOMPLETE" in res.output
    assert "the check is incomplete: the checker must still" in res.output
    assert "JRC-5.3-IDQA" in res.output.split("the checker must still", 1)[1]
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    assert doc["verdict"] == "incomplete"
    junit = (out / "junit.xml").read_text(encoding="utf-8")
    assert 'name="JRC-5.3-IDQA[D-2026-014]"' in junit
    case = junit.split('name="JRC-5.3-IDQA[D-2026-014]"', 1)[1].split("</testcase>", 1)[0]
    assert 'type="incomplete"' in case
    html = (out / "report.html").read_text(encoding="utf-8")
    assert (
        'class="banner incomplete"' in html
        and "The check is incomplete: the checker must still" in html
    )


def test_cli_exit_codes_0_and_1_unchanged(tmp_path: Path) -> None:
    for example, code in (("aerial-pass", 0), ("aerial-fail", 1)):
        res = CliRunner().invoke(
            main(),
            [
                "check",
                str(EXAMPLES / example),
                "-p",
                "jrc-v3",
                "--checker",
                str(CHECKERS / example),
                "--out",
                str(tmp_path / example),
                "--format",
                "json",
                "--date",
                DATE,
            ],
        )
        assert res.exit_code == code, res.output


# --- after sign-off (ledger/signed.py) ---------------------------------------------------------------


def _signoff(rules: set[str], verdict: str = "pass") -> list[dict[str, Any]]:
    return [
        {
            "by": "S. Upervisor",
            "role": "supervisor",
            "date": "2026-11-22",
            "manual": dict.fromkeys(sorted(rules), verdict),
        }
    ]


def test_after_signoff_every_unsigned_manual_check_signed_pass_accepts(tmp_path: Path) -> None:
    doc = check_with(
        EXAMPLES / "aerial-pass", "jrc-v3", checker=_unsigned("aerial-pass", tmp_path), date=DATE
    ).document
    unsigned = _mandatory_manual_missing(doc)
    assert after_signoff(doc, _signoff(unsigned))["verdict"] == V.ACCEPTED
    some = set(sorted(unsigned)[:-1])
    after = after_signoff(doc, _signoff(some))
    assert after["verdict"] == V.INCOMPLETE and sorted(unsigned)[-1] in after["basis"]
    # signed fail: a rejecting rule rejects; a rule whose consequence is the checker's stays incomplete
    assert after_signoff(doc, _signoff({"JRC-5.3-IDQA"}, "fail"))["verdict"] == V.REJECTED
    assert after_signoff(doc, _signoff({"JRC-12.4-SELECTION"}, "fail"))["verdict"] == V.INCOMPLETE


def test_after_signoff_of_open_checkpoint_work_stays_incomplete(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    _keep_points(d, "B01", 14)
    doc = check_with(d, _profile(tmp_path), params=["tolerance_xy=0.5"], date=DATE).document
    # a sign-off cannot supply the missing check points: only manual verdicts are signed
    after = after_signoff(doc, _signoff({"T-MIN-CP"}))
    assert after["verdict"] == V.INCOMPLETE and "T-MIN-CP" in after["basis"]


@pytest.mark.parametrize("verdict", ["accepted", "rejected", "incomplete"])
def test_schema_takes_each_overall_verdict(verdict: str) -> None:
    doc = check_with(EXAMPLES / "aerial-pass", "jrc-v3", params=PARAMS, date=DATE).document
    QcrDocument.model_validate({**json.loads(json.dumps(doc)), "verdict": verdict})
    with pytest.raises(ValueError):
        QcrDocument.model_validate({**json.loads(json.dumps(doc)), "verdict": "maybe"})


def test_an_incomplete_run_in_the_ledger_signs_without_acknowledging_a_rejection(
    tmp_path: Path,
) -> None:
    """The ledger stores `incomplete` as the run's verdict; the supervisor signing the missing manual
    checks needs no --acknowledge-rejection (nothing was rejected), and the report of the signed run
    shows INCOMPLETE with ACCEPTED after sign-off."""
    import pdfplumber

    ledger = tmp_path / "qc.sqlite"
    run = CliRunner().invoke(
        main(),
        [
            "check",
            str(EXAMPLES / "aerial-pass"),
            "-p",
            "jrc-v3",
            "--checker",
            str(_unsigned("aerial-pass", tmp_path)),
            "--out",
            str(tmp_path / "o"),
            "--format",
            "json",
            "--date",
            DATE,
            "--ledger",
            str(ledger),
            "--operator",
            "A. Auditor",
        ],
    )
    assert run.exit_code == 3, run.output
    doc = json.loads((tmp_path / "o" / "qcr.json").read_text(encoding="utf-8"))
    manual = [a for r in sorted(_mandatory_manual_missing(doc)) for a in ("--manual", f"{r}=pass")]
    sign = CliRunner().invoke(
        main(),
        [
            "signoff",
            "1",
            "--by",
            "M. Rossi",
            "--role",
            "supervisor",
            "--date",
            "2026-11-22",
            *manual,
            "--ledger",
            str(ledger),
        ],
    )
    assert sign.exit_code == 0, sign.output
    rep = CliRunner().invoke(
        main(),
        [
            "report",
            "--ledger",
            str(ledger),
            "--run",
            "1",
            "--format",
            "pdf",
            "--out",
            str(tmp_path / "rep"),
        ],
    )
    assert rep.exit_code == 0, rep.output
    with pdfplumber.open(tmp_path / "rep" / "report.pdf") as pdf:
        flat = " ".join((pdf.pages[0].extract_text() or "").split())
    assert "INCOMPLETE" in flat and "Verdict after sign-off: ACCEPTED" in flat, flat
