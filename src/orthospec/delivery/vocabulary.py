"""Closed vocabularies of the text columns a rule branches on (issue 25 item 4).

A rule that applies when ``scenes.correction_method == 'rpc'`` must not become "not applicable"
because the table says ``RPC``, ``rpc-block`` or ``rpc_refined``: a spelling would otherwise decide
whether the Table 9 GCP minimums are checked at all. The allowed values live once, as a
``values:`` list (and optional ``synonyms:``) on the column in specs/delivery-tables.yaml; this
module reads them, and the table reader (delivery/reader.py) calls :func:`apply` on every table it
parses, so that:

* a cell is normalised before any rule sees it: case, surrounding blanks and separators (space,
  ``-``, ``.``, ``/``) do not matter, and a listed synonym becomes its canonical value
  (``Polynomial`` -> ``poly``, ``Cubic convolution`` -> ``cubic``);
* a cell that is none of the allowed values (nor a synonym) refuses the delivery with exit 2, naming
  the file, the row and the column and listing the allowed values: an unknown word is neither
  matched nor silently left out;
* an empty cell stays empty: the fact is not given, so a `when` that reads it is ``missing``
  (engine/applicability.py), never not-applicable.

:func:`literal_problems` checks the other side: a profile `when` (or an ``in`` requirement)
comparing a vocabulary column with a word that is not one of its canonical values could never
match a normalised cell; the engine treats such a rule as undecidable (``missing``), and
tests/test_vocabulary.py keeps the shipped profiles free of them.
"""

from __future__ import annotations

import ast
import itertools
import re
import unicodedata
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import pandas as pd
import yaml

from ..dotted import dotted_name as _dotted
from ..errors import DeliveryError, SpecError
from ..resources import specs_dir

_SEPARATORS = re.compile(r"[\s\-./_]+")


def key(text: str) -> str:
    """The comparison key of a word: Unicode-normalised, case-folded, separators as one ``_``."""
    t = unicodedata.normalize("NFKC", str(text)).casefold().strip()
    return _SEPARATORS.sub("_", t).strip("_")


@dataclass(frozen=True)
class Vocabulary:
    """The allowed values of one column, and the synonyms read as one of them."""

    table: str
    column: str
    values: tuple[str, ...]
    #: comparison key (:func:`key`) -> canonical value, for the values and their synonyms
    lookup: Mapping[str, str]

    def normalise(self, text: Any) -> str | None:
        """The canonical value of ``text``, or None when it is not one of the allowed values."""
        return self.lookup.get(key(text))

    def allowed(self) -> str:
        return ", ".join(self.values)


def _build(table: str, column: str, values: Any, synonyms: Any) -> Vocabulary:
    where = f"specs/delivery-tables.yaml: {table}.{column}"
    if (
        not isinstance(values, list)
        or not values
        or not all(isinstance(v, str) and v.strip() for v in values)
    ):
        raise SpecError(f"{where}: `values:` must be a non-empty list of words")
    lookup: dict[str, str] = {}
    for v in values:
        if key(v) in lookup:
            raise SpecError(f"{where}: values {lookup[key(v)]!r} and {v!r} are the same word")
        lookup[key(v)] = v
    for syn, canon in (synonyms or {}).items():
        if canon not in values:
            raise SpecError(
                f"{where}: synonym {syn!r} maps to {canon!r}, which is not one of its values"
            )
        if key(syn) in lookup and lookup[key(syn)] != canon:
            raise SpecError(f"{where}: synonym {syn!r} already means {lookup[key(syn)]!r}")
        lookup[key(syn)] = canon
    return Vocabulary(table, column, tuple(values), lookup)


@lru_cache(maxsize=1)
def vocabularies() -> dict[tuple[str, str], Vocabulary]:
    """(table, column) -> its closed vocabulary, for every column with ``values:``."""
    raw = yaml.safe_load((specs_dir() / "delivery-tables.yaml").read_text(encoding="utf-8"))
    out: dict[tuple[str, str], Vocabulary] = {}
    for tname, t in raw["tables"].items():
        for cname, c in t["columns"].items():
            if "values" in c:
                if c.get("type", "text") != "text":
                    raise SpecError(
                        f"specs/delivery-tables.yaml: {tname}.{cname}: `values:` is for text columns"
                    )
                out[(tname, cname)] = _build(tname, cname, c["values"], c.get("synonyms"))
            elif "synonyms" in c:
                raise SpecError(
                    f"specs/delivery-tables.yaml: {tname}.{cname}: `synonyms:` without `values:`"
                )
    return out


def of(table: str, column: str) -> Vocabulary | None:
    """The vocabulary of ``table.column``, or None when the column is free text."""
    return vocabularies().get((table, column))


def of_measure(name: str) -> Vocabulary | None:
    """The vocabulary behind a generic ``<table>.<column>`` measure name, else None."""
    parts = name.split(".")
    return of(parts[0], parts[1]) if len(parts) == 2 else None


def apply(table: str, df: pd.DataFrame, file: str) -> None:
    """Normalise ``df``'s vocabulary columns in place; refuse an unknown value (exit 2).

    One lookup per distinct cell, not per row: a national table repeats a handful of words."""
    for (tname, col), voc in vocabularies().items():
        if tname != table or col not in df.columns or not len(df):
            continue
        cells = df[col]
        filled = cells.notna().to_numpy(bool)
        if not filled.any():
            continue
        distinct = pd.unique(cells[filled].astype(str).to_numpy())
        mapping = {v: voc.normalise(v) for v in distinct}
        bad = [v for v, c in mapping.items() if c is None]
        if bad:
            first = cells[filled].astype(str).isin(bad).to_numpy(bool)
            row = int(df.loc[cells[filled].index[first][0], "_row"])
            raise DeliveryError(
                f"{_shown(bad[0])} is not an allowed value; allowed: {voc.allowed()} (a closed vocabulary: the "
                f"rules branch on this column, specs/delivery-tables.yaml)",
                file=file,
                row=row,
                field=col,
            )
        if any(k != v for k, v in mapping.items()):
            out = cells.to_numpy(dtype=object).copy()
            out[filled] = [mapping[str(v)] for v in out[filled]]
            df[col] = out


def _shown(text: str, limit: int = 60) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "...")


# --- the profile side: literals compared with a vocabulary column ------------------------------


def compared_literals(source: str) -> list[tuple[str, str]]:
    """(measure name, literal) for every ``name == 'word'`` / ``!=`` comparison in an expression."""
    try:
        tree = ast.parse(source, mode="eval")
    except SyntaxError:
        return []
    out: list[tuple[str, str]] = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        for a, b in itertools.pairwise(sides):
            for n, lit in ((a, b), (b, a)):
                name = _dotted(n)
                if (
                    name is not None
                    and isinstance(lit, ast.Constant)
                    and isinstance(lit.value, str)
                ):
                    out.append((name, lit.value))
    return out


def literal_problems(source: str, *, extra: Iterable[tuple[str, Any]] = ()) -> list[str]:
    """Why a `when` (and ``extra`` (measure, value) pairs, e.g. an ``in`` requirement's values) can
    never match a normalised cell: a word that is not one of the column's canonical values."""
    out = []
    for name, lit in [*compared_literals(source), *extra]:
        voc = of_measure(name)
        if voc is None or not isinstance(lit, str) or lit in voc.values:
            continue
        near = voc.normalise(lit)
        hint = f" (write {near!r})" if near is not None else ""
        out.append(
            f"{name} is compared with {lit!r}, which is not one of its values ({voc.allowed()}){hint}"
        )
    return out


def unknown_values(name: str, values: np.ndarray) -> np.ndarray:
    """Per item: a value of the vocabulary column ``name`` that is filled but not allowed (a table
    built without the reader, e.g. by a plugin provider): the fact is unknown, not a mismatch."""
    voc = of_measure(name)
    if voc is None:
        return np.zeros(len(values), dtype=bool)
    return np.fromiter(
        (isinstance(v, str) and v.strip() != "" and v not in voc.values for v in values),
        dtype=bool,
        count=len(values),
    )
