"""Extension points: measure providers, output formats and profiles from other distributions.

An agency adds its own measures, report formats or profiles without forking orthospec by
publishing a distribution that declares Python entry points (``pyproject.toml``)::

    [project.entry-points."orthospec.providers"]
    example = "orthospec_example_plugin.providers"     # a module; importing it registers providers
    [project.entry-points."orthospec.formats"]
    tiles-csv = "orthospec_example_plugin.formats:tiles_csv"   # callable(doc) -> str | bytes
    [project.entry-points."orthospec.profiles"]
    example = "orthospec_example_plugin.profiles"      # a package (folder) holding profile YAML

* ``orthospec.providers``: a module whose import registers providers with
  ``orthospec.engine.registry.provider`` (exactly like the built-in ones).
* ``orthospec.formats``: the entry point's name is the format name (``check --format NAME``); the
  object is a callable ``render(doc: dict) -> str | bytes`` taking the QCR document; its
  ``suffix`` attribute (e.g. ``".csv"``) names the output file's extension (default ``.NAME``).
* ``orthospec.profiles``: a package (or module) whose folder holds ``*.yaml`` profiles; they are
  found by ``--profile ID`` and by ``extends`` after the shipped profiles and the extending file's
  folder (a shipped profile of the same id and version wins).

Everything is lazy: ``importlib.metadata`` (about 0.1 s to import) is touched only when a command
needs a plugin (an unknown measure, format or profile id; ``orthospec profiles``; a check run
resolving its measures), never by ``--help``. A plugin that fails to load raises an
:class:`~orthospec.errors.OrthospecError` naming the distribution and the entry point.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import OrthospecError

if TYPE_CHECKING:
    from importlib.metadata import EntryPoint

PROVIDERS = "orthospec.providers"
FORMATS = "orthospec.formats"
PROFILES = "orthospec.profiles"
GROUPS = (PROVIDERS, FORMATS, PROFILES)


@dataclass(frozen=True)
class Format:
    """An output format a plugin adds: ``render(doc)`` writes ``<stem><suffix>``."""

    name: str
    suffix: str
    render: Callable[[dict[str, Any]], str | bytes]
    origin: str


def _dist(ep: EntryPoint) -> str:
    d = getattr(ep, "dist", None)
    return f"{d.name} {d.version}" if d is not None else "(unknown distribution)"


def origin(ep: EntryPoint) -> str:
    """How an error names a plugin: distribution, group and entry point."""
    return f"plugin {_dist(ep)}: entry point {ep.name} = {ep.value} (group {ep.group})"


@cache
def entry_points(group: str) -> tuple[EntryPoint, ...]:
    """The installed entry points of ``group``, sorted by name then value (deterministic)."""
    from importlib.metadata import entry_points as _eps

    return tuple(sorted(_eps(group=group), key=lambda e: (e.name, e.value)))


def installed() -> list[str]:
    """One line per installed orthospec entry point (for fingerprints and ``orthospec profiles``)."""
    return [
        f"{ep.group} {ep.name} = {ep.value} [{_dist(ep)}]" for g in GROUPS for ep in entry_points(g)
    ]


@lru_cache(maxsize=1)
def fingerprint() -> str:
    """SHA-256 over the installed entry points (the profile cache keys on it)."""
    return hashlib.sha256("\n".join(installed()).encode("utf-8")).hexdigest()


def _load(ep: EntryPoint) -> Any:
    try:
        return ep.load()
    except OrthospecError as exc:
        raise OrthospecError(f"{origin(ep)}: {exc}") from exc
    except (
        Exception
    ) as exc:  # a third-party import can fail any way: name the plugin, keep the cause
        raise OrthospecError(f"{origin(ep)}: cannot load: {type(exc).__name__}: {exc}") from exc


_PROVIDERS_LOADED: list[str] = []


def load_providers() -> list[str]:
    """Import every ``orthospec.providers`` module once (they register their providers).

    Returns the origins loaded. Called by the engine when it resolves measures, never at start-up.
    """
    if not _PROVIDERS_LOADED:
        for ep in entry_points(PROVIDERS):
            _load(ep)
            _PROVIDERS_LOADED.append(origin(ep))
        _PROVIDERS_LOADED.append("")  # sentinel: loaded (possibly none)
    return [o for o in _PROVIDERS_LOADED if o]


@lru_cache(maxsize=1)
def formats() -> dict[str, Format]:
    """Output formats plugins add, by name."""
    out: dict[str, Format] = {}
    for ep in entry_points(FORMATS):
        fn = _load(ep)
        if not callable(fn):
            raise OrthospecError(
                f"{origin(ep)}: not callable (expected render(doc) -> str | bytes)"
            )
        suffix = getattr(fn, "suffix", None) or f".{ep.name}"
        if (
            not isinstance(suffix, str)
            or not suffix.startswith(".")
            or "/" in suffix
            or "\\" in suffix
        ):
            raise OrthospecError(
                f"{origin(ep)}: suffix {suffix!r} must be a file extension like '.csv'"
            )
        if ep.name in out:
            raise OrthospecError(
                f"{origin(ep)}: format {ep.name!r} is also declared by {out[ep.name].origin}"
            )
        out[ep.name] = Format(ep.name, suffix, fn, origin(ep))
    return out


def output_format(name: str) -> Format | None:
    """The plugin format ``name``, or None when no plugin declares it."""
    return formats().get(name)


def _folder(ep: EntryPoint) -> Path:
    """The folder of the package an ``orthospec.profiles`` entry point names (found, not run)."""
    mod, _, attr = ep.value.partition(":")
    mod = mod.strip()
    try:
        spec = importlib.util.find_spec(mod)
    except (ImportError, ValueError) as exc:
        raise OrthospecError(f"{origin(ep)}: cannot find module {mod!r}: {exc}") from exc
    if spec is None:
        raise OrthospecError(f"{origin(ep)}: module {mod!r} is not installed")
    if attr:
        raise OrthospecError(
            f"{origin(ep)}: name a package (a folder of profile YAML files), not {attr.strip()!r}"
        )
    if spec.submodule_search_locations:
        folder = Path(next(iter(spec.submodule_search_locations)))
    elif spec.origin:
        folder = Path(spec.origin).parent
    else:
        raise OrthospecError(f"{origin(ep)}: module {mod!r} has no folder")
    if not folder.is_dir():
        raise OrthospecError(f"{origin(ep)}: {folder} is not a folder")
    return folder


@lru_cache(maxsize=1)
def profile_dirs() -> tuple[Path, ...]:
    """Folders of profiles plugins ship, in entry-point order."""
    return tuple(_folder(ep) for ep in entry_points(PROFILES))


def cache_clear() -> None:
    """Forget what was discovered (tests that install a plugin in-process)."""
    entry_points.cache_clear()
    fingerprint.cache_clear()
    formats.cache_clear()
    profile_dirs.cache_clear()
