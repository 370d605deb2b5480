"""check --format parquet: every record as one typed table (issue 14 item 2)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from orthospec.qcr import PARQUET_COLUMNS, all_records

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")
pd = pytest.importorskip("pandas")

ROOT = Path(__file__).resolve().parents[1]
FAIL = ROOT / "examples" / "deliveries" / "aerial-fail"
CHECKER = ROOT / "examples" / "checker" / "aerial-fail"  # the ITT tolerance and manual verdicts
ORTHOSPEC = [sys.executable, "-m", "orthospec.cli.main"]


def _check(out: Path, fmt: str = "json,parquet") -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            *ORTHOSPEC,
            "check",
            str(FAIL),
            "-p",
            "jrc-v3",
            "--out",
            str(out),
            "--format",
            fmt,
            "--date",
            "2026-11-21",
            "--checker",
            str(CHECKER),
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("parquet") / "o"
    res = _check(out)
    assert res.returncode == 1, res.stderr  # aerial-fail is rejected
    return out


def test_the_table_round_trips_every_record(written: Path) -> None:
    doc = json.loads((written / "qcr.json").read_text(encoding="utf-8"))
    records = list(all_records(doc))
    table = pq.read_table(written / "qcr.parquet")
    assert table.schema.names == [name for name, _ in PARQUET_COLUMNS]
    assert table.schema.field("measured_value").type == pa.float64()
    assert table.schema.field("manual").type == pa.bool_()
    frame = table.to_pandas()
    assert len(frame) == len(records) == doc["summary"]["records"]
    for rec, row in zip(records, frame.itertuples(index=False), strict=True):
        assert (row.rule, row.item, row.verdict, row.scope) == (
            rec["rule"],
            rec["item"],
            rec["verdict"],
            rec["scope"],
        )
        v = rec["measured"]["value"]
        if isinstance(v, int | float) and not isinstance(v, bool):
            assert row.measured_value == v
        else:
            assert math.isnan(row.measured_value)
            if v is None:
                assert pd.isna(row.measured_text)
            else:
                assert row.measured_text == (
                    ("true" if v else "false") if isinstance(v, bool) else str(v)
                )
        assert json.loads(row.evidence) == json.loads(json.dumps(rec["evidence"], sort_keys=True))
        assert row.message == rec["message"] and row.requirement_text == rec["requirement"]["text"]
    # the counts a reader gets from pandas are the document's summary
    counts = frame["verdict"].value_counts().to_dict()
    assert counts == {
        k: v for k, v in doc["summary"].items() if k not in ("rules", "records") and v
    }


def test_same_inputs_and_date_give_the_same_bytes_in_another_process(
    written: Path, tmp_path: Path
) -> None:
    res = _check(tmp_path / "again", "json,parquet")
    assert res.returncode == 1, res.stderr
    assert (tmp_path / "again" / "qcr.parquet").read_bytes() == (
        written / "qcr.parquet"
    ).read_bytes()
    assert (tmp_path / "again" / "qcr.json").read_bytes() == (written / "qcr.json").read_bytes()
    meta = pq.ParquetFile(written / "qcr.parquet").metadata
    assert (
        b"orthospec.qcr.date" in meta.metadata
        and meta.metadata[b"orthospec.qcr.date"] == b"2026-11-21"
    )


def test_without_pyarrow_the_check_refuses_before_running(tmp_path: Path) -> None:
    code = (
        "import sys; sys.modules['pyarrow'] = None; sys.modules['pyarrow.parquet'] = None; "
        "from orthospec.cli.main import main; main(sys.argv[1:])"
    )
    res = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "check",
            str(FAIL),
            "-p",
            "jrc-v3",
            "--out",
            str(tmp_path / "o"),
            "--format",
            "json,parquet",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert res.returncode == 2
    assert "install orthospec[parquet]" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "o").exists()


def test_row_groups_hold_a_bounded_batch_and_read_back_whole(
    written: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import io

    from orthospec import qcr

    doc = json.loads((written / "qcr.json").read_text(encoding="utf-8"))
    monkeypatch.setattr(qcr.parquet, "PARQUET_ROWS", 100)
    data = qcr.to_parquet(doc)
    meta = pq.ParquetFile(io.BytesIO(data)).metadata
    assert meta.num_row_groups == -(-doc["summary"]["records"] // 100)
    table = pq.read_table(io.BytesIO(data))
    assert table.column("item").to_pylist() == [r["item"] for r in all_records(doc)]
