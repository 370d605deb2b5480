"""What every phase of an evaluation reads: the profile, the delivery, the parameters in force,
the measure cache, the checker's file, and the integer verdict codes of the columnar results.

A rule's verdicts are an ``int8`` column (one code per item, ``orthospec.verdicts.CODE``) so that
the decision stays vectorised; :class:`RuleResult` is that columnar outcome of one rule.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .. import verdicts as V
from ..delivery.checker import Checker, stated_outlines
from ..delivery.convention import table_of_scope
from ..delivery.in_force import DeliveryInForce
from ..delivery.reader import Delivery
from ..errors import OrthospecError
from ..profile.loader import ResolvedProfile
from ..profile.models import Rule
from ..provenance import Evidence
from .catalog import MeasureCache
from .params import ParamValue
from .registry import EngineOptions, ProviderContext

PASS, FAIL, WARN, NA, MISSING, ERROR, WAIVED = (V.CODE[v] for v in (
    V.PASS, V.FAIL, V.WARN, V.NOT_APPLICABLE, V.MISSING, V.ERROR, V.WAIVED))
VERDICTS = V.VERDICTS
#: worst first, for a rule's overall verdict (as codes)
SEVERITY = tuple(V.CODE[v] for v in V.SEVERITY)


@dataclass
class RuleResult:
    """The columnar outcome of one rule over its items."""

    rule: Rule
    items: np.ndarray
    verdict: np.ndarray
    measured: np.ndarray
    unit: str
    threshold: dict[str, Any]
    evidence: Sequence[tuple[Evidence, ...]]
    notes: np.ndarray
    original: np.ndarray | None = None
    waivers: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: item -> the contractor's waiver request (delivery.yaml): evidence, never in force
    requested: dict[str, dict[str, Any]] = field(default_factory=dict)
    error: str | None = None
    #: the traceback of a rule that crashed, kept only under --debug (ORTHOSPEC_DEBUG=1)
    traceback: str | None = None
    #: per item, why it is not a pass (``orthospec.verdicts.Reason`` or None: the verdict's default)
    reasons: np.ndarray | None = None

    def reason(self, i: int) -> str | None:
        """The reason code of item ``i`` (None for a pass): the rule's own, else its verdict's default."""
        return V.reason_of(
            VERDICTS[int(self.verdict[i])], None if self.reasons is None else self.reasons[i]
        )

    @property
    def worst(self) -> int:
        present = set(self.verdict.tolist())
        for v in SEVERITY:
            if v in present:
                return v
        return NA

    def counts(self) -> dict[str, int]:
        bc = np.bincount(self.verdict.astype(np.int64), minlength=len(VERDICTS))
        return {VERDICTS[i]: int(bc[i]) for i in range(len(VERDICTS))}


def debug_enabled() -> bool:
    """`orthospec --debug` (cli/main.py sets ORTHOSPEC_DEBUG=1): keep tracebacks of crashing rules."""
    return os.environ.get("ORTHOSPEC_DEBUG") == "1"


@dataclass
class Context:
    """The inputs of one evaluation, shared by rules, manual rules, waivers and the roll-up."""

    profile: ResolvedProfile
    d: Delivery
    params: dict[str, ParamValue]
    options: EngineOptions
    checker: Checker | None
    cache: MeasureCache
    manifest: dict[str, Any]
    fail_on: str
    debug: bool
    #: the images were scanned before a verdict was bound to one (``file_sha256``)
    _scanned: bool = False

    @classmethod
    def build(
        cls,
        profile: ResolvedProfile,
        delivery: Delivery,
        parameters: dict[str, ParamValue],
        *,
        fail_on: str,
        options: EngineOptions | Mapping[str, Any] | None,
        checker: Checker | None,
        debug: bool | None,
    ) -> Context:
        opts = EngineOptions.of(options)
        # the delivery as this evaluation judges it: the checker's check points in force, nothing written onto
        # the opened delivery (issue 26: a next check of the same object starts clean)
        delivery = DeliveryInForce.of(delivery, checker)
        pctx = ProviderContext(
            delivery,
            {k: v.quantity() for k, v in parameters.items()},
            opts,
            classes=dict(getattr(profile, "classes", {}) or {}),
            checker=checker,
            outlines=stated_outlines(checker) if checker is not None else None,
            inspection=load_grid(checker, delivery) if checker is not None else None,
        )
        return cls(
            profile,
            delivery,
            parameters,
            opts,
            checker,
            MeasureCache(pctx),
            delivery.flat_manifest(),
            fail_on,
            debug_enabled() if debug is None else debug,
        )

    def file_sha256(self, rel: str) -> str | None:
        """SHA-256 of a delivered file now, None when the delivery does not hold it (or refuses the path).

        When the profile reads raster measures the images are scanned (and hashed in that one read) first,
        so binding a verdict to an image never reads the image a second time."""
        if not self._scanned:
            self._scanned = True
            if any(r.measure.startswith("raster.") for r in self.profile.rules):
                with contextlib.suppress(
                    Exception
                ):  # reported by the rules that read it; hashing follows
                    self.cache.get("raster.readable")
        try:
            p = self.d.path(rel)
        except OrthospecError:
            return None
        return self.d.sha256(rel) if p.is_file() else None

    def universe(self, scope: str) -> tuple[list[str] | None, str | None]:
        """The items a rule at ``scope`` must judge; None = take the measure's own items."""
        d = self.d
        if scope == "delivery":
            return [d.id], None
        if scope == "project":
            return [d.project_id], None
        if scope == "block":
            ids = d.block_ids
            return ids, None if ids else "the delivery declares no blocks"
        if scope == "edge":
            return [e.id for e in d.manifest.edge_targets], "the manifest lists no edge_targets"
        table = table_of_scope(scope)
        if table is None:
            return None, None
        t = d.table(table)
        if t is None:
            return [], f"the manifest declares no '{table}' table"
        return _item_ids(t), None

    def sample_mask(self, scope: str, items: list[str]) -> np.ndarray | None:
        """With `check --sample`, items of the sampled scope outside the sample are not checked."""
        sample = self.options.sample
        if not sample or sample[0] != scope:
            return None
        return np.isin(np.asarray(items, dtype=object), list(sample[1]))


def load_grid(checker: Checker, d: Delivery) -> Any:
    """The checker folder's marked inspection grid, read and checked now (bad input is exit 2 before any
    rule runs), or None when the folder has none."""
    from ..delivery.checker import INSPECTION_GRID

    p = checker.file(INSPECTION_GRID)
    if p is None:
        return None
    from ..inspection.grid import delivered_images, read_grid

    shown = f"{checker.folder}/{INSPECTION_GRID}" if checker.folder is not None else INSPECTION_GRID
    with_ids = _grid_image_ids(p, shown)
    return read_grid(p, display=shown, delivery_id=d.id, now=delivered_images(d, with_ids))


def _grid_image_ids(path: Any, shown: str) -> set[str]:
    """The image ids a grid names (its images layer), so only those images are opened and hashed."""
    from pyogrio import raw

    from ..raster.reading import gdal_errors, readable_vector

    with (
        readable_vector(path, name=shown) as (local, _),
        gdal_errors(file=shown, path=local, what="inspection grid"),
    ):
        try:
            _, _, _, values = raw.read(local, layer="images", columns=["image_id"])
        except Exception:  # no such layer: read_grid names what is missing
            return set()
    return {str(v) for v in values[0]} if values else set()


def _item_ids(t: Any) -> list[str]:
    """A table's item ids as a list of text: the parser's own string objects when the id column
    holds only text (``Table.ids`` converts to pandas' string dtype, and listing that builds a
    new object per id: 57 MB and a conversion per rule at a million check points)."""
    col = t.spec.id
    if col is not None and col in t.df and t.df[col].dtype == object:
        cells = t.df[col].to_numpy(dtype=object)
        if pd.api.types.infer_dtype(cells, skipna=False) == "string":
            return cells.tolist()
    return t.ids.tolist()
