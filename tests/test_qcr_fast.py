"""The vectorised shortcuts of qcr.py (issue 14: a million check points) against their pure-Python
references: the natural sort of ids of one shape (``_uniform_order``) against ``sorted(key=
natural_key)``; the whole-column character checks against the regular expressions they replace;
row numbers from a ``range``; a column of one value; and qcr.csv with row columns written as
head + row + tail against the record-by-record writer (``_iter_csv_records``).
"""

from __future__ import annotations

import json
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.test_qcr_writers import _doc

from orthospec import qcr
from orthospec.qcr import (
    _CSV_SPECIAL,
    _FORMULA_AT,
    _XML_SPECIAL,
    _any_csv_special,
    _encode_columns,
    _formula_at,
    _int_array,
    _iter_csv_records,
    _iter_junit_records,
    _json_texts,
    _numeric_column,
    _uniform_order,
    _xml_special,
    iter_csv,
    iter_junit,
    natural_key,
    natural_order,
    stable,
)


def _reference(ids: list[str]) -> list[int]:
    """The natural order as defined: a stable sort on natural_key (pure Python)."""
    return sorted(range(len(ids)), key=lambda i: natural_key(ids[i]))


#: characters of an id's text part: letters, punctuation, space, a line feed (never a digit)
_TEXT = "aAbPZ_-. /#:\n"


@st.composite
def _one_shape(draw: st.DrawFn) -> tuple[list[str], str]:
    """At least 256 ids of one length whose digits stand at the same places (the shape
    ``_uniform_order`` sorts by bytes), in random order, with repeats; the digit mask as text."""
    width = draw(st.integers(1, 12))
    mask = draw(st.lists(st.booleans(), min_size=width, max_size=width))
    text = draw(st.sampled_from([_TEXT, "P", "ab", " _"]))
    seed = draw(st.integers(0, 2**32 - 1))
    n = draw(st.integers(256, 700))
    rng = random.Random(seed)
    # few distinct digits or text characters: ties and equal runs are common
    digits = draw(st.sampled_from(["0123456789", "01", "0"]))
    ids = ["".join(rng.choice(digits) if m else rng.choice(text) for m in mask) for _ in range(n)]
    if draw(st.booleans()):
        ids.sort(key=natural_key)  # already in order: the no-sort shortcut
    return ids, "".join("9" if m else "a" for m in mask)


@settings(max_examples=80, deadline=None)
@given(_one_shape())
def test_uniform_ids_sort_as_natural_key(case: tuple[list[str], str]) -> None:
    ids, _mask = case
    got = _uniform_order(ids)
    if "\n" in "".join(ids):
        assert got is None  # a line feed inside an id: the general path
    else:
        assert got is not None
        assert got.tolist() == _reference(ids)
    assert natural_order(ids).tolist() == _reference(ids)
    assert natural_order(np.array(ids, dtype=object)).tolist() == _reference(ids)


_odd = st.text(alphabet=st.sampled_from(list("0123456789aP_-. ٣é\x00\n")), max_size=10)


@settings(max_examples=80, deadline=None)
@given(_one_shape(), st.lists(_odd, min_size=1, max_size=8), st.integers(0, 2**32 - 1))
def test_mixed_ids_sort_as_natural_key(
    case: tuple[list[str], str], odd: list[str], seed: int
) -> None:
    """Ids of one shape mixed with any others (other lengths, digit places, non-ASCII digits, NUL,
    line feeds): the shortcut steps aside when the ids are not all of one shape, and the order
    stays the reference's."""
    ids, _mask = case
    ids = ids + odd
    random.Random(seed).shuffle(ids)
    assert natural_order(ids).tolist() == _reference(ids)


def test_uniform_order_known_cases() -> None:
    ids = [f"P{i:07d}" for i in range(1000)][::-1]
    assert _uniform_order(ids).tolist() == list(range(1000))[::-1]
    assert _uniform_order(sorted(ids)).tolist() == list(range(1000))  # in order: no sort
    # one length and mask: F01_0101 ... but the byte order is the natural order only because
    # the digit runs have the same widths; one id of another shape and the shortcut steps aside
    grid = [f"F{b:02d}_{r:02d}{c:02d}" for b in (10, 2, 1) for r in (12, 3) for c in (7, 11)] * 30
    assert _uniform_order(grid).tolist() == _reference(grid)
    assert [grid[i] for i in _uniform_order(grid)[:3].tolist()] == ["F01_0307"] * 3
    assert _uniform_order([*grid, "F1_0307"]) is None
    assert _uniform_order([*grid[:-1], "F01_a307"]) is None  # same length, other digit places
    assert _uniform_order(["é1"] * 300) is None and _uniform_order(["a\x001"] * 300) is None
    assert _uniform_order([1] * 300) is None and _uniform_order(["a1"] * 299 + [None]) is None
    assert _uniform_order(["", ""] * 200) is None


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.text(
            alphabet=st.sampled_from(list("ab1=+-@\t\r\n,\"'&<>\x00\x01\x7f\x85\x9fé≤\ufffe")),
            max_size=6,
        ),
        max_size=12,
    )
)
def test_column_checks_equal_the_regular_expressions(cells: list[str]) -> None:
    joined = "\x00".join(cells)
    with pytest.MonkeyPatch.context() as mp:
        for large in (0, qcr._LARGE):  # the byte checks (any length) and the regex (short texts)
            mp.setattr(qcr.cells, "_LARGE", large)
            assert _any_csv_special(joined) == bool(_CSV_SPECIAL.search(joined))
            assert _formula_at(joined) == bool(_FORMULA_AT.search(joined))
            assert _xml_special("".join(cells)) == bool(_XML_SPECIAL.search("".join(cells)))


def test_row_numbers_from_a_range_or_a_tuple() -> None:
    assert _int_array(range(1, 6)).tolist() == [1, 2, 3, 4, 5]
    assert _int_array(range(10, 0, -3)).tolist() == [10, 7, 4, 1]
    assert _int_array((4, 2, 9)).tolist() == [4, 2, 9] and _int_array(()).tolist() == []
    assert _int_array(range(3)).dtype == np.int64


@pytest.mark.parametrize("v", [0.123456789012345, -0.0, 0.0, 2.5e20, 1e-300, 7.0, np.inf, -np.inf])
def test_a_numeric_column_of_one_value(v: float) -> None:
    """Rounded once when every item has the same value: what stable() gives for that value
    (10 significant digits; a non-finite value is null)."""
    assert _numeric_column(np.full(1000, v)) == {"all": stable(v)}
    mixed = np.array([v, 0.5] * 3)
    assert _numeric_column(mixed) == [stable(x) for x in mixed.tolist()]


@pytest.mark.parametrize("seed", range(12))
def test_row_columns_without_gaps_same_bytes(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """A row column whose every item has its row (the check-point case) is written as head + row +
    tail merged into the line: the bytes of the record-by-record writer, slices cut anywhere."""
    doc = _doc(seed)
    rng = random.Random(seed)
    changed = 0
    for block in doc["compact"].values():
        ev = block.get("evidence")
        if isinstance(ev, dict) and "entry" in ev:
            ev["rows"] = [rng.randrange(1, 10**6) for _ in ev["rows"]]
            changed += 1
        elif isinstance(block["items"], list) and block["items"]:
            block["evidence"] = {
                "entry": rng.choice([0, 1, 6]),
                "rows": [rng.randrange(1, 99) for _ in block["items"]],
            }
            changed += 1
    assert changed
    for chunk in (1 + seed % 5, 50_000):
        monkeypatch.setattr(qcr.blocks, "BLOCK_CHUNK", chunk)
        assert "".join(iter_csv(doc)) == "".join(_iter_csv_records(doc))
        assert "".join(iter_junit(doc)) == "".join(_iter_junit_records(doc))


_json_text = st.text(alphabet=st.sampled_from(list('aP0 "\\\x00\x1f\x7f\n\té≤\u2028/')), max_size=5)


@settings(max_examples=150, deadline=None)
@given(st.lists(_json_text, min_size=1, max_size=300), st.sampled_from([0, 1, 300]), st.booleans())
def test_compact_columns_encode_as_json_does(texts: list[str], repeat: int, mixed: bool) -> None:
    """A compact block written column by column (long text columns joined) is the JSON encoder's
    text of the whole block, whatever the ids hold (quotes, backslashes, control characters)."""
    enc = json.JSONEncoder(ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode
    ids = (texts * (1 + repeat))[: max(len(texts), 256 if repeat else 0)]
    column: list = [*ids, 3] if mixed else ids
    block = {
        "items": column,
        "verdict": {"all": "pass"},
        "evidence": {"entry": 1, "rows": list(range(len(ids)))},
        "message": ids[:3],
    }
    with pytest.MonkeyPatch.context() as mp:
        for large in (0, qcr._LARGE):  # control characters found in the bytes, or by the regex
            mp.setattr(qcr.json, "_LARGE", large)
            assert _encode_columns(enc, block) == enc(block)
            assert _encode_columns(enc, {1: ids}) == enc({1: ids}) and _encode_columns(
                enc, ids
            ) == enc(ids)
            if not mixed and len(ids) >= 256:
                plain = all(not set(t) & set('"\\\x00\x1f\n\t') for t in ids)
                assert (_json_texts(ids) is not None) == plain


def test_heads_and_tails_known_cases() -> None:
    """Ids as a head and trailing digits: heads with digits of their own (``B01_``), a head whose
    key begins another's (``B01_`` and ``B01_2x``: merged in through natural_key), a head ending in
    a non-ASCII digit (``x٣`` + ``5`` is one run), tails of more than 18 digits, NUL, non-text ids."""
    rng = random.Random(7)
    ids = [f"B{b:02d}_{rng.randrange(0, 3000)}" for b in (1, 2, 10) for _ in range(150)]
    assert natural_order(ids).tolist() == _reference(ids)
    for extra in (
        ["B01_2x", "B01_"],
        ["5x", "12", "0012", "0"],
        ["x٣5", "x٣", "x4", "x٣٣", "x٣40"],
        ["P" + "9" * 25, "P" + "0" * 30],
        ["a\x001", "a\x00", "\x00"],
        ["é12", "e12", "E12"],
    ):
        mixed = ids + extra * 3
        rng.shuffle(mixed)
        assert natural_order(mixed).tolist() == _reference(mixed), extra
    numbers = [rng.randrange(0, 10**6) for _ in range(400)] + [None, 2.5]
    as_text = [str(x) for x in numbers]
    assert natural_order(numbers).tolist() == _reference(as_text)
