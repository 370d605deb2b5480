"""qcr.csv and junit.xml written per compact block (issue 14): the same bytes as the record-by-record
writers they replace (``_iter_csv_records`` / ``_iter_junit_records``, which expand every record
through :func:`orthospec.qcr.all_records`).

Compared on the example deliveries (the document in memory and read back from qcr.json) and on
generated documents that hold what the block writers treat specially: mixed pass / not-applicable
columns, full records between compact items, waiver requests, per-item requirements, row columns
with missing rows, selectors, shared ``ref`` columns, records without a rule summary, ids with
commas, quotes, formula starts and control characters, and slices of a block cut anywhere.
"""

from __future__ import annotations

import csv
import io
import json
import random
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from orthospec import api, qcr
from orthospec.qcr import (
    _iter_csv_records,
    _iter_junit_records,
    all_records,
    dumps,
    iter_csv,
    iter_junit,
    natural_key,
)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "deliveries"


def _same(doc) -> None:
    assert "".join(iter_csv(doc)) == "".join(_iter_csv_records(doc))
    assert "".join(iter_junit(doc)) == "".join(_iter_junit_records(doc))


@pytest.mark.parametrize(
    ("name", "kw"),
    [
        ("aerial-pass", {"params": ["tolerance_xy=0.5", "map_crs=EPSG:25832"]}),
        ("aerial-fail", {"checker": ROOT / "examples" / "checker" / "aerial-fail"}),
    ],
)
def test_examples_same_bytes(name: str, kw: dict) -> None:
    doc = api.check(EXAMPLES / name, "jrc-v3", date="2026-11-21", **kw).document
    assert doc["compact"] and doc["records"]  # both forms are exercised
    _same(doc)
    _same(json.loads(dumps(doc)))  # as a reader of qcr.json sees it


# --- generated documents ----------------------------------------------------------------------

_IDS = [
    "P{}",
    "A&{}",
    "A>{}",
    "A'{}",
    "P,{}",
    'P"{}',
    "={}",
    "+{}",
    "-{}",
    "@{}",
    "\t{}",
    "x\x01{}",
    "a<b>&'{}",
    "l\n{}",
    "c\r{}",
    "ü{}",
    "IMG_{}",
    "B{}_x{}",
    "{}",
    " {} ",
    "\x7f{}",
    "q\"'{}",
]
_TEXTS = [
    "",
    "fine",
    "x, y",
    'say "hi"',
    "=SUM(A1)",
    "-3",
    "@me",
    "a\nb",
    "c\rd",
    "<&>",
    "tab\there",
    "ctl\x02x",
    "≤ 0.5 m",
    "'single'",
]


def _ids(rng: random.Random, n: int) -> list[str]:
    """``n`` distinct ids from a few of the templates (a block of plain ids, or with one kind of
    special character, or mixed), in natural order."""
    pool = rng.sample(_IDS, rng.choice([1, 2, 4, len(_IDS)]))
    out: set[str] = set()
    while len(out) < n:
        t = rng.choice(pool)
        out.add(t.format(*(rng.randrange(0, 400) for _ in range(t.count("{}")))))
    return sorted(out, key=natural_key)


def _value(rng: random.Random):
    return rng.choice(
        [
            rng.uniform(-5, 5),
            rng.choice([0.0, 1e-7, 123456789.0, 2.5e20, -0.0]),
            rng.randrange(-9, 99),
            None,
            True,
            False,
            rng.choice(_TEXTS),
        ]
    )


def _column(rng: random.Random, values: list, allow_all: bool = True):
    if allow_all and len(values) > 1 and rng.random() < 0.3:
        return {"all": values[0]}
    return values


def _doc(seed: int) -> dict:
    rng = random.Random(seed)
    evidence = [
        {"file": "tables/checkpoints.csv", "sha256": "a" * 64, "rows": [1, 2]},
        {"file": "tables/checkpoints.csv", "sha256": "a" * 64},
        {
            "file": "tables/checkpoints.csv",
            "sha256": "a" * 64,
            "where": {"block": "B02"},
            "rows_count": 3,
        },
        {"file": "tables/checkpoints.csv", "sha256": "a" * 64, "where": {}, "rows_count": 9},
        {"file": "delivery.yaml", "sha256": "b" * 64, "path": "sensor.type"},
        {"file": '=t,ab"le.csv', "sha256": "c" * 64},
        {"file": "imgs/a b.tif", "sha256": "d" * 64, "rows": [4]},
        {"file": "-cp.csv", "sha256": "e" * 64, "path": "x"},
    ]
    rules, records, compact = [], [], {}
    verdict_counts = dict.fromkeys(
        ("pass", "fail", "warn", "not_applicable", "missing", "error", "waived"), 0
    )
    fail_on = rng.choice(["fail", "warn"])
    first_items = None
    for k in range(rng.randrange(3, 8)):
        rid = (
            rng.choice([f"R-{k}", f"R-{k}", f"R&{k}", f"R&<{k}>", f'R"{k}', f"R'{k}", f"R\x03{k}"])
            + f"-{k}"
        )
        unit = rng.choice(["m", None, "%", "deg"])
        req = {
            "op": "<=",
            "value": 0.5,
            "unit": unit,
            "text": rng.choice(["≤ 0.5 m", "< 1", '"x"', "=1", "a,b"]),
        }
        summary = {
            "rule": rid,
            "title": rng.choice(["Title", "T, <&>", "=T"]),
            "scope": rng.choice(["image", "block", "checkpoint"]),
            "level": rng.choice(["mandatory", "recommended", None]),
            "consequence": rng.choice(["reject_block", "warn"]),
            "citation": rng.choice([{"document": "JRC EUR 23638 EN", "section": "12.7"}, {}]),
            "quote": "",
            "manual": False,
            "measure": rng.choice(["checkpoints.rmse_x", "=m", "a,b", ""]),
            "unit": unit,
            "requirement": req,
        }
        items = (
            first_items if first_items and rng.random() < 0.3 else _ids(rng, rng.randrange(0, 60))
        )
        first_items = first_items or items
        full_mask = [rng.random() < 0.25 for _ in items]
        comp = [it for it, f in zip(items, full_mask, strict=True) if not f]
        for it, f in zip(items, full_mask, strict=True):
            if not f:
                continue
            v = rng.choice(["fail", "warn", "missing", "error", "waived"])
            verdict_counts[v] += 1
            rec = {
                "rule": rid,
                "item": it,
                "verdict": v,
                "measured": _value(rng),
                "evidence": rng.sample(evidence, rng.randrange(0, 3)),
                "message": rng.choice(_TEXTS),
            }
            if rng.random() < 0.3:
                rec["requirement"] = {**req, "value": 0.7, "text": rng.choice(_TEXTS)}
            if v == "waived":
                rec["waiver"] = {"justification": "ok", "approver": "x"}
                rec["waived_verdict"] = "fail"
            if rng.random() < 0.2:
                rec["waiver_requested"] = {"justification": rng.choice(_TEXTS)}
            records.append(rec)
        if comp and rng.random() < 0.3:  # an item in full and compact: the full record comes first
            twin = (
                {**records[-1], "item": rng.choice(comp)}
                if records and records[-1]["rule"] == rid
                else None
            )
            if twin is not None:
                verdict_counts[twin["verdict"]] += 1
                mine = [r for r in records if r["rule"] == rid] + [twin]
                records = [r for r in records if r["rule"] != rid] + sorted(
                    mine, key=lambda r: natural_key(r["item"])
                )
        if comp:
            n = len(comp)
            verdicts = [rng.choice(["pass", "pass", "not_applicable"]) for _ in comp]
            if rng.random() < 0.5:
                verdicts = [rng.choice(["pass", "not_applicable"])] * n
            for v in verdicts:
                verdict_counts[v] += 1
            measured = (
                [_value(rng) for _ in comp] if rng.random() < 0.7 else [rng.uniform(0, 1)] * n
            )
            block = {
                "items": comp
                if rng.random() < 0.8 or comp != first_items
                else {"ref": [rules[0]["rule"], "items"]},
                "verdict": _column(rng, verdicts),
                "measured": _column(rng, measured),
            }
            if rng.random() < 0.4:
                texts = [rng.choice(_TEXTS) for _ in range(3)]
                block["requirement"] = _column(
                    rng, [{**req, "value": 0.1 * j, "text": texts[j % 3]} for j in range(n)]
                )
            form = rng.randrange(3)
            if form == 0:
                block["evidence"] = {
                    "entry": rng.choice([1, 5, 7]),
                    "rows": [rng.choice([None, rng.randrange(1, 10**6)]) for _ in comp],
                }
            elif form == 1:
                block["evidence"] = _column(
                    rng,
                    [sorted(rng.sample(range(len(evidence)), rng.randrange(0, 3))) for _ in comp],
                )
            else:
                block["evidence"] = {"all": [2]}
            block["message"] = _column(
                rng,
                [
                    None if v == "pass" and rng.random() < 0.7 else rng.choice(_TEXTS)
                    for v in verdicts
                ],
            )
            if rng.random() < 0.3:
                block["message"] = {"all": None}
            if rng.random() < 0.3:
                block["waiver_requested"] = _column(
                    rng, [rng.choice([None, {"justification": "j"}]) for _ in comp]
                )
            compact[rid] = block
        rules.append(summary)
    if rng.random() < 0.5:  # a record whose rule has no summary: all_records yields it as stored
        records.append(
            {
                "rule": "ORPHAN",
                "item": "x,1",
                "verdict": "fail",
                "evidence": [],
                "measured": {"value": 1.0, "unit": None},
                "message": "m",
                "title": "t",
                "scope": "image",
                "clause": {},
                "level": "mandatory",
                "consequence": "warn",
                "measure": "m",
                "requirement": {"text": "<1"},
            }
        )
    total = sum(verdict_counts.values())
    return {
        "schema": "orthospec.qcr/3",
        "profile": {"id": "p&<1>"},
        "fail_on": fail_on,
        "summary": {"rules": len(rules), "records": total, **verdict_counts},
        "rules": rules,
        "records": records,
        "compact": compact,
        "evidence": evidence,
    }


@pytest.mark.parametrize("seed", range(40))
def test_generated_same_bytes(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    doc = _doc(seed)
    monkeypatch.setattr(qcr.blocks, "BLOCK_CHUNK", 1 + seed % 7)  # slices cut anywhere in a block
    _same(doc)
    monkeypatch.setattr(qcr.blocks, "BLOCK_CHUNK", 50_000)
    _same(doc)
    text = "".join(iter_csv(doc))
    # every row reads back whole: a CR became a (quoted) LF (csv_safe), so no cell splits its row
    rows = list(csv.reader(io.StringIO(text)))
    assert len(rows) == 1 + sum(1 for _ in all_records(doc))
    items = {r["item"] for r in all_records(doc)}
    assert {row[3] for row in rows[1:]} <= {
        ("'" + i if i.startswith(("=", "+", "-", "@", "\t", "\r")) else i)
        .replace("\r\n", "\n")
        .replace("\r", "\n")
        for i in items
    }  # formulas neutralised
    suites = ET.fromstring(
        "".join(iter_junit(doc)).encode()
    )  # well-formed, control characters escaped
    assert sum(int(s.get("tests")) for s in suites) == sum(1 for _ in all_records(doc))


def test_version1_document_written_record_by_record() -> None:
    doc = _doc(3)
    v1 = {**doc, "records": list(all_records(doc))}
    del v1["compact"]
    assert "".join(iter_csv(v1)) == "".join(iter_csv(doc))
    assert "".join(iter_junit(v1)) == "".join(iter_junit(doc))
