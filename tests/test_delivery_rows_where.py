"""delivery.table.rows_where: the bounded re-reading of a delivered table's rows by a qcr.json
evidence selector (``where``), on the same bounds as the table parser.

Expected rows come from Python's csv module over the text (an independent reader), numbered as
the parser numbers data rows (blank lines counted, never selected)."""

from __future__ import annotations

import csv
import hashlib
import io
from pathlib import Path

import pytest

from orthospec.delivery.convention import table_specs
from orthospec.delivery.table import parse_csv, rows_where
from orthospec.delivery.table_bounds import Limits
from orthospec.errors import DeliveryError

TEXT = ("point_id,block,x,y,x_ref,y_ref\n"
        "P1,B01,1,2,1,2\n"
        "P2, B02 ,1,2,1,2\n"
        "\n"
        "P3,B01,1,2,1,2\n"
        "\"P,4\",B02,1,2,1,2\n"
        " , ,,,,\n"
        "P5,\"B01\",1,2,1,2\n")


def _by_csv(text: str, where: dict[str, str]) -> list[int]:
    rows = list(csv.reader(io.StringIO(text)))
    header = [h.strip() for h in rows[0]]
    out = []
    for n, r in enumerate(rows[1:], start=1):
        cells = dict(zip(header, (c.strip() for c in r), strict=False))
        if any(cells.values()) and all(cells.get(k, "") == v for k, v in where.items()):
            out.append(n)
    return out


@pytest.fixture()
def table(tmp_path: Path) -> Path:
    p = tmp_path / "cp.csv"
    p.write_bytes(TEXT.encode())
    return p


@pytest.mark.parametrize("where", [{}, {"block": "B01"}, {"block": "B02"}, {"block": "B03"},
                                   {"block": "B01", "point_id": "P3"}])
def test_rows_where_selects_as_an_independent_csv_reader(
    table: Path, where: dict[str, str]
) -> None:
    assert rows_where(table, where, file="cp.csv") == _by_csv(TEXT, where)


def test_rows_where_numbers_rows_as_the_parser(table: Path) -> None:
    spec = table_specs()["checkpoints"]
    df = parse_csv(TEXT.replace(" , ,,,,\n", ""), spec, file="cp.csv")
    # the parser keeps the blank line's number; the selector gives the same numbers
    assert rows_where(table, {}, file="cp.csv") == [1, 2, 4, 5, 7]
    assert df["_row"].tolist() == [1, 2, 4, 5, 6]
    assert [int(r) for r, b in zip(df["_row"], df["block"], strict=True) if b == "B01"] == [1, 4, 6]


def test_rows_where_checks_the_checksum_of_the_bytes_it_reads(table: Path) -> None:
    sha = hashlib.sha256(TEXT.encode()).hexdigest()
    assert rows_where(table, {"block": "B02"}, file="cp.csv", sha256=sha) == [2, 5]
    with pytest.raises(
        DeliveryError, match=r"cp.csv: the file has changed since the check \(SHA-256 differs\)"
    ):
        rows_where(table, {"block": "B02"}, file="cp.csv", sha256="0" * 64)


def test_rows_where_is_bounded(table: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(DeliveryError, match="exceeds the limit of 10 bytes"):
        rows_where(table, {}, file="cp.csv", limits=Limits(table_bytes=10))
    monkeypatch.setenv("ORTHOSPEC_MAX_CSV_CELL_BYTES", "3")
    with pytest.raises(DeliveryError, match=r"cp.csv:1: a cell longer than 3 bytes"):
        rows_where(table, {}, file="cp.csv")


def test_rows_where_refuses_what_it_cannot_select_by(tmp_path: Path) -> None:
    p = tmp_path / "t.csv"
    p.write_bytes(b"a,b\n1,2\n")
    with pytest.raises(DeliveryError, match="t.csv:1: no column 'block' to select rows by"):
        rows_where(p, {"block": "B01"}, file="t.csv")
    p.write_bytes(b"a,b\n\xff,2\n")
    with pytest.raises(DeliveryError, match="not UTF-8"):
        rows_where(p, {}, file="t.csv")
    p.write_bytes(b"a,b\n1,2,3\n")
    with pytest.raises(DeliveryError, match="row 1: has 3 fields"):
        rows_where(p, {}, file="t.csv")
    with pytest.raises(DeliveryError, match="cannot read table"):
        rows_where(tmp_path / "absent.csv", {}, file="absent.csv")
    p.write_bytes(b"a,b\n1,2\n3\n")
    with pytest.raises(DeliveryError, match="row 2: has 1 fields, the header has 2"):
        rows_where(p, {}, file="t.csv")
    p.write_bytes(b"a,a\n1,2\n")
    with pytest.raises(DeliveryError, match="not a valid CSV table"):
        rows_where(p, {}, file="t.csv")
