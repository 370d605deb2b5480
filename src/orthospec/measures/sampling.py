"""Reproducible selection of images/blocks for external QC (JRC EUR 23638 EN §12.4).

"Generally around 5-10% of orthoimage files will be checked externally. Product files will be
selected on a systematic basis to ensure that: QC is well distributed within the block/site
area; areas with different terrain relief and land cover will be included; areas where
problems are anticipated will be checked ... Additional blocks/images will also be selected on
a random basis." §12.8: redelivery is followed by a check "on a new sample (which may include
the existing data acquired for external QC)".

Algorithm (deterministic for a given ``seed`` and ``round``; independent of input order
because items are first sorted by id):

1. target size ``k = max(minimum, ceil(fraction·N))`` (capped at N);
2. every item of a flagged problem batch ("problem batch");
3. one random item for each terrain/land-cover tag not yet represented ("tag");
4. systematic spread: item centres binned on a g x g grid over their bounding box, grid cells
   visited in serpentine (boustrophedon) order, ``k_sys`` cells taken at even steps along
   that order, one random item per cell ("systematic");
5. the rest, at least ``random_share·k``, drawn uniformly from what is left ("random").

The sample can exceed ``k`` when problem batches and tags alone need more.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import MeasureError

__all__ = ["Sample", "select_sample"]


@dataclass(frozen=True)
class Sample:
    """Selected item ids (sorted) with the reason each was selected."""

    ids: tuple[str, ...]
    reasons: dict[str, str]
    target: int
    n_items: int
    seed: int
    round: int

    @property
    def fraction(self) -> float:
        return len(self.ids) / self.n_items


def _rng(seed: int, round_: int) -> np.random.Generator:
    salt = int.from_bytes(hashlib.sha256(f"orthospec-sample-round-{round_}".encode()).digest()[:8],
                          "big")
    return np.random.default_rng(np.random.SeedSequence([int(seed), salt]))


def select_sample(
    ids: Sequence[Any] | np.ndarray,
    x: Any,
    y: Any,
    *,
    seed: int,
    round: int = 0,  # the redelivery round (shadows the builtin on purpose)
    fraction: float = 0.10,
    minimum: int = 1,
    tags: Sequence[Any] | np.ndarray | None = None,
    batches: Sequence[Any] | np.ndarray | None = None,
    problem_batches: Collection[Any] = (),
    random_share: float = 0.2,
) -> Sample:
    """Select items for external QC (see module docstring for the algorithm).

    Parameters
    ----------
    ids, x, y
        Item ids and centre coordinates (image centres or block centroids).
    seed, round
        Reproducibility: the same seed and round give the same sample; a redelivery uses
        ``round + 1`` and draws a new sample that may include earlier items.
    tags
        Terrain/land-cover tag per item (None or "" = untagged); every tag is represented.
    batches, problem_batches
        Batch per item (e.g. film roll, acquisition) and the batches with known problems:
        all their items are selected.

    Raises
    ------
    MeasureError
        Empty input, duplicate ids, non-finite centres, bad fraction or lengths.
    """
    id_arr = np.asarray([str(i) for i in ids], dtype=object)
    n = id_arr.size
    if n == 0:
        raise MeasureError("no items to sample from")
    ax, ay = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if ax.shape != (n,) or ay.shape != (n,):
        raise MeasureError(f"x and y must have one value per item ({n})")
    uniq, counts = np.unique(id_arr.astype(str), return_counts=True)
    if (counts > 1).any():
        raise MeasureError(f"duplicate item ids: {', '.join(uniq[counts > 1][:20])}")
    bad = ~(np.isfinite(ax) & np.isfinite(ay))
    if bad.any():
        raise MeasureError(f"non-finite centre for item(s) {', '.join(id_arr[bad][:20])}")
    if not (0 < fraction <= 1):
        raise MeasureError(f"sample fraction must be in (0, 1], got {fraction}")
    if not (0 <= random_share <= 1):
        raise MeasureError(f"random_share must be in [0, 1], got {random_share}")

    def _opt(name: str, v: Any) -> np.ndarray | None:
        if v is None:
            return None
        a = np.asarray(["" if t is None else str(t) for t in v], dtype=object)
        if a.size != n:
            raise MeasureError(f"{name} must have one value per item ({n})")
        return a

    tag_arr, batch_arr = _opt("tags", tags), _opt("batches", batches)

    order = np.argsort(id_arr.astype(str), kind="stable")
    id_arr, ax, ay = id_arr[order], ax[order], ay[order]
    tag_arr = None if tag_arr is None else tag_arr[order]
    batch_arr = None if batch_arr is None else batch_arr[order]

    rng = _rng(seed, round)
    target = min(n, max(int(minimum), math.ceil(fraction * n - 1e-9)))
    chosen: dict[int, str] = {}

    # 2. problem batches
    if problem_batches:
        if batch_arr is None:
            raise MeasureError("problem_batches given without a batch per item")
        flagged = {str(b) for b in problem_batches}
        for i in np.flatnonzero(np.isin(batch_arr.astype(str), list(flagged))):
            chosen[int(i)] = f"problem batch {batch_arr[i]}"

    # 3. tags
    if tag_arr is not None:
        for tag in sorted({t for t in tag_arr.tolist() if t}):
            members = np.flatnonzero(tag_arr == tag)
            if not any(int(i) in chosen for i in members):
                pick = int(rng.choice(members))
                chosen[pick] = f"tag {tag}"

    # 4. systematic spread
    n_random = max(0, target - len(chosen))
    n_sys = n_random - math.ceil(random_share * n_random) if n_random > 1 else n_random
    if n_sys > 0:
        g = max(1, math.ceil(math.sqrt(n_sys)))
        cells = _cells(ax, ay, g)
        serp = _serpentine_key(cells, g)
        occupied = np.unique(serp)
        # systematic sampling with a random start along the serpentine order of cells
        start = float(rng.random())
        pos = np.floor((np.arange(n_sys) + start) * occupied.size / n_sys).astype(int)
        for cell in occupied[np.unique(np.minimum(pos, occupied.size - 1))]:
            free = [int(i) for i in np.flatnonzero(serp == cell) if int(i) not in chosen]
            if free:
                chosen[int(rng.choice(free))] = "systematic"

    # 5. random remainder
    left = np.array([i for i in range(n) if i not in chosen], dtype=int)
    need = max(0, target - len(chosen))
    if need and left.size:
        for i in rng.choice(left, size=min(need, left.size), replace=False):
            chosen[int(i)] = "random"

    sel = sorted(chosen)
    return Sample(
        ids=tuple(id_arr[sel].tolist()),
        reasons={str(id_arr[i]): chosen[i] for i in sel},
        target=target, n_items=n, seed=int(seed), round=int(round),
    )


def _cells(x: np.ndarray, y: np.ndarray, g: int) -> tuple[np.ndarray, np.ndarray]:
    def binned(v: np.ndarray) -> np.ndarray:
        lo, hi = float(v.min()), float(v.max())
        if hi == lo:
            return np.zeros(v.size, dtype=int)
        return np.minimum(((v - lo) / (hi - lo) * g).astype(int), g - 1)

    return binned(x), binned(y)


def _serpentine_key(cells: tuple[np.ndarray, np.ndarray], g: int) -> np.ndarray:
    cx, cy = cells
    col = np.where(cy % 2 == 0, cx, g - 1 - cx)
    return cy * g + col
