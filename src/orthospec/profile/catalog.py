"""Measure names a rule may read, without importing the engine (spec/ sits below engine/).

The engine learns its measures by importing every provider (pandas, rasterio, scipy: about a
second). Validating or explaining a profile only needs the names, scopes and units, so they are
kept in ``specs/schema/measures.json`` (built by engine/catalog.py, written by
``python -m orthospec.schemas``) together with a fingerprint of the source files that define
measures. Three sources, in order:

1. the live engine, once engine/catalog.py is imported (it calls :func:`use_live`): always the
   case in ``check``, so the measures that decide a verdict are never taken from a stale list;
2. measures announced by ``@provider`` in this process (engine/registry.py calls
   :func:`announce`), which is how plugin measures are known: a name found nowhere else makes
   the installed ``orthospec.providers`` plugins load (orthospec/plugins.py);
3. the snapshot. A stale one (a provider was edited in a source checkout and the snapshot not
   regenerated) is still used; an unknown measure then says so and names the command that
   regenerates it (:func:`stale_hint`). A test keeps the shipped snapshot current.

This module imports nothing above spec/.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

from .. import plugins
from ..resources import specs_dir

_PKG = Path(__file__).resolve().parent.parent
CATALOG_NAME = "measures.json"


def _sources() -> list[tuple[str, Path]]:
    """The files whose content decides which measure names exist (those registering providers)."""
    out: list[tuple[str, Path]] = []
    eng = _PKG / "engine"
    for p in sorted([*eng.glob("*.py"), *eng.glob("providers/*.py")]):
        try:
            defines = (
                p.name in ("registry.py", "generic.py", "catalog.py")
                or b"provider(" in p.read_bytes()
            )
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


def dumps(doc: dict[str, object]) -> str:
    """The snapshot file's text (engine/catalog.snapshot() gives ``doc``)."""
    return json.dumps(doc, indent=1, sort_keys=True, ensure_ascii=False) + "\n"


_ANNOUNCED: dict[str, tuple[str, str]] = {}
_LIVE: list[tuple[Callable[[str], tuple[str, str] | None], Callable[[], list[str]]]] = []


def announce(name: str, scope: str, unit: str) -> None:
    """A provider registered ``name`` in this process (called by engine/registry.py)."""
    _ANNOUNCED[name] = (scope, unit)


def use_live(info: Callable[[str], tuple[str, str] | None], names: Callable[[], list[str]]) -> None:
    """Look measures up in the engine from now on (called when engine/catalog.py is imported)."""
    _LIVE[:] = [(info, names)]


def snapshot_names() -> list[str]:
    """The names in the snapshot file, current or not."""
    return sorted(_read_snapshot()[1])


@lru_cache(maxsize=1)
def _read_snapshot() -> tuple[bool, dict[str, tuple[str, str]]]:
    """(current, names) of the shipped snapshot; (False, {}) when it is unreadable."""
    try:
        doc = json.loads((specs_dir() / "schema" / CATALOG_NAME).read_text(encoding="utf-8"))
        names = {str(n): (str(v[0]), str(v[1])) for n, v in doc.get("measures", {}).items()}
    except (OSError, ValueError, AttributeError, TypeError, IndexError):
        return False, {}
    return doc.get("fingerprint") == fingerprint(), names


def _snapshot() -> dict[str, tuple[str, str]]:
    return _read_snapshot()[1]


def stale_hint() -> str:
    """What an unknown-measure message adds when the names came from a stale snapshot, else ''."""
    if _LIVE or is_current():
        return ""
    return (
        f" ({specs_dir() / 'schema' / CATALOG_NAME} does not match the measure providers edited in this "
        "checkout: run `python -m orthospec.schemas`)"
    )


def is_current() -> bool:
    """Whether the shipped snapshot matches the code."""
    return _read_snapshot()[0]


def _plugin_lookup(name: str) -> tuple[str, str] | None:
    """Load the installed provider plugins (once) and look ``name`` up among what they announced."""
    if plugins.entry_points(plugins.PROVIDERS):
        plugins.load_providers()
    return _ANNOUNCED.get(name)


def measure_info(name: str) -> tuple[str, str] | None:
    """(scope, unit) of a measure name, like ``engine.catalog.measure_info``, but cheap."""
    if name.startswith("manifest."):
        return "delivery", "any"
    if _LIVE:
        return _LIVE[0][0](name)
    got = _ANNOUNCED.get(name) or _snapshot().get(name)
    return got if got is not None else _plugin_lookup(name)


def all_names() -> list[str]:
    """Every known measure name (for did-you-mean)."""
    if _LIVE:
        return _LIVE[0][1]()
    return sorted(set(_snapshot()) | set(_ANNOUNCED))


def extended_by_plugins() -> bool:
    """Whether this process knows measures beyond the snapshot (plugin providers were loaded):
    a profile validated now is not written to the profile cache (it depends on the plugins)."""
    snap = _read_snapshot()[1]
    return any(n not in snap for n in _ANNOUNCED)
