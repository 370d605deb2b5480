"""The defect classes of the inspection grid and the manual rules they answer (specs/inspection.yaml)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import yaml

from ..errors import SpecError
from ..present import cite
from ..resources import specs_dir

FILE = "inspection.yaml"
_CODE = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class DefectClass:
    """One defect class: its field name in the grid, title, clause and the seed's words."""

    code: str
    title: str
    clause: dict[str, Any]
    quote: str

    def cite(self) -> str:
        return cite(self.clause)


@dataclass(frozen=True)
class Catalogue:
    """The defect classes in field order, and rule id -> the codes that fail an image for it."""

    defects: tuple[DefectClass, ...]
    rules: dict[str, tuple[str, ...]]

    @property
    def codes(self) -> tuple[str, ...]:
        return tuple(d.code for d in self.defects)

    def get(self, code: str) -> DefectClass:
        return next(d for d in self.defects if d.code == code)


@lru_cache(maxsize=1)
def catalogue() -> Catalogue:
    """specs/inspection.yaml, checked: unique field-safe codes, rules naming known codes."""
    path = specs_dir() / FILE
    raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    if not isinstance(raw, dict) or raw.get("orthospec_inspection") != 1:
        raise SpecError("expected orthospec_inspection: 1", file=str(path))
    defects: list[DefectClass] = []
    for d in raw.get("defects") or []:
        code = str(d["code"])
        if not _CODE.match(code) or code in {x.code for x in defects}:
            raise SpecError(
                f"defect code {code!r} is not a unique lower-case field name", file=str(path)
            )
        defects.append(
            DefectClass(code, str(d["title"]), dict(d.get("clause") or {}), str(d["quote"]))
        )
    codes = {d.code for d in defects}
    rules: dict[str, tuple[str, ...]] = {}
    for rule, want in (raw.get("rules") or {}).items():
        got = tuple(sorted(codes)) if want == "all" else tuple(want)
        unknown = sorted(set(got) - codes)
        if unknown:
            raise SpecError(f"rule {rule} names unknown defect codes {unknown}", file=str(path))
        rules[str(rule)] = tuple(c for c in (d.code for d in defects) if c in got)
    return Catalogue(tuple(defects), rules)
