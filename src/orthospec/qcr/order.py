"""Natural order of item ids (``B2`` before ``B10``), fast for a million ids.
"""

from __future__ import annotations

import bisect
import itertools
import re
import sys
from typing import Any

import numpy as np

_DIGITS = re.compile(r"(\d+)")


def natural_key(text: str) -> tuple[Any, ...]:
    """IMG_2 before IMG_10: digits compare as numbers, the rest as text (total order, stable)."""
    return tuple((0, int(p), p) if p.isdecimal() else (1, 0, p) for p in _DIGITS.split(text))


#: digit runs longer than this (leading zeros included) take the exact path (int64 holds 18 digits)
_FAST_DIGITS = 18


def natural_order(items: Any) -> np.ndarray:
    """Indices that sort ``items`` by :func:`natural_key` (ties in item order), vectorised.

    Ids of one length and one digit layout (``P0000001``, ``F01_0101``) sort as bytes
    (:func:`_uniform_order`). Otherwise each id is a head and its trailing ASCII digits
    (``B01_`` + ``17``): the distinct heads (few) are ordered by ``natural_key``, and the ids by
    numpy keys: the head's rank, digits or not, the number, then its count of digits (among equal
    numbers, its leading zeros: what ``natural_key`` compares after the number, ``'0' < '00'`` but
    ``'001' < '01'``). That is the
    natural order when no head's key begins another's (checked; ``B01_`` and ``B01_2x`` would
    not do). An id outside it (a head that begins another, more than 18 trailing digits) takes
    ``natural_key`` and is merged in by binary search. The same order as ``sorted(...,
    key=natural_key)`` (tests/test_qcr_scale.py, tests/test_qcr_fast.py)."""
    listed = items.tolist() if isinstance(items, np.ndarray) else list(items)
    n = len(listed)
    if n < 256:
        return _slow_order(listed if _all_text(listed) else [str(x) for x in listed], np.arange(n))
    uniform = _uniform_order(listed)
    if uniform is not None:
        return uniform
    try:
        strs = listed
        fast, rank, value, digits, has = _head_tail_keys(strs)  # str methods: TypeError unless text
    except TypeError:
        strs = [x if type(x) is str else str(x) for x in listed]
        fast, rank, value, digits, has = _head_tail_keys(strs)
    fi = np.flatnonzero(fast)
    if not len(fi):
        return _slow_order(strs, np.arange(n))
    rank, value, digits, has = rank[fi], value[fi], digits[fi], has[fi]
    if bool((rank == rank[0]).all() & has.all()) and bool((np.diff(value) > 0).all()):
        order = fi  # one head and increasing numbers: already in order (ids in file order)
    else:
        # equal numbers: more digits are more leading zeros, first for a number > 0 ('01' < '1'),
        # last for 0 ('0' < '00')
        tie = np.where(value == 0, digits, -digits)
        keys = [
            k for k in (tie, value, has, rank) if not bool((k == k[0]).all())
        ]  # a constant key sorts nothing
        order = fi[
            np.lexsort(keys)
            if len(keys) > 1
            else np.argsort(keys[0], kind="stable")
            if keys
            else np.arange(len(fi))
        ]
    if len(fi) == n:
        return order.astype(np.int64)
    slow = _slow_order(strs, np.flatnonzero(~fast))
    fast_keys = _Keys(strs, order)
    at = [bisect.bisect_left(fast_keys, natural_key(strs[i])) for i in slow.tolist()]
    return np.insert(order, at, slow).astype(np.int64)


_ASCII_DIGITS = "0123456789"


def _head_tail_keys(strs: list[str]) -> tuple[np.ndarray, ...]:
    """Per id: whether the head/tail keys order it (``fast``), its head's rank, its trailing number,
    that number's count of digits, and whether it has one. Python work per id is a few calls in C
    (``rstrip``, ``len``, one join); per distinct head one ``natural_key``."""
    n = len(strs)
    heads = list(map(str.rstrip, strs, itertools.repeat(_ASCII_DIGITS, n)))
    lens = np.fromiter(map(len, strs), dtype=np.int64, count=n)
    tail = lens - np.fromiter(map(len, heads), dtype=np.int64, count=n)
    if (
        len(set(heads[:: max(1, n // 64)])) == 1 and heads.count(heads[0]) == n
    ):  # one head (P1, P2, ...)
        codes, distinct = np.zeros(n, dtype=np.int64), [heads[0]]
    else:
        codes, distinct = _factorize(heads)
    del heads
    keys = [natural_key(h) for h in distinct]
    by_key = sorted(range(len(distinct)), key=keys.__getitem__)
    usable = np.array(
        [not h or not h[-1].isdecimal() for h in distinct], dtype=bool
    )  # '٣' + '5' is one run
    for a, b in itertools.pairwise(by_key):
        if (
            keys[b][: len(keys[a])] == keys[a]
        ):  # a's key begins b's (then it begins every key between)
            usable[a] = False
    rank = np.empty(len(distinct), dtype=np.int64)
    rank[by_key] = np.arange(len(distinct))
    fast = usable[codes] & (tail <= _FAST_DIGITS)
    value = np.zeros(n, dtype=np.int64)
    tail = np.where(fast, tail, 0)
    width = int(tail.max()) if n else 0
    if width:
        # the ids' characters as code points, one buffer: id i ends at ends[i]
        chars = np.frombuffer("".join(strs).encode("utf-32-le", "surrogatepass"), dtype=np.uint32)
        last = np.cumsum(lens) - 1
        for p in range(width):  # the digit p places from the end, times 10**p
            on = p < tail
            digit = chars[np.where(on, last - p, 0)].astype(np.int64) - 48
            value += np.where(on, digit, 0) * 10**p
    return fast, rank[codes], value, tail, tail > 0


def _factorize(values: list[str]) -> tuple[np.ndarray, list[str]]:
    """Codes (into the distinct values, in order of first appearance) and the distinct values."""
    if "pandas" in sys.modules:
        import pandas as pd

        codes, distinct = pd.factorize(np.array(values, dtype=object))
        return np.asarray(codes, dtype=np.int64), list(distinct)
    index: dict[str, int] = {}
    out = np.fromiter(
        (index.setdefault(v, len(index)) for v in values), dtype=np.int64, count=len(values)
    )
    return out, list(index)


def _uniform_order(strs: list[Any]) -> np.ndarray | None:
    """The natural order of ids of one length, ASCII, without NUL, whose digits stand at the same
    positions in every id (``P0000001``, ``F01_0101``), or None for any other list.

    Such ids split into text and digit runs of the same widths at the same places, so comparing
    their :func:`natural_key` part by part is comparing the ids byte by byte (equal-width digit
    runs compare as their numbers, equal numbers are equal runs): a stable byte sort, over one
    buffer of the ids (no Python object per id), and none at all when they are already in order."""
    if not strs or type(strs[0]) is not str:
        return None
    n, width = len(strs), len(strs[0])
    if {len(x) if type(x) is str else -1 for x in strs[:: max(1, n // 64)]} != {width}:
        return None  # a sample of other lengths: no join of every id
    try:
        joined = "\n".join(strs)
    except TypeError:  # not text only
        return None
    if (
        not width
        or len(joined) != n * (width + 1) - 1
        or not joined.isascii()
        or "\x00" in joined
        or joined.count("\n") != n - 1
    ):  # no line feed inside an id: the separators are the n - 1
        return None
    rows = np.frombuffer((joined + "\n").encode("ascii"), dtype=np.uint8).reshape(n, width + 1)
    if not bool((rows[:, width] == 10).all()):  # the lengths differ
        return None
    chars = np.ascontiguousarray(rows[:, :width])
    digit = (chars - np.uint8(48)) < 10  # '0'..'9' (below '0' wraps round to large values)
    if not bool((digit == digit[0]).all()):
        return None
    keys = chars.view(f"S{width}").ravel()
    if bool((keys[1:] >= keys[:-1]).all()):
        return np.arange(n, dtype=np.int64)
    # the bytes as big-endian 8-byte words (zero-padded): integer sorts, in the bytes' order
    words = np.zeros((n, -(-width // 8) * 8), dtype=np.uint8)
    words[:, :width] = chars
    w = words.view(">u8")
    if w.shape[1] == 1:
        return np.argsort(w[:, 0], kind="stable").astype(np.int64)
    return np.lexsort(w.T[::-1]).astype(np.int64)


def _all_text(values: list[Any]) -> bool:
    """Every value is a str (checked in C when pandas is loaded, as it is in a check)."""
    if "pandas" not in sys.modules:
        return all(type(x) is str for x in values)
    from pandas.api.types import infer_dtype

    return infer_dtype(values, skipna=False) == "string"


class _Keys:
    """natural_key of the fast-sorted ids, computed only where a binary search looks."""

    def __init__(self, strs: list[str], order: np.ndarray) -> None:
        self.strs, self.order = strs, order

    def __len__(self) -> int:
        return len(self.order)

    def __getitem__(self, k: int) -> tuple[Any, ...]:
        return natural_key(self.strs[int(self.order[k])])


def _slow_order(strs: list[str], idx: np.ndarray) -> np.ndarray:
    """``idx`` sorted by natural_key of its ids (stable)."""
    keys = [natural_key(strs[i]) for i in idx.tolist()]
    return (
        idx[np.array(sorted(range(len(keys)), key=keys.__getitem__), dtype=np.int64)]
        if len(keys)
        else idx.astype(np.int64)
    )


def _order(items: np.ndarray, cache: dict[Any, Any]) -> np.ndarray:
    """Natural order of a rule's items; rules over the same items share one sort."""
    key = id(items) if len(items) < 2 else (len(items), str(items[0]), str(items[-1]))
    hit = cache.get(key)
    if hit is not None and (hit[1] is items or np.array_equal(hit[1], items)):
        return hit[0]
    order = natural_order(items)
    cache[key] = (order, items)
    return order
