"""qcr.json at scale (issue 14 item 3): evidence that does not grow with the points, the same order
and the same bytes.

A delivery with thousands of check points is built from the example (benchmarks/checkpoints.py
writes the table; a blank line and padded block cells are planted). The selectors the document
writes are re-applied to the CSV with the ``csv`` module, independently of orthospec's reader, and
must give exactly the rows the evaluation held in memory; the natural order's vectorised path is
compared with ``sorted(key=natural_key)`` on generated ids.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from orthospec import api
from orthospec.qcr import (
    ROWS_LISTED_MAX,
    all_records,
    dumps,
    evidence_rows,
    iter_records,
    natural_key,
    natural_order,
)
from orthospec.qcr_model import QcrDocument

ROOT = Path(__file__).resolve().parents[1]
POINTS = 12_000
PARAMS = ["tolerance_xy=0.5", "map_crs=EPSG:25832"]


def _bench_checkpoints():
    spec = importlib.util.spec_from_file_location(
        "bench_checkpoints_qcr", ROOT / "benchmarks" / "checkpoints.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def many(tmp_path_factory) -> Path:
    """aerial-pass with 12,000 generated check points, a blank line and padded block cells."""
    root = tmp_path_factory.mktemp("many") / "cp"
    shutil.copytree(ROOT / "examples" / "deliveries" / "aerial-pass", root)
    table = root / "tables" / "checkpoints.csv"
    _bench_checkpoints().write_checkpoints(table, POINTS)
    lines = table.read_text(encoding="utf-8").splitlines(keepends=True)
    for k in range(
        5, len(lines), 997
    ):  # " B02 ,": the reader strips cells; selectors name the stripped value
        head, block, rest = lines[k].split(",", 2)
        lines[k] = f"{head}, {block} ,{rest}"
    lines.insert(4001, "\n")  # a blank line: counted as a data row number, never selected
    table.write_text("".join(lines), encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def checked(many: Path) -> api.CheckResult:
    return api.check(many, "jrc-v3", params=PARAMS, date="2026-11-21")


def _rows_by_csv(path: Path, where: dict[str, str]) -> list[int]:
    """The data rows (1-based, blank lines counted, never selected) whose stripped cells equal
    ``where`` - with the csv module, not orthospec's reader."""
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = [h.strip() for h in next(reader)]
        out = []
        for n, cells in enumerate(reader, start=1):
            if not any(c.strip() for c in cells):
                continue
            row = dict(zip(header, (c.strip() for c in cells), strict=True))
            if all(row[k] == v for k, v in where.items()):
                out.append(n)
    return out


def test_selectors_resolve_to_exactly_the_rows_held_in_memory(
    many: Path, checked: api.CheckResult
) -> None:
    doc = json.loads(dumps(checked.document))
    written = {(r["rule"], r["item"]): r["evidence"] for r in all_records(doc)}
    seen = set()
    for r in checked.evaluation.results:
        for i in range(len(r.items)):
            ev = r.evidence[i]
            if not any(len(e.rows) > ROWS_LISTED_MAX for e in ev):
                continue
            entries = written[(r.rule.id, str(r.items[i]))]
            assert len(entries) == len(set(ev))
            for e, entry in zip(sorted(set(ev)), entries, strict=True):
                assert (entry["file"], entry["sha256"]) == (e.file, e.sha256)
                if "where" not in entry:
                    assert entry["rows"] == list(e.rows)
                    continue
                assert "rows" not in entry and entry["rows_count"] == len(e.rows)
                key = (e.file, json.dumps(entry["where"], sort_keys=True))
                if key not in seen:
                    independent = _rows_by_csv(many / e.file, entry["where"])
                    assert independent == list(e.rows)
                    assert (
                        evidence_rows(entry, many) == independent
                    )  # the helper readers are offered
                    seen.add(key)
    wheres = {k[1] for k in seen}
    # every row of the table (counts, completeness, roll-up shares) and each block's points
    assert wheres == {"{}", '{"block": "B01"}', '{"block": "B02"}', '{"block": "B03"}'}


def test_evidence_does_not_grow_with_the_points(checked: api.CheckResult) -> None:
    doc = json.loads(dumps(checked.document))
    assert len(doc["evidence"]) < 200  # one entry per point before (issue 14)
    block = doc["compact"]["JRC-DEF-CHECKPOINT-ACCURACY"]
    assert set(block["evidence"]) == {"entry", "rows"} and len(block["evidence"]["rows"]) == POINTS
    assert "requirement" not in block  # one threshold for every point: the rule summary's
    assert doc["evidence"][block["evidence"]["entry"]]["file"] == "tables/checkpoints.csv"
    longest = max(len(json.dumps(r["evidence"])) for r in doc["records"])
    assert longest < 4 * ROWS_LISTED_MAX  # no record lists a block's thousands of rows


def test_many_points_same_bytes_schema_and_every_record(
    many: Path, checked: api.CheckResult
) -> None:
    jsonschema = pytest.importorskip("jsonschema")
    text = dumps(checked.document)
    again = api.check(many, "jrc-v3", params=PARAMS, date="2026-11-21")
    assert dumps(again.document) == text
    doc = json.loads(text)
    assert doc["schema"] == "orthospec.qcr/3"
    QcrDocument.model_validate(doc)
    schema = json.loads((ROOT / "specs" / "schema" / "qcr.schema.json").read_text(encoding="utf-8"))
    jsonschema.validate(doc, schema)
    non_pass = sum(
        int(np.count_nonzero(~np.isin(np.asarray(r.verdict), (0, 3))))
        for r in checked.evaluation.results
    )
    assert non_pass > 0 and len(doc["records"]) == non_pass
    # expanding the compact form gives every record exactly as written in full
    expanded = list(all_records(doc))
    assert len(expanded) == doc["summary"]["records"]
    assert expanded == json.loads(json.dumps(list(iter_records(checked.evaluation))))


# --- natural order ------------------------------------------------------------------------------


def _expected(ids: list[str]) -> list[int]:
    return sorted(range(len(ids)), key=lambda i: natural_key(ids[i]))


_fast_ids = st.builds(
    lambda p, d: p + d,
    st.sampled_from(["", "P", "IMG_", "p", "P-", "a b", "Z"]),
    st.text(alphabet="0123456789", max_size=22),
)
_any_ids = st.text(alphabet=st.sampled_from(list("0123456789aAP_-. ٣é\x00")), max_size=8)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(_fast_ids, _any_ids), max_size=40), st.integers(0, 2**32 - 1))
def test_natural_order_equals_natural_key(extra: list[str], seed: int) -> None:
    rng = np.random.default_rng(seed)
    # enough ids of the common shape for the vectorised path, plus the drawn ones (any shape)
    base = [
        f"P{int(v):0{int(w)}d}"
        for v, w in zip(rng.integers(0, 5000, 300), rng.integers(1, 8, 300), strict=True)
    ]
    ids = base + extra
    perm = rng.permutation(len(ids))
    ids = [ids[i] for i in perm]
    assert natural_order(ids).tolist() == _expected(ids)


def test_natural_order_on_known_cases() -> None:
    ids = [
        "P10",
        "P9",
        "P09",
        "P009",
        "P",
        "P0",
        "P00",
        "Q1",
        "",
        "10",
        "9",
        "F01_0101",
        "F01_0002",
        "P1a",
    ] * 30
    assert natural_order(ids).tolist() == _expected(ids)
    assert [ids[i] for i in natural_order(ids)[::30]] == [
        "",
        "9",
        "10",
        "F01_0002",
        "F01_0101",
        "P",
        "P0",
        "P00",
        "P1a",
        "P009",
        "P09",
        "P9",
        "P10",
        "Q1",
    ]
    big = [f"P{i:07d}" for i in range(50_000)][::-1]
    assert natural_order(big).tolist() == list(range(50_000))[::-1]


def test_reports_and_csv_name_the_selected_rows(checked: api.CheckResult) -> None:
    """A record whose evidence is a selector still says which rows: HTML and qcr.csv name the
    column, the value and the count (JRC §2.4: a record traces to its evidence)."""
    from orthospec.qcr import to_csv
    from orthospec.reports.html import ReportOptions, render_html

    doc = json.loads(dumps(checked.document))
    selected = [
        (r["item"], e)
        for r in all_records(doc, compact=False)
        for e in r["evidence"]
        if "where" in e
    ]
    assert selected  # block-level findings over thousands of points
    item, entry = next((i, e) for i, e in selected if e["where"])
    shown = f"where block = {entry['where']['block']} ({entry['rows_count']} rows)"
    assert item == entry["where"]["block"]
    assert shown in render_html(doc, ReportOptions(bounded=False, figures=False))
    assert f"tables/checkpoints.csv#{shown}" in to_csv(doc)


def test_block_distributions_in_threads_give_the_same_document(
    many: Path, checked: api.CheckResult, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Above PARALLEL_POINTS the blocks' distributions (KD-trees) run in threads beside the
    blunder screening: the same bytes as one block after the other."""
    from orthospec.engine.providers import checkpoints

    monkeypatch.setattr(checkpoints, "PARALLEL_POINTS", 0)
    threaded = api.check(many, "jrc-v3", params=PARAMS, date="2026-11-21")
    assert dumps(threaded.document) == dumps(checked.document)


def test_a_selector_is_not_reapplied_to_a_changed_file(
    many: Path, checked: api.CheckResult, tmp_path: Path
) -> None:
    from orthospec.errors import OrthospecError

    doc = json.loads(dumps(checked.document))
    entry = next(e for e in doc["evidence"] if e.get("where"))
    copy = tmp_path / "d"
    (copy / "tables").mkdir(parents=True)
    text = (many / entry["file"]).read_text(encoding="utf-8")
    (copy / entry["file"]).write_text(text.replace(",B02,", ",B01,", 1), encoding="utf-8")
    with pytest.raises(OrthospecError, match="SHA-256 differs"):
        evidence_rows(entry, copy)
    assert evidence_rows({"file": "x.csv", "sha256": "0" * 64, "rows": [3, 4]}, copy) == [3, 4]


def test_csv_and_junit_by_block_same_bytes(checked: api.CheckResult) -> None:
    """qcr.csv and junit.xml written per compact block give the bytes of the record-by-record
    writers (every record expanded through all_records) for 12,000 check points."""
    from orthospec.qcr import _iter_csv_records, _iter_junit_records, iter_csv, iter_junit

    doc = checked.document
    assert (
        max(len(b["items"]) for b in doc["compact"].values() if isinstance(b["items"], list))
        >= POINTS
    )
    assert "".join(iter_csv(doc)) == "".join(_iter_csv_records(doc))
    assert "".join(iter_junit(doc)) == "".join(_iter_junit_records(doc))
