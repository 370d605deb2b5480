"""The pixel size of each image as measured from its file, and the JRC §9.1 resolution class read
from it.

* ``derived.resolution_class`` (image): the JRC §9.1 class of each scene from its pixel size (the
  delivered file's, or ``scenes.input_pixel_size`` when finer; without a readable file
  ``scenes.input_pixel_size``, else ``images.acquisition_gsd``, else ``images.gsd``) and the
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
from .cells import table_metres as _table_metres

IMAGE = {"derived.resolution_class": "text", "derived.resolution_class_agrees": "bool"}


def measured_pixel_m(ctx: ProviderContext) -> dict[str, float]:
    """Per image id: the coarser axis of its delivered file's pixel, in metres (the one reading of
    the files, raster/facts.py, through the run's scan); images whose file is absent, unreadable or
    not in a length unit are left out (their own raster rules report them)."""
    from .rasters import scanned

    got = scanned(ctx)
    if "missing" in got:
        return {}
    out = {}
    for i, f in got["facts"].items():
        size = f.pixel_size_m
        if size is not None and i not in got["errors"]:
            out[str(i)] = float(max(size))
    return out


def _pixel_sizes(ctx: ProviderContext) -> tuple[pd.Series, dict[str, str], Any]:
    """Per image: the pixel size its §9.1 class is read from, in m, where it came from, and the row
    evidence.

    Measured, not declared (issue 25): the delivered file's own pixel (its geotransform) decides, or
    the scene's input pixel (``scenes.input_pixel_size``) when that is finer: the class is the
    finest the evidence shows, so declaring a coarser input pixel (4 m for a 0.5 m raster) cannot
    move a VHR scene into a class with fewer obligations. Without a readable file the declared
    columns are used, in order: ``scenes.input_pixel_size``, ``images.acquisition_gsd``,
    ``images.gsd``."""
    d = ctx.delivery
    imgs = d.table("images")
    scenes = d.table("scenes")
    ids: list[str] = imgs.ids.astype(str).tolist() if imgs is not None else []
    if scenes is not None:
        ids = sorted(set(ids) | set(scenes.ids.astype(str).tolist()))
    size = pd.Series(np.nan, index=ids, dtype=float)
    source: dict[str, str] = {}
    measured = measured_pixel_m(ctx) if imgs is not None else {}
    if scenes is not None and "input_pixel_size" in scenes.df:
        inp = _table_metres(scenes, "input_pixel_size")
    else:
        inp = pd.Series(dtype=float)
    for i in ids:
        if i not in measured:
            continue
        size[i] = measured[i]
        source[i] = f"the file's pixel, {measured[i]:.4g} m"
        v = inp.get(i)
        if v is not None and np.isfinite(v) and v < measured[i]:
            size[i] = float(v)
            source[i] = (
                f"scenes.input_pixel_size {v:.4g} m, finer than the file's pixel {measured[i]:.4g} "
                "m"
            )
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
            source[i] = f"{t.file} {col}, declared: the file's pixel is unknown"
        size[fill] = s.reindex(size.index)[fill]
    base = scenes if scenes is not None else imgs
    ev = (
        RowEvidence(
            base.file,
            base.sha256,
            pd.Series(base.df["_row"].to_numpy(), index=base.ids.astype(str).to_numpy()),
        )
        if base is not None
        else None
    )
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
        why = (
            "the profile defines no `classes: resolution`"
            if cset is None
            else "the delivery has no images or scenes table"
        )
        notes = pd.Series({i: why for i in items}, dtype=object)
        empty = pd.Series({i: None for i in items}, dtype=object)
        return [
            Measured(n, "image", u, empty.copy(), evidence, notes=notes) for n, u in IMAGE.items()
        ]
    unit = cset["unit"] if isinstance(cset, dict) else cset.unit
    class_items = cset["items"] if isinstance(cset, dict) else cset.items
    in_unit = convert(size.to_numpy(dtype=float), "m", unit)
    classes = classify(in_unit, class_items)
    cls = pd.Series(classes, index=items, dtype=object)
    class_notes: dict[str, str] = {}
    for i, c, v in zip(items, classes, in_unit, strict=True):
        if np.isnan(v):
            class_notes[i] = (
                "no pixel size (scenes.input_pixel_size, images.acquisition_gsd or images.gsd)"
            )
        elif c is None:
            class_notes[i] = (
                f"pixel size {v:.4g} {unit} falls in no class of `classes: resolution` (a gap of "
                "§9.1)"
            )
        else:
            class_notes[i] = f"pixel size {v:.4g} {unit} ({source.get(i, '?')}) -> {c}"
    declared = pd.Series({i: None for i in items}, dtype=object)
    scenes = d.table("scenes")
    if scenes is not None and "resolution_class" in scenes.df:
        decl = pd.Series(
            scenes.df["resolution_class"].to_numpy(), index=scenes.ids.astype(str).to_numpy()
        )
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
        Measured(
            "derived.resolution_class",
            "image",
            "text",
            cls,
            evidence,
            notes=pd.Series(class_notes, dtype=object),
        ),
        Measured(
            "derived.resolution_class_agrees",
            "image",
            "bool",
            pd.Series(agrees, dtype=object),
            evidence,
            notes=pd.Series(
                {
                    i: f"declared {declared.get(i)!s}, computed {cls[i]!s}"
                    for i in items
                    if i not in na
                },
                dtype=object,
            ),
            na=pd.Series(na, dtype=object) if na else None,
        ),
    ]
