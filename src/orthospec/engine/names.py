"""What an expression (`when`, a threshold) may name, and how a missing value is recognised.

:class:`Names` is the mapping the safe expression grammar (profile/expr.py) evaluates against:
parameters, ``manifest.*`` facts and the measures of the rule's scope, per item. During
applicability probing (engine/applicability.py) ``Names.fill`` substitutes a stand-in value where a
fact or measure is missing, to see whether the `when` depends on it.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
import pandas as pd

from .. import units
from ..delivery import vocabulary
from ..dotted import dotted_name
from ..profile.operators import is_missing
from ..units import NON_NUMERIC, parse_unit
from .catalog import MeasureCache, measure_info
from .params import ParamValue
from .registry import Measured

STRING_LITERAL = re.compile(r"'([^']*)'|\"([^\"]*)\"")
NUMBER_LITERAL = re.compile(r"(?<![\w.])(-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?)(?![\w.])")


def missing_mask(values: np.ndarray) -> np.ndarray:
    """Per item: the value is missing (None, NaN, empty text; see spec.operators.is_missing)."""
    if values.dtype.kind == "f":
        return np.isnan(values)
    if values.dtype.kind in "iub":
        return np.zeros(len(values), dtype=bool)
    return np.fromiter((is_missing(v) for v in values), dtype=bool, count=len(values))


#: words of the expression grammar that look like names but are constants
_NULLS = ("null", "None", "true", "false")


def null_tested(when: str) -> set[str]:
    """Names a `when` compares with null: their absence is part of the condition, not missing evidence."""
    out: set[str] = set()
    try:
        tree = ast.parse(when, mode="eval")
    except SyntaxError:
        return out
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(_is_null(x) for x in sides):
                out.update(d for x in sides if (d := dotted_name(x, reserved=_NULLS)) is not None)
    return out


def _is_null(node: ast.AST) -> bool:
    return (isinstance(node, ast.Constant) and node.value is None) or (
        isinstance(node, ast.Name) and node.id in ("null", "None")
    )


def param_key(name: str) -> str:
    """``param.x`` and ``x`` name the same parameter."""
    return name[6:] if name.startswith("param.") else name


class Names(Mapping[str, Any]):
    """Names an expression may use: parameters, manifest paths, measures of the rule's scope."""

    def __init__(
        self,
        params: dict[str, ParamValue],
        manifest: dict[str, Any],
        cache: MeasureCache,
        scope: str,
        items: list[str],
        *,
        scalar: bool = False,
    ) -> None:
        self.params, self.manifest, self.cache = params, manifest, cache
        self.scope, self.item_ids, self.scalar = scope, items, scalar
        #: name -> value substituted where that fact or measure is missing (applicability probing)
        self.fill: dict[str, Any] = {}

    def __getitem__(self, key: str) -> Any:
        if key in self.params:
            q = self.params[key].quantity()  # None when unset: `param != null` tests that
            if q is None and key in self.fill:
                return self.fill[key]
            return q
        if key.startswith("param."):
            return self[key[6:]]
        if key.startswith("manifest."):
            return self._manifest(key)
        info = measure_info(key)
        if info is None:
            raise KeyError(key)
        m = self.cache.get(key)
        if key in self.fill:
            return self._filled(key, m, info)
        if self.broadcast(info[0]) and self.scalar:
            return self._scalar(m)
        return self._column(m, self._values(m, info))

    def _manifest(self, key: str) -> Any:
        v = self.manifest.get(key)
        if is_missing(v) and key in self.fill:
            return self.fill[key]
        if isinstance(v, dict) and set(v) == {"value", "unit"}:
            return units.Q_(float(v["value"]), parse_unit(v["unit"]))
        return v

    def broadcast(self, measure_scope: str) -> bool:
        """A delivery/project measure read from another scope (or scalar): one value for every item."""
        return measure_scope in ("delivery", "project") and (
            self.scalar or self.scope != measure_scope
        )

    def _values(self, m: Measured, info: tuple[str, str]) -> pd.Series:
        if self.broadcast(info[0]):
            one = m.values.iloc[0] if len(m.values) else None
            return pd.Series([one] * len(self.item_ids), index=self.item_ids, dtype=object)
        return m.values.reindex(self.item_ids)

    @staticmethod
    def _scalar(m: Measured) -> Any:
        one = m.values.iloc[0] if len(m.values) else None
        if is_missing(one):
            return None
        if m.unit in NON_NUMERIC or m.unit == "any" or one is None:
            return one
        return units.Q_(float(one), parse_unit(m.unit))

    @staticmethod
    def _column(m: Measured, vals: pd.Series) -> Any:
        if m.unit in NON_NUMERIC or m.unit == "any":
            return vals.to_numpy(dtype=object)
        arr = pd.to_numeric(vals, errors="coerce").to_numpy(dtype=float)
        return units.Q_(arr, parse_unit(m.unit))

    def _filled(self, key: str, m: Measured, info: tuple[str, str]) -> Any:
        """The measure with its missing entries replaced by the probe value ``fill[key]``."""
        if self.broadcast(info[0]):
            one = m.values.iloc[0] if len(m.values) else None
            vals = pd.Series([one] * max(len(self.item_ids), 1), dtype=object)
        else:
            vals = m.values.reindex(self.item_ids)
        raw = vals.to_numpy(dtype=object).copy()
        raw[missing_mask(raw) | vocabulary.unknown_values(key, raw)] = self.fill[key]
        if m.unit in NON_NUMERIC or m.unit == "any":
            return raw[0] if self.scalar else raw
        arr = pd.to_numeric(pd.Series(raw), errors="coerce").to_numpy(dtype=float)
        q = units.Q_(arr, parse_unit(m.unit))
        return q[0] if self.scalar else q

    def __contains__(self, key: object) -> bool:
        if not isinstance(key, str):
            return False
        return (
            key in self.params
            or key.startswith("manifest.")
            or key.startswith("param.")
            or measure_info(key) is not None
        )

    def __iter__(self) -> Iterator[str]:  # pragma: no cover - Mapping protocol; never enumerated
        return iter(self.params)

    def __len__(self) -> int:  # pragma: no cover
        return len(self.params)
