"""Satellite scene facts counted from the delivery's data, not taken from the meta-database (JRC Table 9).

The Table 9 GCP minimums used to read ``scenes.gcp_count``, the contractor's own number: a scene
refined on one GCP passed with ``gcp_count: 4`` (issue 26 "Satellite GCP counts are the
contractor's scenes.gcp_count, not counted from gcps.csv"). Here the GCP file decides:

* ``scene.gcp_count`` (image): the GCP rows of ``gcps.csv`` that controlled the scene: those whose
  ``image_id`` lists it (';'-separated), and, for rows that name no scene, those inside the scene's
  delivered orthoimage footprint (read from the raster). Missing when the delivery has no GCP table.
* ``scene.gcp_count_agrees`` (image): the meta-database's ``scenes.gcp_count`` (§9.5 "Number of
  GCPs", a declaration) equals the count; not applicable where none is declared.
* ``scene.area`` (image): area of the scene's orthoimage footprint in km² (from the raster).
* ``scene.gcp_strip_supplement`` (image): the strip supplement of Table 9, "plus 2 per additional
  100km² of strip scene": ``per_area`` GCPs for each started ``base_area`` beyond the first (both
  parameters, ``gcp_strip_per_area`` 2 and ``gcp_strip_area`` 100 km²).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ...errors import OrthospecError
from ...provenance import Evidence
from ...raster.roi import raster_bounds
from ...units import convert
from ..registry import Measured, ProviderContext, provider

MEASURES = {"scene.gcp_count": "1", "scene.gcp_count_agrees": "bool", "scene.area": "km²",
            "scene.gcp_strip_supplement": "1"}


def strip_supplement(area_km2: float, *, base_area_km2: float = 100.0, per_area: float = 2.0) -> float:
    """Extra GCPs for a strip of ``area_km2``: ``per_area`` for each started ``base_area_km2`` beyond
    the first (Table 9 "plus 2 per additional 100km² of strip scene")."""
    if not math.isfinite(area_km2) or area_km2 <= base_area_km2:
        return 0.0
    return per_area * math.ceil((area_km2 - base_area_km2) / base_area_km2 - 1e-9)


def footprints(ctx: ProviderContext) -> dict[str, tuple[tuple[float, float, float, float] | None, str | None]]:
    """Image id -> (left, bottom, right, top) of its delivered raster, or (None, why); once per run."""
    if "scene.footprints" in ctx.memo:
        return ctx.memo["scene.footprints"]  # type: ignore[no-any-return]
    d = ctx.delivery
    out: dict[str, tuple[Any, str | None]] = {}
    imgs = d.table("images")
    if imgs is not None and "file" in imgs.df:
        for iid, rel, row in zip(imgs.ids.astype(str), imgs.df["file"].tolist(), imgs.df["_row"].tolist(),
                                 strict=True):
            if rel is None:
                out[iid] = (None, f"{imgs.file} row {row} names no file")
                continue
            try:
                out[iid] = (raster_bounds(d.path(str(rel), file=imgs.file, row=int(row)), name=str(rel)), None)
            except (OrthospecError, OSError) as exc:
                out[iid] = (None, f"{rel}: {exc}")
    ctx.memo["scene.footprints"] = out
    return out


def _area_km2(bounds: tuple[float, float, float, float], unit: str | None) -> float | None:
    if unit not in ("m", "ft", "usft"):
        return None
    w = float(convert([bounds[2] - bounds[0]], unit, "m")[0])
    h = float(convert([bounds[3] - bounds[1]], unit, "m")[0])
    return abs(w * h) / 1e6


def _param(ctx: ProviderContext, name: str, unit: str, default: float) -> float:
    v = ctx.parameters.get(name)
    if v is None:
        return default
    if hasattr(v, "to"):
        return float(v.to(unit).magnitude)
    return float(v)


@provider(scope="image", measures=MEASURES)
def scene_gcps(ctx: ProviderContext) -> list[Measured]:
    """GCPs per scene counted from gcps.csv, the declared count compared, the strip supplement."""
    d = ctx.delivery
    imgs, scenes, gcps = d.table("images"), d.table("scenes"), d.table("gcps")
    ids: list[str] = imgs.ids.astype(str).tolist() if imgs is not None else []
    if scenes is not None:
        ids += [i for i in scenes.ids.astype(str).tolist() if i not in set(ids)]
    feet = footprints(ctx)
    count: dict[str, Any] = {}
    notes: dict[str, str] = {}
    ev: dict[str, tuple[Evidence, ...]] = {}
    if gcps is None:
        for i in ids:
            count[i], notes[i], ev[i] = None, "the delivery has no GCP table (tables.gcps): nothing to count", ()
    else:
        df = gcps.df
        named = df["image_id"].tolist() if "image_id" in df else [None] * len(df)
        xs, ys = df["x"].to_numpy(float), df["y"].to_numpy(float)
        rows = df["_row"].to_numpy(np.int64)
        lists = [{p.strip() for p in str(v).split(";") if p.strip()} if v is not None else set() for v in named]
        unnamed = np.array([not s for s in lists], dtype=bool)
        unknown = sorted({p for s in lists for p in s} - set(ids))
        for i in ids:
            by_name = np.array([i in s for s in lists], dtype=bool)
            inside = np.zeros(len(df), dtype=bool)
            b, why = feet.get(i, (None, "no images row"))
            if b is not None and unnamed.any():
                inside = unnamed & (xs >= b[0]) & (xs <= b[2]) & (ys >= b[1]) & (ys <= b[3])
            hit = by_name | inside
            n = int(hit.sum())
            parts = []
            if by_name.any():
                parts.append(f"{int(by_name.sum())} naming it in {gcps.file} image_id")
            if unnamed.any():
                parts.append(f"{int(inside.sum())} of the {int(unnamed.sum())} rows naming no scene inside its "
                             "orthoimage footprint" if b is not None else
                             f"{int(unnamed.sum())} rows name no scene and its footprint is unknown ({why})")
            if b is None and unnamed.any() and not by_name.any():
                count[i] = None
            else:
                count[i] = float(n)
            notes[i] = f"{n} GCP(s): " + "; ".join(parts) if parts else f"no row of {gcps.file} names {i}"
            if unknown:
                notes[i] += f" ({gcps.file} image_id names unknown scenes: {', '.join(unknown[:5])})"
            ev[i] = (Evidence(gcps.file, gcps.sha256, tuple(int(r) for r in rows[hit])),)
    declared: dict[str, Any] = {}
    decl_ev: dict[str, Evidence] = {}
    if scenes is not None and "gcp_count" in scenes.df:
        for i, v, row in zip(scenes.ids.astype(str), scenes.df["gcp_count"].tolist(), scenes.df["_row"].tolist(),
                             strict=True):
            if v is not None and not (isinstance(v, float) and math.isnan(v)):
                declared[i] = float(v)
                decl_ev[i] = Evidence(scenes.file, scenes.sha256, (int(row),))
    agrees: dict[str, Any] = {}
    agree_notes: dict[str, str] = {}
    na: dict[str, str] = {}
    for i in ids:
        if i not in declared:
            agrees[i] = None
            na[i] = "the meta-database declares no gcp_count for this scene"
        elif count.get(i) is None:
            agrees[i], agree_notes[i] = None, notes[i]
        else:
            agrees[i] = declared[i] == count[i]
            agree_notes[i] = f"declared {declared[i]:g} (scenes.gcp_count), counted {count[i]:g}: {notes[i]}"
    base = _param(ctx, "gcp_strip_area", "km²", 100.0)
    per = _param(ctx, "gcp_strip_per_area", "1", 2.0)
    area: dict[str, Any] = {}
    supp: dict[str, Any] = {}
    area_notes: dict[str, str] = {}
    for i in ids:
        b, why = feet.get(i, (None, "no images row"))
        a = _area_km2(b, d.crs_unit if d.manifest.project.crs else "m") if b is not None else None
        area[i] = a
        supp[i] = strip_supplement(a, base_area_km2=base, per_area=per) if a is not None else None
        area_notes[i] = (f"orthoimage footprint {a:.4g} km²; + {supp[i]:g} GCP(s) for a strip (Table 9: "
                         f"+{per:g} per additional {base:g} km²)" if a is not None else
                         f"no footprint area: {why or 'the project CRS is not in a length unit'}")
    row_ev = {i: (*ev.get(i, ()), *((decl_ev[i],) if i in decl_ev else ())) for i in ids}
    img_ev: dict[str, tuple[Evidence, ...]] = {}
    if imgs is not None:
        img_ev = {str(i): (Evidence(imgs.file, imgs.sha256, (int(r),)),)
                  for i, r in zip(imgs.ids, imgs.df["_row"], strict=True)}
    s = pd.Series
    return [
        Measured("scene.gcp_count", "image", "1", s(count, dtype=object), s(ev, dtype=object),
                 notes=s(notes, dtype=object)),
        Measured("scene.gcp_count_agrees", "image", "bool", s(agrees, dtype=object), s(row_ev, dtype=object),
                 notes=s(agree_notes, dtype=object), na=s(na, dtype=object) if na else None),
        Measured("scene.area", "image", "km²", s(area, dtype=object), s(img_ev, dtype=object),
                 notes=s(area_notes, dtype=object)),
        Measured("scene.gcp_strip_supplement", "image", "1", s(supp, dtype=object), s(img_ev, dtype=object),
                 notes=s(area_notes, dtype=object)),
    ]
