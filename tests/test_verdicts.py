"""The verdict vocabulary (orthospec.verdicts): the names every layer imports instead of spelling them."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys

import yaml

from orthospec import verdicts as V


def test_names_are_the_plain_strings_of_the_qcr_format() -> None:
    # the strings documented in docs/ARCHITECTURE.md (qcr.json "verdict" and "summary" keys)
    assert (V.PASS, V.FAIL, V.WARN, V.NOT_APPLICABLE, V.MISSING, V.ERROR, V.WAIVED) == (
        "pass",
        "fail",
        "warn",
        "not_applicable",
        "missing",
        "error",
        "waived",
    )
    assert (V.ACCEPTED, V.REJECTED, V.INCOMPLETE) == ("accepted", "rejected", "incomplete")
    assert set(V.VERDICTS) == {
        "pass",
        "fail",
        "warn",
        "not_applicable",
        "missing",
        "error",
        "waived",
    }
    assert len(V.VERDICTS) == 7 and V.OVERALL == ("accepted", "rejected", "incomplete")
    assert V.CONSEQUENCES == (
        "reject_item",
        "reject_block",
        "return_delivery",
        "incomplete",
        "warn",
    )
    assert set(V.REJECTING) == {"reject_item", "reject_block", "return_delivery"}


def test_names_serialise_as_plain_strings() -> None:
    # JSON (qcr.json), YAML (profiles' tests: expect) and SQLite (the ledger) store the bare word
    assert json.dumps([V.PASS, V.REJECTED]) == '["pass", "rejected"]'
    assert yaml.safe_dump(V.MISSING).strip().splitlines()[0] == "missing"
    con = sqlite3.connect(":memory:")
    assert con.execute("select ?", (V.NOT_APPLICABLE,)).fetchone()[0] == "not_applicable"


def test_codes_index_the_tuple() -> None:
    for name in V.VERDICTS:
        assert V.VERDICTS[V.CODE[name]] == name


def test_severity_covers_every_verdict_once_worst_first() -> None:
    assert sorted(V.SEVERITY) == sorted(V.VERDICTS)
    # an error (the check could not run) is worse than a measured failure, which is worse than
    # an unmeasured value; a waived finding is still worse than a clean pass
    order = [
        V.severity_rank(v)
        for v in ("error", "fail", "missing", "warn", "waived", "pass", "not_applicable")
    ]
    assert order == sorted(order) == list(range(7))
    assert V.severity_rank("no-such-verdict") == 7
    assert V.PROBLEMS == ("error", "fail", "missing", "warn")
    assert set(V.FAILING) == {"fail", "missing", "error"}
    assert set(V.NEUTRAL) == {"not_applicable", "waived"}


def test_worst() -> None:
    assert V.worst(["pass", "warn", "pass"]) == "warn"
    assert V.worst({"pass", "missing", "fail"}) == "fail"
    assert V.worst(["waived", "not_applicable"]) == "waived"
    assert V.worst([]) == "not_applicable"
    assert V.overall(True) == "rejected" and V.overall(False) == "accepted"
    # a real failure rejects whatever the checker still has to do; open checker's work alone is incomplete
    assert V.overall(True, True) == "rejected" and V.overall(False, True) == "incomplete"


def test_exit_codes() -> None:
    assert [V.exit_code(v) for v in ("accepted", "rejected", "incomplete")] == [0, 1, 3]
    assert V.exit_code("no-such-verdict") == 1  # never 0 for a verdict we do not know


def test_import_is_standard_library_only() -> None:
    code = (
        "import sys; import orthospec.verdicts; "
        "bad = [m for m in ('numpy', 'pandas', 'pydantic', 'yaml', 'click') if m in sys.modules]; "
        "print(bad)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
