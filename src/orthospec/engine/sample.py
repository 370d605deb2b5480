"""Draw the external-QC sample (JRC §12.4) from a delivery: images or blocks, reproducibly."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from shapely.geometry import Polygon

from ..delivery.convention import ColumnSpec, TableSpec
from ..delivery.reader import Delivery, parse_csv
from ..errors import DeliveryError, OrthospecError
from ..measures.sampling import Sample, select_sample

SAMPLE_SPEC = TableSpec(
    "sample", "delivery", "item", "External QC sample written by `orthospec sample`.",
    {
        "item": ColumnSpec("item", "text", None, True, "Selected image or block id."),
        "scope": ColumnSpec("scope", "text", None, True, "image or block."),
        "reason": ColumnSpec("reason", "text", None, False, "Why it was selected."),
        "seed": ColumnSpec("seed", "number", "1", False, "Seed of the draw."),
        "round": ColumnSpec("round", "number", "1", False, "Redelivery round."),
    },
)


@dataclass(frozen=True)
class DrawnSample:
    scope: str
    sample: Sample
    table: pd.DataFrame


def _image_centres(d: Delivery) -> tuple[list[str], np.ndarray, np.ndarray, pd.DataFrame]:
    """Each image's position: its exposure centre from the table, else its footprint's centre.

    The spread of the systematic part of the sample depends on these positions, so an image
    that cannot be read is an error naming it (never placed at an invented position).
    """
    t = d.require_table("images")
    df = t.df
    ids = t.ids.tolist()
    if {"exposure_x", "exposure_y"} <= set(df.columns) and df["exposure_x"].notna().all():
        return ids, df["exposure_x"].to_numpy(float), df["exposure_y"].to_numpy(float), df
    from ..raster.roi import raster_bounds

    xs, ys = [], []
    for i, f, row in zip(ids, df["file"].astype(str), df["_row"], strict=True):
        path = d.path(f, what="image file", file=t.file, row=int(row))
        try:
            left, bottom, right, top = raster_bounds(path, name=f)
        except OrthospecError as exc:
            raise DeliveryError(
                f"image {i} cannot be placed for the sample: {exc}; give its "
                "exposure_x / exposure_y in the images table or deliver a readable image",
                file=t.file,
                row=int(row),
            ) from None
        xs.append((left + right) / 2)
        ys.append((bottom + top) / 2)
    return ids, np.asarray(xs), np.asarray(ys), df


def draw(
    d: Delivery,
    *,
    scope: str = "image",
    seed: int,
    round: int = 0,
    fraction: float = 0.10,
    minimum: int = 1,
    random_share: float = 0.2,
    must_include: set[str] | frozenset[str] = frozenset(),
) -> DrawnSample:
    """Images (§12.3/§12.4) or blocks (§12.8) for external QC; same seed+round, same sample."""
    if scope == "image":
        ids, x, y, df = _image_centres(d)
        tags = df["tags"].fillna("").astype(str).tolist() if "tags" in df else None
        batches = df["batch"].fillna("").astype(str).tolist() if "batch" in df else None
        problem = sorted(
            {
                b
                for b in (batches or [])
                if b and any(blk.problem_batch and blk.id == b for blk in d.manifest.blocks)
            }
        )
    elif scope == "block":
        ids, xs, ys, tags = [], [], [], []
        for b in d.manifest.blocks:
            ids.append(b.id)
            if b.polygon and len(b.polygon) >= 3:
                c = Polygon(b.polygon).centroid
                xs.append(c.x)
                ys.append(c.y)
            else:
                xs.append(float(len(xs)))
                ys.append(0.0)
            tags.append(";".join(b.tags))
        if not ids:
            raise DeliveryError("the manifest declares no blocks to sample", file="delivery.yaml")
        x, y = np.asarray(xs), np.asarray(ys)
        batches = None
        problem = [b.id for b in d.manifest.blocks if b.problem_batch]
        batches = ids if problem else None
    else:
        raise DeliveryError(f"cannot sample scope {scope!r}; use image or block")
    s = select_sample(
        ids,
        x,
        y,
        seed=seed,
        round=round,
        fraction=fraction,
        minimum=minimum,
        tags=tags,
        batches=batches,
        problem_batches=problem,
        random_share=random_share,
    )
    extra = sorted(set(must_include) & set(map(str, ids)) - set(s.ids))
    if extra:  # tightened audit: every suspect item of the last checks is drawn again
        reasons = {**s.reasons, **dict.fromkeys(extra, "tightened audit trail")}
        s = Sample(tuple(sorted((*s.ids, *extra))), reasons, s.target, s.n_items, s.seed, s.round)
    table = pd.DataFrame(
        {
            "item": list(s.ids),
            "scope": scope,
            "reason": [s.reasons[i] for i in s.ids],
            "seed": seed,
            "round": round,
        }
    )
    return DrawnSample(scope, s, table)


def read_sample(path: str | Path) -> tuple[str, set[str]]:
    """A sample table written by `orthospec sample`: (scope, ids)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise DeliveryError(f"cannot read sample table: {exc.strerror}", file=str(path)) from None
    df = parse_csv(text, SAMPLE_SPEC, file=str(path))
    scopes = set(df["scope"].astype(str))
    if len(scopes) != 1 or not scopes <= {"image", "block"}:
        raise DeliveryError(
            f"a sample table holds one scope (image or block), found {sorted(scopes)}",
            file=str(path),
        )
    return scopes.pop(), set(df["item"].astype(str))
