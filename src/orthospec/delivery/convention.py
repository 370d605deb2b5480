"""The delivery table convention, read from specs/delivery-tables.yaml (data, not code)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import yaml

from ..resources import specs_dir

ColumnType = Literal["text", "number", "bool", "date", "datetime"]


@dataclass(frozen=True)
class ColumnSpec:
    name: str
    type: ColumnType
    unit: str | None  # for numbers: a unit, or "length" = the delivery's coordinate unit
    required: bool
    description: str


@dataclass(frozen=True)
class TableSpec:
    name: str
    scope: str
    id: str | None
    description: str
    columns: dict[str, ColumnSpec]

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
                          s.get("description", ""))
            for c, s in t["columns"].items()
        }
        out[name] = TableSpec(name, t["scope"], t.get("id"), t.get("description", ""), cols)
    return out
