"""Named value classes of a profile (e.g. the JRC §9.1 resolution classes), applied to numbers.

Pure numpy, no I/O. A class set is a list of intervals ``{id, min, max, min_inclusive,
max_inclusive}`` in one unit; a value in no interval (a gap of the text, e.g. 8-10 m between
HR and MR in JRC §9.1) gets no class (None), never the nearest one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def _get(item: Any, key: str, default: Any = None) -> Any:
    if isinstance(item, Mapping):
        return item.get(key, default)
    return getattr(item, key, default)


def classify(values: Sequence[float] | np.ndarray, items: Sequence[Any]) -> list[str | None]:
    """The id of the first class whose interval contains each value; None for NaN or a gap.

    ``items`` are the class set's items (pydantic ``ClassItem`` or mappings); bounds not given
    are open (-inf / +inf).
    """
    v = np.asarray(values, dtype=float)
    out: list[str | None] = [None] * v.size
    for item in items:
        lo, hi = _get(item, "min"), _get(item, "max")
        lo_inc, hi_inc = _get(item, "min_inclusive", True), _get(item, "max_inclusive", True)
        with np.errstate(invalid="ignore"):
            a = np.ones(v.size, dtype=bool) if lo is None else (v >= lo if lo_inc else v > lo)
            b = np.ones(v.size, dtype=bool) if hi is None else (v <= hi if hi_inc else v < hi)
        for i in np.flatnonzero(a & b & ~np.isnan(v)):
            if out[i] is None:
                out[i] = str(_get(item, "id"))
    return out
