"""Text cells of a check-point table stay the text delivered (issue 14: the C parser infers the
text columns, and would turn a column into numbers, booleans or NaN when every value of it reads
as one; such a column is re-read as text)."""

from __future__ import annotations

import pytest

from orthospec.delivery.convention import table_specs
from orthospec.delivery.reader import parse_csv

HEADER = "point_id,block,x,y,x_ref,y_ref,image_id,source,excluded,exclusion_reason\n"


@pytest.mark.parametrize("cells", [
    ("007", "1e3", " 12 "),            # numbers: pandas would make 7, 1000.0, 12
    ("true", "false", "TRUE"),         # booleans
    ("2026-01-01", "2026-02-03", ""),  # dates (and one empty cell)
    ("B", "inf", "nan"),               # words a float parser knows
])
def test_text_columns_keep_the_delivered_text(cells: tuple[str, str, str]) -> None:
    rows = "".join(f"P{i},B01,1.5,2,1,2,{c},{c},false,{c}\n" for i, c in enumerate(cells))
    df = parse_csv((HEADER + rows).encode(), table_specs()["checkpoints"], file="t.csv")
    want = [c.strip() or None for c in cells]
    for col in ("image_id", "source", "exclusion_reason"):
        assert df[col].tolist() == want
        assert all(v is None or type(v) is str for v in df[col].tolist())
    assert df["block"].tolist() == ["B01"] * 3 and df["excluded"].tolist() == [False] * 3
