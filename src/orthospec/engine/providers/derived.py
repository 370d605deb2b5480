"""Facts the engine computes from the delivery's data rather than trusting a declared flag.

* ``derived.orthorectification`` (delivery): ``space_resection`` when any block of the manifest
  was produced by space resection (or the manifest says so), else the declared or block method.
  JRC §12.8 footnote 6 ("For projects where space resection has been used in the production of
  individual orthophotos should any block fail, the dataset will be subject to redelivery") keys
  on it; the manifest's ``product.orthorectification`` alone is a flag the contractor may omit.
* ``derived.resolution_class`` (image): the JRC §9.1 class of each scene from its pixel size
  (``scenes.input_pixel_size``, else ``images.acquisition_gsd``, else ``images.gsd``) and the
  profile's ``classes: resolution``; the contractor's own label (``scenes.resolution_class``) is
  checked against it by ``derived.resolution_class_agrees``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ...measures.classes import classify
from ...units import convert
from ..registry import Measured, ProviderContext, RowEvidence, provider

DELIVERY = {"derived.orthorectification": "text"}
IMAGE = {"derived.resolution_class": "text", "derived.resolution_class_agrees": "bool"}


def _norm(v: Any) -> str | None:
    if v is None:
        return None
    t = str(v).strip().lower().replace(" ", "_").replace("-", "_")
    return t or None


@provider(scope="delivery", measures=DELIVERY)
def orthorectification(ctx: ProviderContext) -> list[Measured]:
    """How the orthoimages were produced, from the blocks' methods and the manifest."""
    d = ctx.delivery
    methods = {b.id: _norm(b.method) for b in d.manifest.blocks}
    declared = _norm(getattr(d.manifest.product, "orthorectification", None))
    sr = sorted(b for b, m in methods.items() if m == "space_resection")
    ev = (d.manifest_evidence("blocks"), d.manifest_evidence("product.orthorectification"))
    note = None
    if sr:
        value: str | None = "space_resection"
        note = f"block(s) {', '.join(sr)} produced by space resection (blocks[].method)"
    elif declared:
        value = declared
        note = "declared in delivery.yaml product.orthorectification"
    else:
        known = sorted({m for m in methods.values() if m})
        value = known[0] if len(known) == 1 else None
        note = (f"blocks[].method: {known[0]}" if len(known) == 1 else
                "delivery.yaml gives no product.orthorectification and the blocks' methods "
                + ("disagree (" + ", ".join(known) + ")" if known else "are not given"))
    return [Measured("derived.orthorectification", "delivery", "text", pd.Series({d.id: value}, dtype=object),
                     pd.Series({d.id: ev}, dtype=object), notes=pd.Series({d.id: note}, dtype=object))]


def _pixel_sizes(ctx: ProviderContext) -> tuple[pd.Series, dict[str, str], Any]:
    """Per image: pixel size in m, which column it came from, and the row evidence."""
    d = ctx.delivery
    imgs = d.table("images")
    scenes = d.table("scenes")
    ids: list[str] = imgs.ids.astype(str).tolist() if imgs is not None else []
    if scenes is not None:
        ids = sorted(set(ids) | set(scenes.ids.astype(str).tolist()))
    size = pd.Series(np.nan, index=ids, dtype=float)
    source: dict[str, str] = {}
    candidates = [(scenes, "input_pixel_size"), (imgs, "acquisition_gsd"), (imgs, "gsd")]
    for t, col in candidates:
        if t is None or col not in t.df:
            continue
        unit = t.units.get(col, "m") if hasattr(t, "units") else "m"
        vals = pd.to_numeric(t.df[col], errors="coerce").to_numpy(dtype=float)
        vals = convert(vals, unit, "m")
        s = pd.Series(vals, index=t.ids.astype(str).to_numpy())
        s = s[~s.index.duplicated()]
        fill = size.isna() & s.reindex(size.index).notna()
        for i in size.index[fill]:
            source[i] = f"{t.file} {col}"
        size[fill] = s.reindex(size.index)[fill]
    base = scenes if scenes is not None else imgs
    ev = (RowEvidence(base.file, base.sha256, pd.Series(base.df["_row"].to_numpy(),
                                                        index=base.ids.astype(str).to_numpy()))
          if base is not None else None)
    return size, source, ev


@provider(scope="image", measures=IMAGE)
def resolution_class(ctx: ProviderContext) -> list[Measured]:
    """JRC §9.1 resolution class per image from its pixel size and the profile's classes."""
    d = ctx.delivery
    cset = ctx.classes.get("resolution")
    size, source, ev = _pixel_sizes(ctx)
    items = size.index.tolist()
    evidence: Any = ev if ev is not None else pd.Series({i: () for i in items}, dtype=object)
    if cset is None or not items:
        why = ("the profile defines no `classes: resolution`" if cset is None
               else "the delivery has no images or scenes table")
        notes = pd.Series({i: why for i in items}, dtype=object)
        empty = pd.Series({i: None for i in items}, dtype=object)
        return [Measured(n, "image", u, empty.copy(), evidence, notes=notes) for n, u in IMAGE.items()]
    unit = cset["unit"] if isinstance(cset, dict) else cset.unit
    class_items = cset["items"] if isinstance(cset, dict) else cset.items
    in_unit = convert(size.to_numpy(dtype=float), "m", unit)
    classes = classify(in_unit, class_items)
    cls = pd.Series(classes, index=items, dtype=object)
    notes = {}
    for i, c, v in zip(items, classes, in_unit, strict=True):
        if np.isnan(v):
            notes[i] = "no pixel size (scenes.input_pixel_size, images.acquisition_gsd or images.gsd)"
        elif c is None:
            notes[i] = f"pixel size {v:.4g} {unit} falls in no class of `classes: resolution` (a gap of §9.1)"
        else:
            notes[i] = f"pixel size {v:.4g} {unit} ({source.get(i, '?')}) -> {c}"
    declared = pd.Series({i: None for i in items}, dtype=object)
    scenes = d.table("scenes")
    if scenes is not None and "resolution_class" in scenes.df:
        decl = pd.Series(scenes.df["resolution_class"].to_numpy(), index=scenes.ids.astype(str).to_numpy())
        declared = decl[~decl.index.duplicated()].reindex(items)
    agrees: dict[str, Any] = {}
    na: dict[str, str] = {}
    for i in items:
        dv = declared.get(i)
        if dv is None or (isinstance(dv, float) and np.isnan(dv)) or not str(dv).strip():
            na[i] = "the contractor declares no resolution class for this scene"
            agrees[i] = None
        elif cls[i] is None:
            agrees[i] = None
        else:
            agrees[i] = str(dv).strip().upper() == str(cls[i]).upper()
    return [
        Measured("derived.resolution_class", "image", "text", cls, evidence,
                 notes=pd.Series(notes, dtype=object)),
        Measured("derived.resolution_class_agrees", "image", "bool", pd.Series(agrees, dtype=object), evidence,
                 notes=pd.Series({i: f"declared {declared.get(i)!s}, computed {cls[i]!s}" for i in items
                                  if i not in na}, dtype=object),
                 na=pd.Series(na, dtype=object) if na else None),
    ]
