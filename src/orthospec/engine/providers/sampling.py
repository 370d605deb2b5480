"""Whether the external-QC sample in force was selected as JRC §12.4 says (automating JRC-12.4-SELECTION).

"Product files will be selected on a systematic basis to ensure that: QC is well distributed within the
block/site area; areas with different terrain relief and land cover will be included; areas where
problems are anticipated will be checked (e.g. known quality problems with specific batches of
original photos high view angles, etc)". The sample in force is the one ``check --sample`` gives (an
``orthospec sample`` table), else the images the delivery's ``sample`` column marks, else every image
(the whole delivery is checked).

* ``sample.strata_missed`` (delivery): strata the sample leaves out, named in the note: a block
  without a sampled image; a terrain / land-cover tag (``images.tags``) no sampled image carries; a
  problem batch (a block flagged ``problem_batch``, or an ``images.batch`` of that name) without a
  sampled image; images beyond the Table 8 view angle (``hr_view_angle_max``, "high view angles")
  of which none is sampled. A block sample (§12.8) is judged on the blocks' tags and problem flags.

The random part ("Additional blocks/images will also be selected on a random basis") cannot be told
from a list of ids; `orthospec sample` draws it and records each item's reason.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ...provenance import Evidence
from ..registry import Measured, ProviderContext, provider

NAME = "sample.strata_missed"


def _sample(ctx: ProviderContext, ids: list[str], marked: list[bool]) -> tuple[str, set[str], str]:
    """(scope, sampled ids, where the sample comes from)."""
    given = ctx.options.sample
    if given:
        return str(given[0]), set(map(str, given[1])), "the sample given with check --sample"
    if any(marked):
        return (
            "image",
            {i for i, m in zip(ids, marked, strict=True) if m},
            "images marked in the sample column",
        )
    return "image", set(ids), "no sample: every image is checked"


def _view_angles(ctx: ProviderContext, ids: list[str]) -> pd.Series:
    """The largest view angle the image's records give (images, scenes): a high angle in either makes
    it a problem area to sample."""
    d = ctx.delivery
    out = pd.Series(np.nan, index=ids, dtype=float)
    for table in ("images", "scenes"):
        t = d.table(table)
        if t is not None and "view_angle" in t.df:
            s = pd.Series(
                pd.to_numeric(t.df["view_angle"], errors="coerce").to_numpy(float),
                index=t.ids.astype(str).to_numpy(),
            )
            s = s[~s.index.duplicated()].reindex(ids).abs()
            out = pd.concat([out, s], axis=1).max(axis=1)
    return out


def strata_missed(ctx: ProviderContext) -> tuple[list[str], str, tuple[Evidence, ...]]:
    """(strata without a sampled item, wording of the sample, evidence)."""
    d = ctx.delivery
    imgs = d.table("images")
    blocks = d.manifest.blocks
    problem_blocks = {b.id for b in blocks if b.problem_batch}
    if imgs is None:
        return [], "no images table", (d.manifest_evidence("tables"),)
    df = imgs.df
    ids = imgs.ids.astype(str).tolist()
    marked = [v is True for v in df["sample"].tolist()] if "sample" in df else [False] * len(ids)
    scope, sampled, source = _sample(ctx, ids, marked)
    ev: tuple[Evidence, ...] = (imgs.evidence(df["_row"])[0], d.manifest_evidence("blocks"))
    missed: list[str] = []
    if scope == "block":
        for tag in sorted({t for b in blocks for t in b.tags}):
            if not any(tag in b.tags for b in blocks if b.id in sampled):
                missed.append(f"tag {tag!r}: no sampled block carries it")
        for b in sorted(problem_blocks - sampled):
            missed.append(f"problem block {b}: not sampled")
        return missed, f"{len(sampled)} of {len(blocks)} blocks ({source})", ev
    block_of = dict(zip(ids, df["block"].astype(str).tolist(), strict=True))
    for b in sorted(set(block_of.values())):
        if not any(block_of[i] == b for i in sampled if i in block_of):
            missed.append(f"block {b}: no image sampled")
    if "tags" in df:
        tags_of = {
            i: {t.strip() for t in str(v).split(";") if t.strip()} if v is not None else set()
            for i, v in zip(ids, df["tags"].tolist(), strict=True)
        }
        for tag in sorted(set().union(*tags_of.values()) if tags_of else set()):
            if not any(tag in tags_of[i] for i in sampled if i in tags_of):
                missed.append(f"tag {tag!r}: no sampled image carries it")
    batch_of = dict(zip(ids, df["batch"].tolist(), strict=True)) if "batch" in df else {}
    for b in sorted(problem_blocks):
        members = [i for i in ids if block_of.get(i) == b or str(batch_of.get(i)) == b]
        if members and not sampled & set(members):
            missed.append(f"problem batch {b}: none of its {len(members)} images sampled")
    limit = ctx.parameters.get("hr_view_angle_max")
    lim = (
        float(limit.to("degree").magnitude)
        if limit is not None and hasattr(limit, "to")
        else float(limit or 15.0)
    )
    views = _view_angles(ctx, ids)
    high = [i for i in ids if views.get(i, np.nan) > lim]
    if high and not sampled & set(high):
        missed.append(
            f"high view angles: none of the {len(high)} images beyond {lim:g} deg sampled"
        )
    return missed, f"{len(sampled & set(ids))} of {len(ids)} images ({source})", ev


@provider(scope="delivery", measures={NAME: "1"})
def sample_selection(ctx: ProviderContext) -> list[Measured]:
    """Strata of JRC §12.4 (blocks, terrain/land-cover tags, problem batches, high view angles) the
    sample in force leaves out."""
    d = ctx.delivery
    missed, what, ev = strata_missed(ctx)
    note = f"sample: {what}; " + (
        "every block, tag, problem batch and high view angle is represented"
        if not missed
        else "the checker must add: " + "; ".join(missed)
    )
    value: Any = float(len(missed))
    return [
        Measured(
            NAME,
            "delivery",
            "1",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]
