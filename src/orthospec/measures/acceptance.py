"""Acceptance arithmetic of the external QC: block, project and image-delivery verdicts.

JRC EUR 23638 EN:

* §12.7: "The planimetric threshold will be applied independently in X, and Y. Failure to
  meet the specification in either of these two dimensions (i.e. RMSEx or RMSEy) will reject
  the block." The DEM is checked with the Z tolerance. A result is *marginal* when "just
  below or above the tolerance": here within ``margin`` (a fraction of the tolerance) on
  either side.
* §12.8: at least 10 % of blocks checked; "Should more than 5% of the blocks that are
  subjected to external QC fail, all products will be returned"; footnote 6: with space
  resection any failing block means redelivery.
* §12.3: at least 10 % of images sampled; "more than 5% of the images tested fail ... the
  entire delivery may be returned".

A block *passes* when ``RMSE <= tolerance`` ("should this exceed the project specification,
all products ... will be rejected"). Vectorised: arrays in, arrays out; no NaN verdicts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import MeasureError

__all__ = [
    "BlockVerdicts",
    "DeliveryVerdict",
    "ProjectVerdict",
    "block_verdicts",
    "image_delivery_verdict",
    "project_verdict",
]


@dataclass(frozen=True)
class BlockVerdicts:
    """Per-block verdicts; every array has one entry per block, in input order."""

    block_ids: np.ndarray = field(compare=False)
    pass_x: np.ndarray = field(compare=False)
    pass_y: np.ndarray = field(compare=False)
    pass_z: np.ndarray | None = field(compare=False)  # None when no DEM is checked
    passed: np.ndarray = field(compare=False)
    marginal: np.ndarray = field(compare=False)
    reasons: np.ndarray = field(compare=False)  # str per block

    @property
    def failed_ids(self) -> tuple[str, ...]:
        return tuple(self.block_ids[~self.passed].tolist())

    @property
    def marginal_ids(self) -> tuple[str, ...]:
        return tuple(self.block_ids[self.marginal].tolist())


def _arr(name: str, v: Any, n: int | None, ids: np.ndarray | None = None) -> np.ndarray:
    a = np.atleast_1d(np.asarray(v, dtype=float))
    if n is not None:
        try:
            a = np.broadcast_to(a, (n,)).copy()
        except ValueError:
            raise MeasureError(f"{name} has {a.size} values for {n} blocks") from None
    bad = ~np.isfinite(a)
    if bad.any():
        who = ids[bad][:20].tolist() if ids is not None and ids.size == a.size else \
            np.flatnonzero(bad)[:20].tolist()
        raise MeasureError(f"{name} is not a finite number for block(s) {', '.join(map(str, who))}")
    return a


def block_verdicts(
    rmse_x: Any,
    rmse_y: Any,
    rmse_z: Any = None,
    *,
    tolerance_xy: Any,
    tolerance_z: Any = None,
    margin: float = 0.1,
    block_ids: Sequence[Any] | np.ndarray | None = None,
    unit: str = "m",
) -> BlockVerdicts:
    """Block verdicts of JRC §12.7, X and Y (and Z for DEMs) applied independently.

    ``tolerance_xy``/``tolerance_z`` are scalars or one per block. ``marginal`` is True when
    any checked axis lies within ``margin × tolerance`` of its tolerance, either side.

    Raises
    ------
    MeasureError
        Non-finite or negative RMSE, non-positive tolerance, mismatched lengths, ``rmse_z``
        without ``tolerance_z``.
    """
    rx0 = np.atleast_1d(np.asarray(rmse_x, dtype=float))
    n = rx0.size
    ids = np.asarray([str(b) for b in block_ids], dtype=object) if block_ids is not None else \
        np.asarray([str(i) for i in range(n)], dtype=object)
    if ids.size != n:
        raise MeasureError(f"{ids.size} block ids for {n} blocks")
    rx = _arr("rmse_x", rx0, n, ids)
    ry = _arr("rmse_y", rmse_y, n, ids)
    tol = _arr("tolerance_xy", tolerance_xy, n, ids)
    if (tol <= 0).any():
        raise MeasureError("tolerance_xy must be positive")
    if (rx < 0).any() or (ry < 0).any():
        raise MeasureError("an RMSE cannot be negative")
    if not (0 <= margin < 1):
        raise MeasureError(f"margin is a fraction of the tolerance in [0, 1), got {margin}")
    px, py = rx <= tol, ry <= tol
    marginal = (np.abs(rx - tol) <= margin * tol) | (np.abs(ry - tol) <= margin * tol)
    pz = None
    rz = tz = None
    if rmse_z is not None:
        if tolerance_z is None:
            raise MeasureError("rmse_z given without tolerance_z (the DEM's Z threshold)")
        rz = _arr("rmse_z", rmse_z, n, ids)
        tz = _arr("tolerance_z", tolerance_z, n, ids)
        if (tz <= 0).any():
            raise MeasureError("tolerance_z must be positive")
        pz = rz <= tz
        marginal |= np.abs(rz - tz) <= margin * tz
    passed = px & py if pz is None else px & py & pz

    reasons = []
    for i in range(n):
        parts = [
            f"RMSE_x {rx[i]:.4g} {'<=' if px[i] else '>'} {tol[i]:.4g} {unit}",
            f"RMSE_y {ry[i]:.4g} {'<=' if py[i] else '>'} {tol[i]:.4g} {unit}",
        ]
        if pz is not None and rz is not None and tz is not None:
            parts.append(f"RMSE_z {rz[i]:.4g} {'<=' if pz[i] else '>'} {tz[i]:.4g} {unit}")
        text = ("pass: " if passed[i] else "fail (all products of the block rejected): ") + \
            "; ".join(parts)
        if marginal[i]:
            text += (f"; marginal (within {margin:.0%} of the tolerance): further checks may be "
                     "needed (JRC §12.7)")
        reasons.append(text)
    return BlockVerdicts(
        block_ids=ids, pass_x=px, pass_y=py, pass_z=pz, passed=passed, marginal=marginal,
        reasons=np.asarray(reasons, dtype=object),
    )


@dataclass(frozen=True)
class ProjectVerdict:
    """Project-level result of JRC §12.8."""

    n_blocks: int
    n_checked: int
    checked_fraction: float
    sample_sufficient: bool
    n_failed: int
    failed_fraction: float
    return_all: bool
    redeliver: tuple[str, ...]  # failing blocks: examined, corrected and redelivered
    reason: str


def project_verdict(
    n_blocks: int,
    checked_passed: Any,
    *,
    checked_ids: Sequence[Any] | np.ndarray | None = None,
    min_checked_fraction: float = 0.10,
    max_failed_fraction: float = 0.05,
    space_resection: bool = False,
) -> ProjectVerdict:
    """Project verdict from the pass/fail of the externally checked blocks (JRC §12.8).

    ``return_all`` is True when more than ``max_failed_fraction`` of the checked blocks
    fail, or (``space_resection``, footnote 6) when any block fails. An insufficient sample
    (< ``min_checked_fraction`` of ``n_blocks``) is reported, never silently passed.
    """
    passed = np.atleast_1d(np.asarray(checked_passed, dtype=bool))
    n_checked = int(passed.size)
    if n_blocks < 1 or n_checked > n_blocks:
        raise MeasureError(f"{n_checked} checked blocks out of {n_blocks}: impossible")
    if n_checked == 0:
        raise MeasureError("no block was checked: the project verdict needs checked blocks")
    ids = np.asarray([str(b) for b in checked_ids], dtype=object) if checked_ids is not None \
        else np.asarray([str(i) for i in range(n_checked)], dtype=object)
    if ids.size != n_checked:
        raise MeasureError(f"{ids.size} block ids for {n_checked} checked blocks")
    frac_checked = n_checked / n_blocks
    enough = frac_checked >= min_checked_fraction - 1e-12
    n_failed = int((~passed).sum())
    frac_failed = n_failed / n_checked
    ret = frac_failed > max_failed_fraction or (space_resection and n_failed > 0)
    parts = [f"{n_checked}/{n_blocks} blocks checked ({frac_checked:.1%})"]
    if not enough:
        parts.append(f"sample below the minimum {min_checked_fraction:.0%} (JRC §12.8)")
    parts.append(f"{n_failed} failed ({frac_failed:.1%} of checked)")
    if ret:
        why = "space resection: any failing block" if space_resection and \
            frac_failed <= max_failed_fraction else f"more than {max_failed_fraction:.0%} failed"
        parts.append(f"{why}: all products returned to the contractor for further QA")
    elif n_failed:
        parts.append("failing blocks are corrected and redelivered")
    return ProjectVerdict(
        n_blocks=n_blocks, n_checked=n_checked, checked_fraction=frac_checked,
        sample_sufficient=bool(enough), n_failed=n_failed, failed_fraction=frac_failed,
        return_all=bool(ret), redeliver=tuple(ids[~passed].tolist()), reason="; ".join(parts),
    )


@dataclass(frozen=True)
class DeliveryVerdict:
    """Image-delivery result of JRC §12.3."""

    n_images: int
    n_sampled: int
    sampled_fraction: float
    sample_sufficient: bool
    n_failed: int
    failed_fraction: float
    return_delivery: bool
    reprocess: tuple[str, ...]
    reason: str


def image_delivery_verdict(
    n_images: int,
    sampled_failed: Any,
    *,
    sampled_ids: Sequence[Any] | np.ndarray | None = None,
    min_sample_fraction: float = 0.10,
    max_failed_fraction: float = 0.05,
) -> DeliveryVerdict:
    """Delivery verdict from the failures among sampled images (JRC §12.3).

    ``sampled_failed`` is True for an image failing one or more Chapter 6 / §9.2 checks.
    """
    failed = np.atleast_1d(np.asarray(sampled_failed, dtype=bool))
    n_s = int(failed.size)
    if n_images < 1 or n_s > n_images or n_s == 0:
        raise MeasureError(f"{n_s} sampled images out of {n_images}: impossible or empty sample")
    ids = np.asarray([str(b) for b in sampled_ids], dtype=object) if sampled_ids is not None \
        else np.asarray([str(i) for i in range(n_s)], dtype=object)
    if ids.size != n_s:
        raise MeasureError(f"{ids.size} image ids for {n_s} sampled images")
    frac_s = n_s / n_images
    enough = frac_s >= min_sample_fraction - 1e-12
    n_f = int(failed.sum())
    frac_f = n_f / n_s
    ret = frac_f > max_failed_fraction
    parts = [f"{n_s}/{n_images} images sampled ({frac_s:.1%})"]
    if not enough:
        parts.append(f"sample below the minimum {min_sample_fraction:.0%} (JRC §12.3)")
    parts.append(f"{n_f} failed ({frac_f:.1%} of sampled)")
    if ret:
        parts.append(f"more than {max_failed_fraction:.0%} failed: the entire delivery may be "
                     "returned for quality checking and redelivery")
    elif n_f:
        parts.append("failing images are reprocessed until the specification is met")
    return DeliveryVerdict(
        n_images=n_images, n_sampled=n_s, sampled_fraction=frac_s, sample_sufficient=bool(enough),
        n_failed=n_f, failed_fraction=frac_f, return_delivery=bool(ret),
        reprocess=tuple(ids[failed].tolist()), reason="; ".join(parts),
    )

