"""Work one run computes once and several providers read (issue 28): a typed key into the run's memo
(``ProviderContext.memo``), so every reader names one object, gets its declared type back, and no
two modules spell the same string key. No measure is registered here.

    FOOTPRINTS = Shared("image_footprints", lambda ctx: image_footprints(ctx.delivery))
    feet = FOOTPRINTS.get(ctx)  # computed by the first caller of the run, then the same object
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar, cast

from ..registry import ProviderContext

T = TypeVar("T")


@dataclass(frozen=True)
class Shared(Generic[T]):
    """One piece of shared work: ``compute(ctx)`` once per run, kept under ``key`` in ``ctx.memo``."""

    key: str
    compute: Callable[[ProviderContext], T]

    def get(self, ctx: ProviderContext) -> T:
        """The value of this run, computed on first use."""
        if self.key not in ctx.memo:
            ctx.memo[self.key] = self.compute(ctx)
        return cast(T, ctx.memo[self.key])
