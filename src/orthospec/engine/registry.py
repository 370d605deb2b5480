"""Measure providers: adapt a delivery to named measure columns, once per run, lazily.

A provider is a function ``fn(ctx: ProviderContext) -> Iterable[Measured]`` registered for one
scope and a fixed set of measure names with their units. The evaluator asks the registry for
the provider of a measure only when a rule needs it, so a profile that never reads rasters
never opens one.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..errors import MeasureError, OrthospecError
from ..provenance import Evidence

if TYPE_CHECKING:
    from ..delivery.reader import Delivery

#: Scopes in report order; the evaluator sorts records by this.
SCOPES: tuple[str, ...] = (
    "delivery", "project", "block", "image", "band", "checkpoint", "gcp", "flight", "camera",
    "scanner", "dem", "mosaic", "edge",
)


@dataclass
class Measured:
    """One measure over the items of one scope, with the evidence behind each value."""

    name: str
    scope: str
    unit: str
    values: pd.Series
    evidence: pd.Series
    detail: dict[str, Any] | None = None
    #: per-item explanation when a value is missing or could not be computed (reason text)
    notes: pd.Series | None = None
    #: items whose value could not be computed because their input is broken (verdict `error`)
    errors: pd.Series | None = None
    #: items the measure does not apply to (verdict `not_applicable`), value = reason text
    na: pd.Series | None = None

    def __post_init__(self) -> None:
        self.values.index = self.values.index.astype(str)
        if isinstance(self.evidence, pd.Series):
            self.evidence = self.evidence.reindex(self.values.index)
            self.evidence = self.evidence.map(lambda e: e if isinstance(e, tuple) else ())

    def evidence_for(self, items: list[str]) -> Sequence[tuple[Evidence, ...]]:
        """Evidence per item, in ``items`` order (empty tuple where there is none)."""
        if isinstance(self.evidence, RowEvidence):
            return self.evidence.take(items)
        ev = self.evidence.reindex(items)
        return [e if isinstance(e, tuple) else () for e in ev.tolist()]


class RowEvidence:
    """Per-row evidence of one table, built only when a record is written (no tuple per row)."""

    def __init__(self, file: str, sha256: str, rows: pd.Series) -> None:
        self.file, self.sha256 = file, sha256
        self.rows = rows  # index = item id, value = 1-based data row

    def take(self, items: list[str]) -> _LazyEvidence:
        rows = self.rows.reindex(items).to_numpy(dtype=float)
        return _LazyEvidence(self.file, self.sha256, rows)


class _LazyEvidence(Sequence[tuple[Evidence, ...]]):
    def __init__(self, file: str, sha256: str, rows: np.ndarray) -> None:
        self.file, self.sha256, self.rows = file, sha256, rows

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, i: int) -> tuple[Evidence, ...]:  # type: ignore[override]
        r = self.rows[i]
        if np.isnan(r):
            return ()
        return (Evidence(self.file, self.sha256, (int(r),)),)


@dataclass
class ProviderContext:
    """What a provider may read: the opened delivery, the resolved parameters, options."""

    delivery: Delivery
    parameters: Mapping[str, Any]  # name -> pint Quantity, str, bool, number
    options: Mapping[str, Any] = field(default_factory=dict)  # workers, scheduler, cache...
    #: shared work between providers of one run (e.g. one pass over the checkpoints)
    memo: dict[str, Any] = field(default_factory=dict)
    #: the profile's named classes (e.g. ``resolution`` of JRC §9.1), for computed class measures
    classes: Mapping[str, Any] = field(default_factory=dict)


ProviderFn = Callable[[ProviderContext], Iterable[Measured]]


@dataclass(frozen=True)
class ProviderSpec:
    fn: ProviderFn
    scope: str
    measures: Mapping[str, str]  # name -> unit
    description: str


_PROVIDERS: dict[str, ProviderSpec] = {}


def provider(*, scope: str, measures: Mapping[str, str]) -> Callable[[ProviderFn], ProviderFn]:
    """Register ``fn`` as the provider of ``measures`` (name -> unit) at ``scope``."""
    if scope not in SCOPES:
        raise ValueError(f"unknown scope {scope!r}; expected one of {', '.join(SCOPES)}")

    def deco(fn: ProviderFn) -> ProviderFn:
        spec = ProviderSpec(fn, scope, dict(measures), (fn.__doc__ or "").strip().split("\n")[0])
        for name in measures:
            if name in _PROVIDERS and _PROVIDERS[name].fn is not fn:
                raise ValueError(f"measure {name!r} is provided twice")
            _PROVIDERS[name] = spec
        return fn

    return deco


def _load_builtin() -> None:
    import importlib
    import pkgutil

    from . import providers

    for info in sorted(pkgutil.iter_modules(providers.__path__), key=lambda i: i.name):
        importlib.import_module(f"{providers.__name__}.{info.name}")


def known_measures() -> dict[str, ProviderSpec]:
    _load_builtin()
    return dict(sorted(_PROVIDERS.items()))


def lookup(name: str) -> ProviderSpec | None:
    _load_builtin()
    return _PROVIDERS.get(name)


def measure_info(name: str) -> tuple[str, str] | None:
    """(scope, unit) of any measure a rule may name, or None if nobody provides it."""
    spec = lookup(name)
    if spec is not None:
        return spec.scope, spec.measures[name]
    if name.startswith("rollup."):
        return ROLLUP.get(name)
    from . import generic

    return generic.info(name)


#: Measures the evaluator computes itself in its second phase, from item verdicts.
ROLLUP: dict[str, tuple[str, str]] = {
    "rollup.image_rejected_share": ("delivery", "%"),
    "rollup.images_sampled_share": ("delivery", "%"),
    "rollup.block_rejected_share": ("project", "%"),
    "rollup.blocks_checked_share": ("project", "%"),
    "rollup.images_rejected": ("delivery", "1"),
    "rollup.blocks_rejected": ("project", "1"),
}


class UnknownMeasure(MeasureError, KeyError):
    """No provider supplies this measure (a profile naming it fails validation first)."""

    def __str__(self) -> str:
        return f"no provider for measure {self.args[0]!r}"


class MeasureCache:
    """Calls each provider at most once per run; remembers failures as per-measure errors."""

    def __init__(self, ctx: ProviderContext) -> None:
        self.ctx = ctx
        self._done: dict[int, dict[str, Measured] | Exception] = {}
        self._generic: dict[tuple[str, str], Measured | Exception] = {}

    def get(self, name: str) -> Measured:
        spec = lookup(name)
        if spec is None:
            from . import generic

            if generic.info(name) is None:
                raise UnknownMeasure(name)
            gkey = ("generic", name)
            if gkey not in self._generic:
                try:
                    self._generic[gkey] = generic.compute(name, self.ctx.delivery)
                except Exception as exc:
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
            except Exception as exc:  # a provider bug must not stop other rules
                self._done[key] = exc
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
