"""qcr.json records: compact pass / not-applicable columns, every other record in full (issue 14 item 2).

The expected records come from the evaluation itself (its verdict arrays, counted with numpy) and
from :func:`orthospec.qcr.iter_records`, the record-by-record writer the compact form replaces;
the document is read back from the bytes written, never from the dict in memory.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from orthospec import api
from orthospec.engine.evaluator import VERDICTS
from orthospec.qcr import (
    all_records,
    dumps,
    iter_dumps,
    iter_records,
    point_frame,
    point_rows,
    stable,
)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "deliveries"
CHECKER = ROOT / "examples" / "checker" / "aerial-fail"  # the ITT tolerance and manual verdicts


@pytest.fixture(scope="module")
def fail_check() -> api.CheckResult:
    return api.check(EXAMPLES / "aerial-fail", "jrc-v3", date="2026-11-21", checker=CHECKER)


def _json(x):
    return json.loads(json.dumps(x))


def test_every_non_pass_record_is_in_full(fail_check: api.CheckResult) -> None:
    doc = json.loads(dumps(fail_check.document))
    expected = sum(
        int(np.count_nonzero(~np.isin(np.asarray(r.verdict), (0, 3))))  # not pass, not n/a
        for r in fail_check.evaluation.results
    )
    assert expected > 0
    assert len(doc["records"]) == expected
    assert all(r["verdict"] not in ("pass", "not_applicable") for r in doc["records"])
    counts = {v: 0 for v in VERDICTS}
    for r in fail_check.evaluation.results:
        for code in np.asarray(r.verdict).tolist():
            counts[VERDICTS[code]] += 1
    got = {v: 0 for v in VERDICTS}
    for rec in all_records(doc):
        got[rec["verdict"]] += 1
    assert got == counts
    assert doc["summary"] == {
        "rules": len(fail_check.evaluation.results),
        "records": sum(counts.values()),
        **counts,
    }


def test_expanded_records_equal_the_records_in_full(fail_check: api.CheckResult) -> None:
    doc = json.loads(dumps(fail_check.document))
    full = _json(list(iter_records(fail_check.evaluation)))
    assert list(all_records(doc)) == full
    # a record does not repeat its rule's text: each quote is written once, in its rule summary
    text = dumps(fail_check.document)
    for rule in ("JRC-12.7-RMSEY", "JRC-6.3-CV"):
        recs = [r for r in full if r["rule"] == rule]
        assert len(recs) > 1 and {r["verdict"] for r in recs} - {"pass", "not_applicable"}
        quote = recs[0]["quote"]
        assert text.count(json.dumps(quote, ensure_ascii=False)) == sum(
            r["quote"] == quote for r in doc["rules"]
        )
    # rules over the same images share one item list
    refs = [b["items"]["ref"] for b in doc["compact"].values() if isinstance(b["items"], dict)]
    assert refs and all(isinstance(doc["compact"][rid][col], list) for rid, col in refs)


def test_stream_equals_text_and_is_deterministic(
    fail_check: api.CheckResult, tmp_path: Path
) -> None:
    text = "".join(iter_dumps(fail_check.document))
    assert text == dumps(fail_check.document)
    again = api.check(EXAMPLES / "aerial-fail", "jrc-v3", date="2026-11-21", checker=CHECKER)
    assert dumps(again.document) == text
    # the header is indented like json.dumps(indent=1) would write it
    doc = json.loads(text)
    assert json.dumps(doc["summary"], indent=1).replace("\n", "\n ") in text


def test_old_documents_are_read_as_they_are() -> None:
    recs = [
        {"rule": "R", "item": "a", "verdict": "pass"},
        {"rule": "R", "item": "b", "verdict": "fail"},
    ]
    assert list(all_records({"schema": "orthospec.qcr/1", "records": recs})) == recs


def test_point_tables_in_every_form() -> None:
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame(
        {"point_id": ["P1", "P2"], "dx": [0.1234567890123, float("nan")], "n": [1, 2]}
    )
    table = stable({"points": frame})["points"]
    assert table == {
        "columns": ["point_id", "dx", "n"],
        "data": {"point_id": ["P1", "P2"], "dx": [0.123456789, None], "n": [1, 2]},
    }
    rows = [{"point_id": "P1", "dx": 0.123456789, "n": 1}, {"point_id": "P2", "dx": None, "n": 2}]
    assert point_rows(table) == rows
    assert point_rows(rows) == rows
    assert point_rows(None) == []
    back = point_frame(table)
    assert list(back.columns) == ["point_id", "dx", "n"] and back["n"].tolist() == [1, 2]
    assert point_frame(rows)["point_id"].tolist() == ["P1", "P2"]


def test_vectorised_rounding_equals_the_scalar_rule() -> None:
    from orthospec.qcr import round_sig

    rng = np.random.default_rng(7)
    x = np.concatenate(
        [
            rng.normal(0, 1, 20000) * 10.0 ** rng.integers(-25, 25, 20000),
            [0.3, 1 / 3, 2.5e-30, 5e25, 123456789012345.0],
        ]
    )
    assert round_sig(x).tolist() == [stable(float(v)) for v in x]


def test_problems_only_reading_and_streamed_csv_junit(fail_check: api.CheckResult) -> None:
    import csv
    import io
    import xml.etree.ElementTree as ET

    from orthospec.qcr import iter_csv, iter_junit

    doc = json.loads(dumps(fail_check.document))
    every = list(all_records(doc))
    assert list(all_records(doc, compact=False)) == [
        r for r in every if r["verdict"] not in ("pass", "not_applicable")
    ]
    rows = list(csv.reader(io.StringIO("".join(iter_csv(doc, rows_per_piece=7)))))
    assert len(rows) == 1 + len(every) == 1 + doc["summary"]["records"]
    assert [(r[0], r[3], r[6]) for r in rows[1:]] == [
        (r["rule"], r["item"], r["verdict"]) for r in every
    ]
    root = ET.fromstring("".join(iter_junit(doc)))
    cases = root.findall("./testsuite/testcase")
    assert len(cases) == len(every)
    assert len(root.findall("./testsuite/testcase/failure")) == sum(
        r["verdict"] in ("fail", "missing") for r in every
    )
    assert int(root.get("failures")) == doc["summary"]["fail"] + doc["summary"]["missing"]


def test_a_version_1_document_reads_and_renders_as_version_2(fail_check: api.CheckResult) -> None:
    """qcr.json files written before the compact form (every record in full) give the same CSV and
    terminal summary: readers go through all_records, whatever the version."""
    import io

    from rich.console import Console

    from orthospec.qcr import to_csv
    from orthospec.reports.terminal import render

    v2 = json.loads(dumps(fail_check.document))
    v1 = {k: v for k, v in v2.items() if k not in ("compact", "evidence")}
    v1["schema"] = "orthospec.qcr/1"
    v1["records"] = _json(list(iter_records(fail_check.evaluation)))
    assert to_csv(v1) == to_csv(v2)

    def terminal(doc: dict) -> str:
        buf = io.StringIO()
        render(doc, Console(file=buf, width=120, highlight=False, soft_wrap=False))
        return buf.getvalue()

    assert terminal(v1) == terminal(v2)
