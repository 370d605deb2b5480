"""Which measures exist and who computes them: built-in providers, plugin providers, generic table
measures and the evaluator's roll-ups; and the per-run cache that calls each provider once.

Providers register with engine/registry.py when their module is imported. This module imports
them (the modules of engine/providers/, then the ``orthospec.providers`` entry points of
installed plugins, see orthospec/plugins.py), once per process, on the first lookup. It also
builds the snapshot ``specs/schema/measures.json`` (built-in measures only) that profile/catalog.py
reads so that validating a profile does not import the engine; once this module is imported,
profile/catalog.py asks it instead (never stale, plugins included).
"""

from __future__ import annotations

import contextlib
import importlib
import pkgutil
import threading
from typing import Any

from .. import plugins, units
from ..delivery.convention import table_specs
from ..errors import OrthospecError
from ..profile import catalog as spec_catalog
from . import generic, providers
from .registry import _PROVIDERS, ROLLUP, Measured, ProviderContext, ProviderSpec, UnknownMeasure

_LOADED: list[bool] = []


def _builtin_modules() -> None:
    for info in sorted(pkgutil.iter_modules(providers.__path__), key=lambda i: i.name):
        importlib.import_module(f"{providers.__name__}.{info.name}")


def _load() -> None:
    """Import the built-in provider modules, then the plugins' (once)."""
    if not _LOADED:
        _builtin_modules()
        _LOADED.append(True)
    plugins.load_providers()  # once loaded a no-op; a broken plugin raises again on every lookup


def preload() -> threading.Thread:
    """Import the built-in providers (scipy, rasterio, shapely: about 0.4 s) and build pint's unit
    registry in a thread, while the caller reads the delivery's tables (pandas' C parser
    releases the GIL while it tokenises). A failure is left to the first lookup, which imports
    again and raises where it is reported; plugins load there too, never in this thread."""
    def run() -> None:
        with contextlib.suppress(Exception):  # raised again, and reported, by the first lookup()
            units.parse_unit("m")  # pint's registry first: the tables' units need it at once
            _builtin_modules()

    thread = threading.Thread(target=run, name="orthospec-preload", daemon=True)
    thread.start()
    return thread


def known_measures() -> dict[str, ProviderSpec]:
    """Every measure a provider registers (built-in and plugin), by name."""
    _load()
    return dict(sorted(_PROVIDERS.items()))


def lookup(name: str) -> ProviderSpec | None:
    _load()
    return _PROVIDERS.get(name)


def measure_info(name: str) -> tuple[str, str] | None:
    """(scope, unit) of any measure a rule may name, or None if nobody provides it."""
    spec = lookup(name)
    if spec is not None:
        return spec.scope, spec.measures[name]
    if name.startswith("rollup."):
        return ROLLUP.get(name)
    return generic.info(name)


def builtin(spec: ProviderSpec) -> bool:
    """Whether a provider ships with orthospec (the snapshot holds only those)."""
    return spec.fn.__module__.startswith(f"{providers.__name__}.")


def snapshot() -> dict[str, Any]:
    """The content of specs/schema/measures.json: built-in, generic and roll-up measure names."""
    names: dict[str, list[str]] = {
        n: [s.scope, s.measures[n]] for n, s in known_measures().items() if builtin(s)
    }
    names.update({n: list(v) for n, v in ROLLUP.items()})
    for t, spec in table_specs().items():
        cands = [f"{t}.present", f"{t}.count", f"{t}.count_per_block"]
        for c in spec.columns:
            cands += [
                f"{t}.{c}",
                f"{t}.{c}.complete",
                *(f"{t}.{c}.{a}" for a in generic.AGGREGATES),
            ]
        for n in cands:
            got = generic.info(n)
            if got is not None and n not in names:
                names[n] = list(got)
    return {"fingerprint": spec_catalog.fingerprint(), "measures": dict(sorted(names.items()))}


def _all_names() -> list[str]:
    return sorted(set(known_measures()) | set(ROLLUP) | set(spec_catalog.snapshot_names()))


spec_catalog.use_live(measure_info, _all_names)


class MeasureCache:
    """Calls each provider at most once per run; remembers failures as per-measure errors."""

    def __init__(self, ctx: ProviderContext) -> None:
        self.ctx = ctx
        self._done: dict[int, dict[str, Measured] | Exception] = {}
        self._generic: dict[tuple[str, str], Measured | Exception] = {}

    def get(self, name: str) -> Measured:
        spec = lookup(name)
        if spec is None:
            if generic.info(name) is None:
                raise UnknownMeasure(name)
            gkey = ("generic", name)
            if gkey not in self._generic:
                try:
                    self._generic[gkey] = generic.compute(name, self.ctx.delivery)
                except (
                    Exception
                ) as exc:  # kept with its traceback and re-raised for every rule reading it
                    self._generic[gkey] = exc
            got_g = self._generic[gkey]
            if isinstance(got_g, Exception):
                raise got_g
            return got_g
        key = id(spec.fn)
        if key not in self._done:
            try:
                out = {m.name: m for m in spec.fn(self.ctx)}
                self._done[key] = out
            except OrthospecError as exc:
                self._done[key] = exc
            except Exception as exc:  # a provider bug must not stop other rules: kept (traceback
                self._done[key] = exc  # included) and re-raised to each rule reading the measure
        got = self._done[key]
        if isinstance(got, Exception):
            raise got
        if name not in got:
            raise UnknownMeasure(name)
        return got[name]

    def details(self) -> dict[str, Any]:
        """Per-provider extras for reports (e.g. the checkpoint table), from providers that ran."""
        out: dict[str, Any] = {}
        for got in self._done.values():
            if isinstance(got, Exception):
                continue
            for m in got.values():
                if m.detail:
                    for k, v in m.detail.items():
                        out.setdefault(k, v)
        return dict(sorted(out.items()))
