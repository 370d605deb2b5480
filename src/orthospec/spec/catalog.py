"""Measure names a rule may read, without importing the engine.

The engine learns its measures by importing every provider (pandas, rasterio, scipy: about a
second). Validating or explaining a profile only needs the names, scopes and units, so they are
kept in ``specs/schema/measures.json``, written by ``python -m orthospec.spec.schema`` together
with a fingerprint of the source files that define measures. When the fingerprint does not match
the code (a provider changed and the snapshot was not regenerated), the engine is imported
instead: a stale snapshot makes validation slower, never wrong.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..resources import specs_dir

_PKG = Path(__file__).resolve().parent.parent
CATALOG_NAME = "measures.json"


def _sources() -> list[tuple[str, Path]]:
    """The files whose content decides which measure names exist (those registering providers)."""
    out: list[tuple[str, Path]] = []
    eng = _PKG / "engine"
    for p in sorted([*eng.glob("*.py"), *eng.glob("providers/*.py")]):
        try:
            defines = p.name in ("registry.py", "generic.py") or b"provider(" in p.read_bytes()
        except OSError:
            defines = True
        if defines:
            out.append((p.relative_to(_PKG).as_posix(), p))
    out.append(("delivery/convention.py", _PKG / "delivery" / "convention.py"))
    out.append(("specs/delivery-tables.yaml", specs_dir() / "delivery-tables.yaml"))
    return out


@lru_cache(maxsize=1)
def fingerprint() -> str:
    h = hashlib.sha256()
    for name, path in _sources():
        h.update(name.encode() + b"\0")
        try:
            h.update(hashlib.sha256(path.read_bytes()).digest())
        except OSError:
            h.update(b"(absent)")
    return h.hexdigest()


def build() -> dict[str, Any]:
    """Every measure name from the registry and the generic table measures (imports the engine)."""
    from ..delivery.convention import table_specs
    from ..engine import generic
    from ..engine.registry import ROLLUP, known_measures

    names: dict[str, list[str]] = {n: [s.scope, s.measures[n]] for n, s in known_measures().items()}
    names.update({n: list(v) for n, v in ROLLUP.items()})
    for t, spec in table_specs().items():
        cands = [f"{t}.present", f"{t}.count", f"{t}.count_per_block"]
        for c in spec.columns:
            cands += [f"{t}.{c}", f"{t}.{c}.complete", *(f"{t}.{c}.{a}" for a in generic.AGGREGATES)]
        for n in cands:
            got = generic.info(n)
            if got is not None and n not in names:
                names[n] = list(got)
    return {"fingerprint": fingerprint(), "measures": dict(sorted(names.items()))}


def write(folder: Path) -> Path:
    p = folder / CATALOG_NAME
    p.write_text(json.dumps(build(), indent=1, sort_keys=True, ensure_ascii=False) + "\n", encoding="utf-8")
    return p


@lru_cache(maxsize=1)
def _snapshot() -> dict[str, tuple[str, str]] | None:
    try:
        doc = json.loads((specs_dir() / "schema" / CATALOG_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(doc, dict) or doc.get("fingerprint") != fingerprint():
        return None
    return {n: (v[0], v[1]) for n, v in doc.get("measures", {}).items()}


@lru_cache(maxsize=1)
def _live() -> dict[str, tuple[str, str]]:
    """The names from the engine itself (stale snapshot): imported once, then looked up."""
    return {n: (v[0], v[1]) for n, v in build()["measures"].items()}


def is_current() -> bool:
    """Whether the shipped snapshot matches the code (else lookups import the engine)."""
    return _snapshot() is not None


def measure_info(name: str) -> tuple[str, str] | None:
    """(scope, unit) of a measure name, like ``engine.registry.measure_info``, but cheap."""
    if name.startswith("manifest."):
        return "delivery", "any"
    snap = _snapshot()
    if snap is None:
        snap = _live()
    return snap.get(name)


def all_names() -> list[str]:
    """Every known measure name (for did-you-mean)."""
    snap = _snapshot()
    return sorted(snap if snap is not None else _live())
