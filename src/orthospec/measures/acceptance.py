"""Acceptance arithmetic of the external QC: project and image-delivery verdicts (the one
implementation; the evaluator's roll-up calls it).

JRC EUR 23638 EN:

* §12.7 (block verdicts, X and Y applied independently) is encoded as profile rules
  (JRC-12.7-RMSEX/-RMSEY, consequence reject_block); their failing blocks feed §12.8 here.
* §12.8: at least 10 % of blocks checked; "Should more than 5% of the blocks that are
  subjected to external QC fail, all products will be returned"; footnote 6: with space
  resection any failing block means redelivery.
* §12.3: at least 10 % of images sampled; "more than 5% of the images tested fail ... the
  entire delivery may be returned". The "may" is the ``returns`` argument: default True (the
  delivery is returned), because accepting a delivery with more than 5 % unusable images is the
  wrong acceptance an auditor cannot trust; a checker who uses the discretion passes False
  (profile parameter ``image_fail_share_action: keep``) and the failing images are reprocessed.

Vectorised: arrays in, arrays out; no NaN verdicts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import MeasureError

__all__ = [
    "DeliveryVerdict",
    "ProjectVerdict",
    "image_delivery_verdict",
    "project_verdict",
]


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
    returns: bool = True,
) -> DeliveryVerdict:
    """Delivery verdict from the failures among sampled images (JRC §12.3).

    ``sampled_failed`` is True for an image failing one or more Chapter 6 / §9.2 checks.
    ``returns`` is the "may" of §12.3 (see the module docstring): with False, exceeding the
    share is reported but the delivery is not returned.
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
    exceeded = frac_f > max_failed_fraction
    ret = exceeded and returns
    parts = [f"{n_s}/{n_images} images sampled ({frac_s:.1%})"]
    if not enough:
        parts.append(f"sample below the minimum {min_sample_fraction:.0%} (JRC §12.3)")
    parts.append(f"{n_f} failed ({frac_f:.1%} of sampled)")
    if ret:
        parts.append(f"more than {max_failed_fraction:.0%} failed: the entire delivery is "
                     "returned for quality checking and redelivery")
    elif exceeded:
        parts.append(
            f"more than {max_failed_fraction:.0%} failed; the checker used the discretion of "
            "§12.3 ('may be returned'): failing images are reprocessed"
        )
    elif n_f:
        parts.append("failing images are reprocessed until the specification is met")
    return DeliveryVerdict(
        n_images=n_images,
        n_sampled=n_s,
        sampled_fraction=frac_s,
        sample_sufficient=bool(enough),
        n_failed=n_f,
        failed_fraction=frac_f,
        return_delivery=bool(ret),
        reprocess=tuple(ids[failed].tolist()),
        reason="; ".join(parts),
    )
