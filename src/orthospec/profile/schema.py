"""The profile JSON Schema, generated from the pydantic models of profile/models.py.

Writing every published schema (profile, delivery manifest, QCR, measure catalog) needs the
QCR model and the engine, which sit above spec/: that is orthospec/schemas.py
(``python -m orthospec.schemas``).
"""

from __future__ import annotations

import json
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
    s["description"] = (
        "A versioned YAML spec profile: parameters the tender fixes, lookup tables, "
        "classes and rules with clause, quote, scope, measure, requirement, level and "
        "consequence. See docs/ARCHITECTURE.md."
    )
    return s


def dumps(schema: dict[str, Any]) -> str:
    return json.dumps(schema, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit("moved: run `python -m orthospec.schemas` (it writes every published schema)")
