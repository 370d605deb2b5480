"""Reading single cells and columns of the delivery's tables the way the ``derived.*`` providers
need: a cell that holds a value, a column in metres, a normalised method name. No measure is
registered here.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ...units import convert


def filled(v: Any) -> bool:
    """The cell holds a value (not None, NaN or blank)."""
    return v is not None and not (isinstance(v, float) and np.isnan(v)) and bool(str(v).strip())


def norm(v: Any) -> str | None:
    """A name lower-cased with spaces and hyphens as underscores (``Space resection`` ->
    ``space_resection``); None when blank."""
    if v is None:
        return None
    t = str(v).strip().lower().replace(" ", "_").replace("-", "_")
    return t or None


def table_metres(t: Any, col: str) -> pd.Series:
    """One numeric column of a table in metres, indexed by item id (first row per id)."""
    vals = convert(
        pd.to_numeric(t.df[col], errors="coerce").to_numpy(dtype=float), t.units.get(col, "m"), "m"
    )
    s = pd.Series(vals, index=t.ids.astype(str).to_numpy())
    return s[~s.index.duplicated()]
