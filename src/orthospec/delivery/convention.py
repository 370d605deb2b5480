"""The delivery table convention, read from specs/delivery-tables.yaml (data, not code)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import yaml

from ..errors import SpecError
from ..resources import specs_dir

ColumnType = Literal["text", "number", "bool", "date", "datetime"]


@dataclass(frozen=True)
class ColumnSpec:
    name: str
    type: ColumnType
    unit: str | None  # for numbers: a unit, or "length" = the delivery's coordinate unit
    required: bool
    description: str
    #: bounds a number must respect (an RMSE or a precision is >= 0, a share <= 100 %): the one CSV
    #: reader refuses a value outside them (red team R14)
    min: float | None = None
    max: float | None = None


@dataclass(frozen=True)
class TableSpec:
    name: str
    scope: str
    id: str | None
    description: str
    columns: dict[str, ColumnSpec]
    items: bool = False  # its rows are the items of its scope (`items: true` in the YAML)

    @property
    def required(self) -> list[str]:
        return [c for c, s in self.columns.items() if s.required]


@lru_cache(maxsize=1)
def table_specs() -> dict[str, TableSpec]:
    raw = yaml.safe_load((specs_dir() / "delivery-tables.yaml").read_text(encoding="utf-8"))
    out: dict[str, TableSpec] = {}
    for name, t in raw["tables"].items():
        cols = {
            c: ColumnSpec(c, s.get("type", "text"), s.get("unit"), bool(s.get("required", False)),
                          s.get("description", ""), s.get("min"), s.get("max"))
            for c, s in t["columns"].items()
        }
        out[name] = TableSpec(name, t["scope"], t.get("id"), t.get("description", ""), cols,
                              bool(t.get("items", False)))
    return out


@lru_cache(maxsize=1)
def _scope_tables() -> dict[str, str]:
    out: dict[str, str] = {}
    for name, spec in table_specs().items():
        if spec.items:
            if spec.scope in out or spec.id is None:
                raise SpecError(
                    f"specs/delivery-tables.yaml: table {name!r}: `items: true` needs an id "
                    f"column and one table per scope (scope {spec.scope!r})"
                )
            out[spec.scope] = name
    return out


def table_of_scope(scope: str) -> str | None:
    """The table whose rows are the items of ``scope`` (``image`` -> ``images``), else None.

    The one scope -> table map (issue 15): read from ``items: true`` in specs/delivery-tables.yaml.
    Scopes whose items come from the manifest (delivery, project, block, edge) have none.
    """
    return _scope_tables().get(scope)
