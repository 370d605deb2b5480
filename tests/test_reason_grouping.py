"""The findings list and the ledger audit group by reason code (issue 28 item 4).

Why: ``missing`` has several causes (an unset parameter, no GSD, no value, an unsigned manual
check...) that a reader told apart only by reading messages. Every non-pass record carries a
``reason`` (orthospec.verdicts.Reason); the findings (terminal, report section 1) and the ledger's
audit state group by it. Expected counts are read from the records' own ``reason`` field in
qcr.json, independently of the grouping code.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from tests.checking import CHECKERS, EXAMPLES

from orthospec import verdicts as V
from orthospec.cli.main import cli
from orthospec.ledger.audit import MARGINAL, family_of
from orthospec.qcr import all_records
from orthospec.reports.findings import by_reason, findings, reason_line


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """aerial-fail checked once, recorded in a SQLite ledger, with its terminal and HTML output."""
    tmp = tmp_path_factory.mktemp("reasons")
    ledger = tmp / "qc.sqlite"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(EXAMPLES / "aerial-fail"),
            "--profile",
            "jrc-v3",
            "--checker",
            str(CHECKERS / "aerial-fail"),
            "--date",
            "2026-11-21",
            "--out",
            str(tmp / "out"),
            "--format",
            "terminal,json,html",
            "--ledger",
            str(ledger),
        ],
        terminal_width=400,
    )
    assert res.exit_code == 1, res.output
    doc = json.loads((tmp / "out" / "qcr.json").read_text(encoding="utf-8"))
    return {
        "doc": doc,
        "terminal": res.output,
        "html": (tmp / "out" / "report.html").read_text(encoding="utf-8"),
        "ledger": ledger,
    }


def _problems(doc: dict[str, Any]) -> list[dict[str, Any]]:
    return [r for r in all_records(doc, compact=False) if r["verdict"] in V.PROBLEMS]


def test_findings_count_every_problem_record_under_its_reason(run: dict[str, Any]) -> None:
    problems = _problems(run["doc"])
    expected = Counter(r["reason"] for r in problems)
    assert len(expected) >= 3  # the example fails for several reasons (not_met, no_value, ...)
    groups = by_reason(findings(problems))
    assert {g["reason"]: g["records"] for g in groups} == dict(expected)
    # most records first, and the terminal prints the same grouping
    assert [g["records"] for g in groups] == sorted(expected.values(), reverse=True)
    line = reason_line(findings(problems))
    assert line is not None and line in " ".join(run["terminal"].split())
    for why, n in expected.items():
        assert f"{why} " in line and f"({n} record" in line


def test_one_finding_holds_records_of_one_reason_per_rule(run: dict[str, Any]) -> None:
    """A finding of a single rule never mixes reasons (``no_value`` and ``not_met`` of one rule are
    two findings); the report lists the groups in section 1."""
    for f in findings(_problems(run["doc"])):
        if len(f.rules) == 1:
            assert set(f.reasons) == {f.reason}
        assert sum(f.reasons.values()) == f.n_records
    assert 'class="data by-reason"' in run["html"]
    for why in Counter(r["reason"] for r in _problems(run["doc"])):
        assert f'<td class="mono">{why}</td>' in run["html"]


def test_ledger_audit_groups_each_family_by_reason(run: dict[str, Any]) -> None:
    doc = run["doc"]
    project = CliRunner().invoke(
        cli(), ["ledger", "runs", "--ledger", str(run["ledger"]), "--json"]
    )
    key = json.loads(project.output)[0]["audit_trail"]
    res = CliRunner().invoke(
        cli(), ["ledger", "state", key, "--ledger", str(run["ledger"]), "--json"]
    )
    assert res.exit_code == 0, res.output
    families = {f["family"]: f for f in json.loads(res.output)["families"]}
    # independent count: qcr.json's failing and warning records per family and reason
    expected: dict[str, Counter[str]] = {}
    for r in all_records(doc, compact=False):
        if r["verdict"] in (*V.FAILING, V.WARN):
            expected.setdefault(family_of(r), Counter())[r["reason"]] += 1
    assert expected, "the example has failing records"
    for fam, counts in expected.items():
        got = {g["reason"]: g["records"] for g in families[fam]["by_reason"]}
        assert families[fam]["state"] == "tightened"
        assert {k: v for k, v in got.items() if k != MARGINAL} == dict(counts), fam
    # a family whose runs all passed clearly has no reason groups
    assert all(not f["by_reason"] for f in families.values() if f["state"] == "normal")
    text = CliRunner().invoke(cli(), ["ledger", "state", key, "--ledger", str(run["ledger"])])
    assert "- not_met: " in text.output


def test_a_ledger_without_reasons_in_its_documents_reads_the_verdict_default(
    tmp_path: Path,
) -> None:
    """Runs recorded before reason codes: the audit groups by the verdict's default reason."""
    from orthospec.ledger.audit import RunRecords, audit_states

    recs = [
        {"rule": "R1", "item": "B1", "verdict": "missing", "family": "§1", "measured": None,
         "requirement": {"op": "<=", "value": 1.0}},
        {"rule": "R2", "item": "B1", "verdict": "fail", "family": "§1", "measured": 2.0,
         "requirement": {"op": "<=", "value": 1.0}},
        {"rule": "R3", "item": "B1", "verdict": "pass", "family": "§1", "measured": 0.99,
         "requirement": {"op": "<=", "value": 1.0}},
    ]  # fmt: skip
    st = audit_states([RunRecords(1, recs, reasons=lambda: {("R1", "B1"): "unset_parameter"})])
    assert {w: n for w, n, _ in st["§1"].by_reason} == {
        "unset_parameter": 1,
        "not_met": 1,
        MARGINAL: 1,
    }
    st = audit_states([RunRecords(1, recs)])
    assert {w: n for w, n, _ in st["§1"].by_reason} == {"no_value": 1, "not_met": 1, MARGINAL: 1}
