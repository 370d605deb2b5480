"""How orthospec prints a value and cites a clause: one vocabulary for every output.

qcr.json messages, qcr.csv and Parquet cells, the terminal, the HTML and PDF reports, the tender
annex and the CLI all format values and citations here, so a value reads the same wherever a reader
meets it (a measured 0.641 m is never ``0.641`` in one place and ``0.64`` in another) and "no value"
has one spelling, :data:`NO_VALUE`. The sentence of a requirement lives with its operator
(``profile/operators.py``); this module only formats the numbers and units it is given.

Foundation layer, standard library only: every layer above may import it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

__all__ = [
    "NO_UNIT",
    "NO_VALUE",
    "CiteStyle",
    "cite",
    "fmt_fixed",
    "fmt_measured",
    "fmt_number",
    "fmt_quantity",
    "fmt_value",
    "unit_suffix",
]

#: how every output spells a value that is not there (None, NaN)
NO_VALUE = "n/a"

#: units not printed after a number (dimensionless and the non-numeric kinds)
NO_UNIT = frozenset({"", "1", "text", "bool", "date", "any"})


def unit_suffix(unit: Any) -> str:
    """What follows a number: ``" m"``, or nothing for a dimensionless or non-numeric unit."""
    return f" {unit}" if unit and unit not in NO_UNIT else ""


def _is_bool(x: Any) -> bool:
    return isinstance(x, bool) or type(x).__name__ == "bool_"  # numpy's bool prints True/False


def _no_value(x: Any) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def fmt_value(x: Any, digits: int = 6) -> str:
    """A measured or threshold value as printed: ``digits`` significant digits (6: what qcr.json's
    messages and requirement texts say), booleans as true/false (as a profile writes them), None
    and NaN as :data:`NO_VALUE`, a list as its values joined by commas."""
    if type(x) is float:  # the common case first (a message per record of a national delivery)
        return f"{x:.{digits}g}" if x == x else NO_VALUE
    if _no_value(x):
        return NO_VALUE
    if _is_bool(x):
        return "true" if x else "false"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    if isinstance(x, list | tuple):
        return ", ".join(fmt_value(v, digits) for v in x)
    return str(x)


def fmt_fixed(x: Any, places: int = 3) -> str:
    """A number with ``places`` decimals (table columns of one statistic line up); text as given."""
    if _no_value(x) or isinstance(x, str) or _is_bool(x):
        return x if isinstance(x, str) else fmt_value(x)
    f = float(x)
    return f"{f:.{places}f}" if math.isfinite(f) else fmt_value(f)


def fmt_number(x: Any) -> str:
    """A number for a reader's sentence: whole numbers as such, three significant digits, values
    of 1000 and more to the unit (a finding says ``0.641 m``, ``1234 m``, never ``1.23e+03 m``)."""
    if _no_value(x) or _is_bool(x) or not isinstance(x, int | float):
        return fmt_value(x)
    if isinstance(x, int):
        return str(x)
    if not math.isfinite(x):
        return fmt_value(x)
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return f"{x:.0f}" if abs(x) >= 1000 else f"{x:.3g}"


def fmt_quantity(value: Any, unit: Any, digits: int = 6) -> str:
    """A value with its unit (``0.641 m``); no unit after :data:`NO_VALUE` or a dimensionless one."""
    text = fmt_value(value, digits)
    return text if text == NO_VALUE else text + unit_suffix(unit)


def fmt_measured(m: Mapping[str, Any] | None) -> str:
    """A QCR record's ``measured`` entry (``{value, unit}``) as a quantity."""
    if not m:
        return NO_VALUE
    return fmt_quantity(m.get("value"), m.get("unit"))


# --- clause citations ----------------------------------------------------------------------------

#: ``text``: the citation a person reads (qcr.json, reports, terminal, annex, CLI);
#: ``columns``: the parts as the profile writes them, comma-separated (qcr.csv and Parquet cells);
#: ``ref``: section, table and figure without the document (qcr.json ``clause_ref``, short columns);
#: ``section``: the section alone (the ledger's audit family when a rule names none)
CiteStyle = Literal["text", "columns", "ref", "section"]


def _part(clause: Any, key: str) -> Any:
    if isinstance(clause, Mapping):
        return clause.get(key)
    return getattr(clause, key, None)


def cite(clause: Any, style: CiteStyle = "text") -> str:
    """A clause citation: ``JRC EUR 23638 EN, §12.4, Table 12, row 'Check points'`` (``text``).

    ``clause`` is a profile's :class:`~orthospec.profile.models.Clause`, its dict as qcr.json
    records it, text already worded (returned as given) or None (``""``). Every output cites
    through this function, so one rule is cited the same way in all of them.
    """
    if not clause:
        return ""
    if isinstance(clause, str):
        return clause
    doc, section, table, row, figure = (
        _part(clause, k) for k in ("document", "section", "table", "row", "figure")
    )
    if style == "columns":
        return ", ".join(str(v) for v in (doc, section, table, row) if v)
    if style == "section":
        return f"§{section}" if section else ""
    if style == "ref":
        parts = [
            f"§{section}" if section else "",
            f"T{table}" if table else "",
            f"Fig. {figure}" if figure else "",
        ]
        return " ".join(p for p in parts if p) or str(doc or "")
    parts = [
        str(doc or ""),
        f"§{section}" if section else "",
        f"Table {table}" if table else "",
        f"row '{row}'" if row else "",
        f"Figure {figure}" if figure else "",
    ]
    return ", ".join(p for p in parts if p)
