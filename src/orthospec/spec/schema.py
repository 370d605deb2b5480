"""Generate the published JSON Schemas (profile, delivery manifest, QCR) from the models.

`python -m orthospec.spec.schema` rewrites specs/schema/*.json (and the measure catalog
measures.json, see spec/catalog.py); a test fails when they are stale.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from .models import Profile

SCHEMA_BASE = "https://orthospec.dev/schema/"


def profile_schema() -> dict[str, Any]:
    s = Profile.model_json_schema(mode="validation")
    # if/then/else instead of oneOf: editors and validators then report the mistake inside the rule
    s["properties"]["rules"]["items"] = {
        "if": {"properties": {"override": {"const": True}}, "required": ["override"]},
        "then": {"$ref": "#/$defs/RuleOverride"},
        "else": {"$ref": "#/$defs/Rule"},
    }
    s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    s["$id"] = SCHEMA_BASE + "profile.schema.json"
    s["title"] = "orthospec spec profile"
    s["description"] = ("A versioned YAML spec profile: parameters the tender fixes, lookup tables, "
                        "classes and rules with clause, quote, scope, measure, requirement, level and "
                        "consequence. See docs/ARCHITECTURE.md.")
    return s


def all_schemas() -> dict[str, dict[str, Any]]:
    from ..delivery.manifest import manifest_schema
    from ..qcr import qcr_schema

    return {
        "profile.schema.json": profile_schema(),
        "delivery.schema.json": manifest_schema(),
        "qcr.schema.json": qcr_schema(),
    }


def dumps(schema: dict[str, Any]) -> str:
    return json.dumps(schema, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def write(folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, schema in all_schemas().items():
        p = folder / name
        p.write_text(dumps(schema), encoding="utf-8")
        out.append(p)
    from .catalog import write as write_catalog

    out.append(write_catalog(folder))
    return out


if __name__ == "__main__":  # pragma: no cover
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("specs/schema")
    for p in write(target):
        print(p)
