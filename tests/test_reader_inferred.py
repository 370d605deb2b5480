"""The table parser's inferred fast path (issue 14): pandas' C parser infers the text columns, the
reader checks every column against the spec and counts record widths from the parsed cells. It
must give exactly what the exact path (every cell as text, converted column by column) gives:
the same frame, or the same DeliveryError naming file, row and column. Expected values come from
the cell texts written here, Python's float() and str.strip(), the csv module and hashlib."""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import warnings
from collections.abc import Iterator

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from orthospec.delivery import reader, table_bounds, table_shape
from orthospec.delivery import table as table_parser
from orthospec.delivery.convention import ColumnSpec, TableSpec, table_specs
from orthospec.delivery.reader import Limits, check_csv_bounds, parse_csv
from orthospec.errors import DeliveryError

SPEC = TableSpec("t", "checkpoint", "id", "test table", {
    "id": ColumnSpec("id", "text", None, True, ""),
    "word": ColumnSpec("word", "text", None, False, ""),
    "n": ColumnSpec("n", "number", None, False, ""),
    "flag": ColumnSpec("flag", "bool", None, False, ""),
    "day": ColumnSpec("day", "date", None, False, ""),
})
HEADER = list(SPEC.columns)
CP = table_specs()["checkpoints"]


@contextlib.contextmanager
def exact_path() -> Iterator[None]:
    """parse_csv with every cell read as text and converted column by column."""
    saved = table_parser._read_typed
    table_parser._read_typed = lambda *a: None
    try:
        yield
    finally:
        table_parser._read_typed = saved


@contextlib.contextmanager
def object_inference() -> Iterator[None]:
    """pandas 2's inference (text columns as object), available in pandas 3 behind an option."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            ctx = pd.option_context("future.infer_string", False)
        except (KeyError, pd.errors.OptionError):  # a pandas without the option: its default
            ctx = contextlib.nullcontext()
        with ctx:
            yield


def outcome(body: bytes, spec: TableSpec = SPEC) -> tuple[str, object]:
    try:
        return "ok", parse_csv(body, spec, file="t.csv")
    except DeliveryError as exc:
        return "error", str(exc)


def assert_same(fast: tuple[str, object], exact: tuple[str, object], body: bytes, *,
                check_column_type: bool = True) -> None:
    assert fast[0] == exact[0], (body, fast, exact)
    if fast[0] == "error":
        assert fast[1] == exact[1], body
        return
    pd.testing.assert_frame_equal(
        fast[1], exact[1], check_exact=True, check_column_type=check_column_type
    )
    for col, values in fast[1].items():  # the exact path's Python types, not only equal values
        if col != "_row" and values.dtype == object:
            assert all(v is None or type(v) in (str, bool) for v in values), (col, body)


# --- random tables: fast path == exact path ---------------------------------------------------

TRICKY = [
    "001",
    "1e5",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "true",
    "false",
    "TRUE",
    "False",
    "t",
    "yes",
    "0",
    "1",
    "-0",
    "2.5",
    "+3",
    ".5",
    "1_000",
    "0x10",
    "2026-01-31",
    "2026-1-1",
    "abc",
    "B01",
    " 7 ",
    " true",
    "\xa0x",
    "x\u3000",
    "\x1cy",
    "é",
    "a,b",
    'say "hi"',
    "two\nlines",
    "  ",
    "",
]
cell = st.one_of(
    st.sampled_from(TRICKY),
    st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
    st.integers(-(10**20), 10**20).map(str),
    st.text(alphabet='ab ,"\n\t\xa01é', max_size=6),
)


def encode(rows: list[list[str]], quote_all: bool) -> bytes:
    """A CSV table: cells quoted (quotes doubled) when they need it, or all of them."""

    def one(c: str) -> str:
        needs = quote_all or any(ch in c for ch in ',"\n') or c != c.strip(" ")
        return '"' + c.replace('"', '""') + '"' if needs else c

    return ("\n".join(",".join(map(one, r)) for r in [HEADER, *rows]) + "\n").encode()


table = st.lists(st.lists(cell, min_size=3, max_size=6), min_size=1, max_size=8)


def fix_width(rows: list[list[str]], ragged: bool) -> list[list[str]]:
    return rows if ragged else [(r + [""] * 5)[:5] for r in rows]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    rows=table,
    ragged=st.booleans(),
    quote_all=st.booleans(),
    ids=st.sampled_from(["row", "random"]),
    blank=st.booleans(),
)
def test_fast_path_equals_exact_path_on_random_tables(rows, ragged, quote_all, ids, blank):
    rows = fix_width(rows, ragged)
    if ids == "row":  # mostly valid tables, so the comparison reaches the typed frame
        rows = [[f"P{i}", *r[1:]] for i, r in enumerate(rows)]
    body = encode(rows, quote_all)
    if blank:
        body = body.replace(b"\n", b"\n\n", 1)  # a blank line after the header
    fast = outcome(body)
    with exact_path():
        exact = outcome(body)
    assert_same(fast, exact, body)
    with object_inference():  # the column labels' Index is object there too
        assert_same(outcome(body), exact, body, check_column_type=False)


@settings(max_examples=200, deadline=None)
@given(
    words=st.lists(st.sampled_from(TRICKY[:24]), min_size=1, max_size=6),
    numbers=st.lists(
        st.floats(allow_nan=False, allow_infinity=False).map(repr), min_size=1, max_size=6
    ),
)
def test_valid_tables_give_the_csv_modules_cells_and_pythons_floats(words, numbers):
    """Words that look like numbers, booleans or NaN stay their text; numbers are float()."""
    n = min(len(words), len(numbers))
    rows = [[f"P{i}", words[i], numbers[i], "", ""] for i in range(n)]
    body = encode(rows, quote_all=False)
    df = parse_csv(body, SPEC, file="t.csv")
    want = list(csv.reader(io.StringIO(body.decode())))[1:]
    assert df["word"].tolist() == [r[1].strip() or None for r in want]
    np.testing.assert_array_equal(df["n"].to_numpy(), [float(r[2]) for r in want])
    assert df["flag"].tolist() == [None] * n and df["day"].tolist() == [None] * n
    assert df["_row"].tolist() == list(range(1, n + 1))


# --- each branch of the inferred path -----------------------------------------------------------


def test_an_all_empty_text_column_is_none_not_float():
    body = b"id,word,n,flag,day\nP1,,1.5,,\nP2,,2.5,,\n"
    df = parse_csv(body, SPEC, file="t.csv")
    for col in ("word", "flag", "day"):
        assert df[col].dtype == object and df[col].tolist() == [None, None]


@pytest.mark.parametrize(
    "words, want",
    [
        (["true", "FALSE", "True"], [True, False, True]),  # the parser's bool dtype
        (["false", "", "TRUE"], [False, None, True]),  # object of True/False/NaN
        (["yes", "n", "1"], [True, False, True]),  # our words the parser leaves as text
    ],
)
def test_a_bool_column_the_parser_reads_as_booleans(words, want):
    body = ("id,flag\n" + "".join(f"P{i},{w}\n" for i, w in enumerate(words))).encode()
    df = parse_csv(body, SPEC, file="t.csv")
    assert df["flag"].tolist() == want and df["flag"].dtype == object
    with exact_path():
        pd.testing.assert_frame_equal(df, parse_csv(body, SPEC, file="t.csv"))


def test_a_text_column_inferred_differently_in_two_chunks_keeps_its_text():
    """The C parser infers each chunk of rows on its own: "001" as 1 in the first, words later
    (object of mixed types, with a DtypeWarning pandas would print): the column is re-read as text."""
    n = 300_000
    lines = [
        f"P{i},{'001' if i < n // 2 else 'x'},,{'true' if i < n // 2 else 'yes'},\n"
        for i in range(n)
    ]
    body = ("id,word,n,flag,day\n" + "".join(lines)).encode()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no DtypeWarning reaches the user
        df = parse_csv(body, SPEC, file="t.csv")
    assert df["word"].iloc[0] == "001" and df["word"].iloc[-1] == "x"
    assert set(df["word"]) == {"001", "x"}
    assert df["flag"].tolist() == [True] * n  # booleans in one chunk, words in the other: re-read


@pytest.mark.parametrize(
    "body, message",
    [
        (b"id,word,n\nP1,a,1\nP2,b\n", "t.csv: row 2: has 2 fields, the header has 3"),
        # a first record one field long becomes pandas' index; a later short one would balance the commas
        (b"id,word,n\nP1,a,1,9\nP2,b\n", "t.csv: row 1: has 4 fields, the header has 3"),
        # a NUL is a control character: refused before any parsing, by line (issue 28)
        (b"id,word,n\nP1,a,1.5\nP2,b\x00\n", "t.csv:3: a control character (U+0000)"),
    ],
)
def test_record_widths_when_the_cells_cannot_tell(body, message):
    with pytest.raises(DeliveryError) as fast:
        parse_csv(body, SPEC, file="t.csv")
    assert message in str(fast.value)
    with exact_path(), pytest.raises(DeliveryError) as exact:
        parse_csv(body, SPEC, file="t.csv")
    assert str(exact.value) == str(fast.value)


def test_blank_lines_keep_their_row_numbers():
    body = b"id,word,n\nP1,a,1\n\n,,\nP2,b,2\n"
    df = parse_csv(body, SPEC, file="t.csv")
    assert df["_row"].tolist() == [1, 4] and df["id"].tolist() == ["P1", "P2"]


# (a control character such as \x1c at a cell's edge is refused where the table is read: test_control_characters.py)
@pytest.mark.parametrize("word", ["\xa0padded\xa0", "padded\u3000", " padded ", "\tpadded"])
def test_cells_are_stripped_as_python_strips_them(word):
    body = f'id,word\nP1,"{word}"\nP2,plain\n'.encode()
    assert parse_csv(body, SPEC, file="t.csv")["word"].tolist() == [word.strip(), "plain"]


def test_non_ascii_letters_at_a_cell_edge_are_kept():
    body = "id,word\nP1,é\nP2,ü-ß\n".encode()
    assert parse_csv(body, SPEC, file="t.csv")["word"].tolist() == ["é", "ü-ß"]


@pytest.mark.parametrize(
    "ids, message",
    [
        (["P1", "P2", "P1"], "duplicate id 'P1' in rows 1, 3"),  # out of order: hashed
        (["P1", "P2", "P2"], "duplicate id 'P2' in rows 2, 3"),  # in order but not increasing
        (["B", "A", "C"], None),  # distinct, out of order
    ],
)
def test_duplicate_ids_whatever_their_order(ids, message):
    body = ("id,word\n" + "".join(f"{i},w\n" for i in ids)).encode()
    if message is None:
        assert parse_csv(body, SPEC, file="t.csv")["id"].tolist() == ids
        return
    with pytest.raises(DeliveryError, match=f"t.csv: column 'id': {message}"):
        parse_csv(body, SPEC, file="t.csv")


def test_a_large_checkpoint_table_reads_like_the_csv_module(tmp_path):
    """Sorted ids, repeated texts, quoted commas, a boolean and an empty column, as a national
    check-point table has them, against the csv module and float()."""
    n = 20_000
    lines = [
        f"P{i:06d},B0{i % 3 + 1},{500000 + i / 7:.3f},{5400000 + i / 3:.3f},1,2,F_{i % 50},"
        f'"GNSS, survey",{"false" if i % 9 else "TRUE"},,0.03\n'
        for i in range(n)
    ]
    text = (
        "point_id,block,x,y,x_ref,y_ref,image_id,source,excluded,exclusion_reason,precision_xy\n"
        + "".join(lines)
    )
    df = parse_csv(text.encode(), CP, file="cp.csv")
    rows = list(csv.DictReader(io.StringIO(text)))
    assert df["point_id"].tolist() == [r["point_id"] for r in rows]
    assert df["source"].tolist() == ["GNSS, survey"] * n
    np.testing.assert_array_equal(df["x"].to_numpy(), [float(r["x"]) for r in rows])
    assert df["excluded"].tolist() == [r["excluded"] == "TRUE" for r in rows]
    assert df["exclusion_reason"].tolist() == [None] * n
    assert (
        df["block"].dtype == object and df["block"].iloc[0] is df["block"].iloc[3]
    )  # one shared text
    with object_inference():  # pandas 2: object columns, record widths from the bytes
        pd.testing.assert_frame_equal(
            parse_csv(text.encode(), CP, file="cp.csv"), df, check_column_type=False
        )


# --- reading the bytes --------------------------------------------------------------------------


@pytest.mark.parametrize("chunk", [4096, 1 << 20])
def test_csv_bounds_on_long_limits_find_the_long_line(chunk):
    """With limits long enough for the block test (no byte-by-byte count), a line longer than the
    columns limit allows is still found at its row; one just within passes."""
    limits = Limits(table_bytes=2**30, columns=600, cell_bytes=10_000)
    short = b"".join(b"P%d,B1,1,2,1,2\n" % i for i in range(2000))
    check_csv_bounds(
        io.BytesIO(b"a,b\n" + short + b"x" * 599 + b"\n" + short),
        file="t.csv",
        limits=limits,
        chunk=chunk,
    )
    wide = b"a,b\n" + short + b"," * 700 + b"\n" + short
    with pytest.raises(
        DeliveryError, match=r"t.csv: row 2001: 701\+ fields on one line exceed the limit of 600"
    ):
        check_csv_bounds(io.BytesIO(wide), file="t.csv", limits=limits, chunk=chunk)


def test_short_lines_block_test():
    data = b"ab\n" * 1000
    assert table_bounds._short_lines(data, 0, 600)
    assert not table_bounds._short_lines(data, 599, 600)  # the carried line grows too long
    assert not table_bounds._short_lines(data[:1500] + b"y" * 700 + b"\n" + data, 0, 600)
    assert not table_bounds._short_lines(data, 0, 100)  # blocks too short to pay: count


@pytest.mark.parametrize("rows", [10, 300_000])  # hashed inline, and in a thread beside the parse
def test_table_checksum_is_the_files_sha256(make_delivery, rows):
    from tests.conftest import MANIFEST

    manifest = MANIFEST.replace(
        "tables: {images: tables/images.csv,",
        "tables: {checkpoints: tables/cp.csv, images: tables/images.csv,",
    )
    text = "point_id,block,x,y,x_ref,y_ref\n" + "".join(
        f"P{i},B1,1.5,2.5,1.5,2.5\n" for i in range(rows)
    )
    d = reader.open_delivery(
        make_delivery(f"sha{rows}", manifest=manifest, extra={"tables/cp.csv": text})
    )
    t = d.table("checkpoints")
    assert t.sha256 == hashlib.sha256(text.encode()).hexdigest() == d.sha256("tables/cp.csv")
    assert len(t.df) == rows


@pytest.mark.parametrize("kind", ["string", "large_string"])
def test_cell_bytes_count_the_commas_and_see_the_edges(kind):
    pa = pytest.importorskip("pyarrow")
    cells = ["a,b", None, "", " x", "plain", ",,", "y\u3000", "z"]
    arr = pa.array(cells, type=getattr(pa, kind)())
    for part in (arr, arr.slice(2), arr.slice(1, 3), arr.slice(4, 2), arr.slice(7)):
        texts = [c for c in part.to_pylist() if c]
        assert table_shape._cell_bytes(part) == (
            sum(c.count(",") for c in texts),
            any(c != c.strip() for c in texts),
        ), part.to_pylist()
    if hasattr(pa, "string_view"):
        assert table_shape._cell_bytes(pa.array(cells, type=pa.string_view())) is None
