"""One CSV table parser (issue 15 item 1): delivery tables and `measure accuracy` point files are
read by delivery.reader.parse_csv, with one set of boolean words and the same refusals (file, row
and column named); its vectorised fast path gives what the exact path and the csv module give."""

import csv
import io
import random

import numpy as np
import pandas as pd
import pytest
from tests.conftest import MANIFEST

from orthospec.delivery import reader, table, table_shape
from orthospec.delivery.convention import table_specs
from orthospec.delivery.points import read_points_csv
from orthospec.delivery.reader import open_delivery, parse_csv
from orthospec.errors import DeliveryError

CP_HEADER = "point_id,block,x,y,x_ref,y_ref,excluded,exclusion_reason\n"


def _delivery_flag(make_delivery, word: str) -> object:
    """The `excluded` value a delivery's checkpoints table gives for ``word`` (row 2)."""
    manifest = MANIFEST.replace("tables: {images: tables/images.csv,",
                                "tables: {checkpoints: tables/cp.csv, images: tables/images.csv,")
    text = CP_HEADER + "P1,B1,1,2,1,2,,\n" + f"P2,B1,1,2,1,2,{word},cone moved\n"
    d = open_delivery(make_delivery(f"d{abs(hash(word))}", manifest=manifest,
                                    extra={"tables/cp.csv": text}))
    return d.table("checkpoints").df["excluded"].tolist()[1]


def _points_flag(tmp_path, word: str) -> bool:
    """Whether a `measure accuracy` point file excludes row 2 for ``word``."""
    path = tmp_path / f"p{abs(hash(word))}.csv"
    path.write_text("id,dx,dy,excluded,exclusion_reason\nA,1,2,,\n" f"B,1,2,{word},cone moved\n",
                    encoding="utf-8")
    return "B" in read_points_csv(path).exclusions


@pytest.mark.parametrize(
    "word, value",
    [
        ("true", True),
        ("TRUE", True),
        ("Yes", True),
        ("y", True),
        ("1", True),
        ("t", True),
        (" T ", True),
        ("false", False),
        ("No", False),
        ("n", False),
        ("0", False),
        ("f", False),
        ("", None),
    ],
)
def test_both_former_paths_accept_the_same_boolean_words(make_delivery, tmp_path, word, value):
    assert _delivery_flag(make_delivery, word) is value
    assert _points_flag(tmp_path, word) is (value is True)


@pytest.mark.parametrize("word", ["x", "maybe", "ja", "2", "-"])
def test_both_former_paths_refuse_the_same_words_naming_file_row_column(
    make_delivery, tmp_path, word
):
    with pytest.raises(DeliveryError) as delivery_err:
        _delivery_flag(make_delivery, word)
    assert f"tables/cp.csv: row 2: column 'excluded': expected true/false, got {word!r}" in str(
        delivery_err.value
    )
    with pytest.raises(DeliveryError) as points_err:
        _points_flag(tmp_path, word)
    assert f".csv: row 2: column 'excluded': expected true/false, got {word!r}" in str(
        points_err.value
    )


@pytest.mark.parametrize(
    "text, message",
    [
        ("id,dx,dy\nA,1,2\nB,1\n", "row 2: has 2 fields, the header has 3"),
        ("id,dx,dy\nA,1,2\nB,1,2,3\n", "row 2: has 4 fields, the header has 3"),
        ("id,dx,dy\nA,1,2\nB,1_000,2\n", "row 2: column 'dx': expected a number, got '1_000'"),
        ("id,dx,dy\nA,1,2\n,1,2\n", "row 2: column 'id': required value is empty"),
    ],
)
def test_point_files_are_refused_like_delivery_tables(tmp_path, text, message):
    """A ragged row is no longer padded or cut silently: the delivery table rule, with its row."""
    path = tmp_path / "p.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DeliveryError, match=message):
        read_points_csv(path)


def test_point_file_rows_are_file_rows_after_blank_lines(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("id,dx,dy\nA,1,2\n\nB,3,4\nB,5,6\n", encoding="utf-8")
    with pytest.raises(
        DeliveryError, match=r"row 4: column 'id': duplicate point id 'B' \(first on row 3\)"
    ):
        read_points_csv(path)


def _csv_widths(text: str) -> list[int]:
    return [max(len(r), 1) for r in csv.reader(io.StringIO(text))]  # an empty line: one empty field


def test_record_widths_are_the_csv_modules_on_random_tables():
    """Quotes, doubled quotes, quoted delimiters and line ends, chunk edges anywhere: where the fast
    pass answers it gives the csv module's field counts; where it declines, the csv module decides."""
    rng = random.Random(7)
    alphabet = ["a", ",", '"', "\n", " ", "é", '""', "\t"]
    answered = 0
    for _ in range(20_000):
        text = "".join(rng.choice(alphabet) for _ in range(rng.randint(0, 14)))
        fast = table_shape._records_fast(text.encode(), chunk=rng.choice([1, 2, 3, 7, 64]))
        if fast is None:
            assert table_shape._records(text.encode()).widths.tolist() == [
                len(r) for r in csv.reader(io.StringIO(text))
            ]
            continue
        answered += 1
        assert fast.widths.tolist() == _csv_widths(text), text
        if not fast.padded:  # nothing to strip: every cell is its own strip()
            assert all(c == c.strip() for r in csv.reader(io.StringIO(text)) for c in r), text
    assert answered > 5_000


TRICKY = (
    CP_HEADER
    + "P1,B1,1.5,2,1,2,,\n"
    + '"P2",B1, 3 ,4e0,3,4,yes,"moved, then ""re-set""\nby the crew"\n'
    + "\n"
    + "P3,B2,-0.0,0,0,1,N,\n"
    + "P4, B2 ,1e-3,.5,+2,5.,,\n"
)


def test_fast_path_equals_the_exact_path_and_the_csv_module():
    spec = table_specs()["checkpoints"]
    fast = parse_csv(TRICKY, spec, file="cp.csv")
    exact_reader = table._read_typed
    try:
        table._read_typed = lambda *a: None  # every cell as text, converted column by column
        exact = parse_csv(TRICKY, spec, file="cp.csv")
    finally:
        table._read_typed = exact_reader
    pd.testing.assert_frame_equal(fast, exact)
    rows = list(csv.DictReader(io.StringIO(TRICKY)))
    rows = [r for r in rows if any(v.strip() for v in r.values())]
    assert fast["_row"].tolist() == [1, 2, 4, 5]  # the blank line is data row 3
    assert fast["point_id"].tolist() == [r["point_id"].strip() for r in rows]
    assert fast["block"].tolist() == ["B1", "B1", "B2", "B2"]
    np.testing.assert_array_equal(fast["x"].to_numpy(), [float(r["x"]) for r in rows])
    np.testing.assert_array_equal(fast["y_ref"].to_numpy(), [float(r["y_ref"]) for r in rows])
    assert fast["excluded"].tolist() == [None, True, False, None]
    assert fast["exclusion_reason"].tolist()[1] == 'moved, then "re-set"\nby the crew'


def test_a_column_of_boolean_words_is_not_read_as_numbers():
    """pandas' C parser reads a float column holding only TRUE/FALSE as 1/0; the parser must not."""
    text = "point_id,block,x,y,x_ref,y_ref\nP1,B1,TRUE,2,1,2\nP2,B1,FALSE,2,1,2\n"
    with pytest.raises(DeliveryError, match="row 1: column 'x': expected a number, got 'TRUE'"):
        parse_csv(text, table_specs()["checkpoints"], file="cp.csv")


def test_bad_utf8_names_the_byte_after_a_bom():
    data = b"\xef\xbb\xbfa,b\xff\n"
    with pytest.raises(UnicodeDecodeError) as plain:
        data.decode("utf-8-sig")
    with pytest.raises(
        DeliveryError, match=rf"cp.csv: not UTF-8 text \(byte {plain.value.start}\)"
    ):
        reader.utf8_body(data, file="cp.csv")
    bad_in_second_chunk = b"abc" + "é".encode()[:1] + b"z"
    with pytest.raises(DeliveryError, match=r"byte 3\)"):
        reader.utf8_body(bad_in_second_chunk, file="cp.csv", chunk=4)
    assert reader.utf8_body(b"a\r\nb\rc\n", file="x") == b"a\nb\nc\n"


@pytest.mark.parametrize("chunk", [7, 64, 1 << 20])
def test_csv_bounds_skip_short_lines_but_still_find_the_long_one(chunk):
    """Chunks whose lines are all shorter than the limits are passed over without counting
    delimiters; the carried state still places a too-wide line or too-long cell at its row."""
    short = b"".join(b"P%d,B1,1,2,1,2\n" % i for i in range(500))
    limits = reader.Limits(table_bytes=2**30, columns=8, cell_bytes=40)
    reader.check_csv_bounds(
        io.BytesIO(b"point_id,block,x,y,x_ref,y_ref\n" + short),
        file="cp.csv",
        limits=limits,
        chunk=chunk,
    )
    wide = b"point_id,block,x,y,x_ref,y_ref\n" + short + b"P,B," + b"1," * 9 + b"1\n" + short
    with pytest.raises(
        DeliveryError, match=r"cp.csv: row 501: \d+\+ fields on one line exceed the limit of 8"
    ):
        reader.check_csv_bounds(io.BytesIO(wide), file="cp.csv", limits=limits, chunk=chunk)
    long_cell = (
        b"point_id,block,x,y,x_ref,y_ref\n" + short + b"P," + b"x" * 50 + b",1,2,1,2\n" + short
    )
    with pytest.raises(DeliveryError, match=r"cp.csv: row 501: a cell longer than 40 bytes"):
        reader.check_csv_bounds(io.BytesIO(long_cell), file="cp.csv", limits=limits, chunk=chunk)
