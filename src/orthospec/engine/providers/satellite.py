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
  100km² of strip scene": ``per_area`` GCPs (parameter ``gcp_strip_per_area``, 2) for each started
  100 km² (the text's step, ``STRIP_AREA_KM2``) beyond the first.
* ``scene.gcp_quadrants`` (image): how many of the four quarters of the scene's orthoimage footprint
  hold one of its GCPs (Table 9 "well distributed (in grid) with points as near as possible to each
  corner/edge (no extrapolation)": 4 when every quarter is controlled).
* ``scene.checkpoints_on_gcps`` (image): check points of checkpoints.csv measured on the scene
  (``image_id``) that are GCPs of that scene: the same point id, or a reference position within
  ``blunder_factor`` x the two points' combined precision of a GCP (Table 9 master image "check points
  which were not used as GCPs"). Missing when no check point of the scene is listed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ...delivery.in_force import INTERNAL
from ...measures.independence import separation
from ...provenance import Evidence
from ...raster.footprints import image_footprints
from ...units import convert
from ..registry import Measured, ProviderContext, provider
from .shared import Shared

MEASURES = {
    "scene.gcp_count": "1",
    "scene.gcp_count_agrees": "bool",
    "scene.area": "km²",
    "scene.gcp_strip_supplement": "1",
    "scene.gcp_quadrants": "1",
    "scene.checkpoints_on_gcps": "1",
}
#: the strip step of Table 9 ("plus 2 per additional 100km² of strip scene")
STRIP_AREA_KM2 = 100.0
#: precision (m) assumed for a point whose precision_xy is not given, when telling a check point from a GCP
DEFAULT_PRECISION_M = 0.05


def strip_supplement(
    area_km2: float, *, base_area_km2: float = 100.0, per_area: float = 2.0
) -> float:
    """Extra GCPs for a strip of ``area_km2``: ``per_area`` for each started ``base_area_km2`` beyond
    the first (Table 9 "plus 2 per additional 100km² of strip scene")."""
    if not math.isfinite(area_km2) or area_km2 <= base_area_km2:
        return 0.0
    return per_area * math.ceil((area_km2 - base_area_km2) / base_area_km2 - 1e-9)


#: image id -> (left, bottom, right, top) of its delivered raster, or (None, why); once per run
FOOTPRINTS: Shared[dict[str, tuple[tuple[float, float, float, float] | None, str | None]]] = Shared(
    "image_footprints", lambda ctx: image_footprints(ctx.delivery)
)


def footprints(
    ctx: ProviderContext,
) -> dict[str, tuple[tuple[float, float, float, float] | None, str | None]]:
    """Image id -> (left, bottom, right, top) of its delivered raster, or (None, why); once per run."""
    return FOOTPRINTS.get(ctx)


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
    if (
        d.manifest.sensor.type != "satellite"
    ):  # Table 9 facts: no raster or GCP file is read for air photos
        # (every rule reading these applies to satellite deliveries only: its `when` says why not here)
        return [
            Measured(
                n,
                "image",
                u,
                pd.Series(dict.fromkeys(ids), dtype=object),
                pd.Series({i: () for i in ids}, dtype=object),
            )
            for n, u in MEASURES.items()
        ]
    feet = footprints(ctx)
    count: dict[str, Any] = {}
    notes: dict[str, str] = {}
    ev: dict[str, tuple[Evidence, ...]] = {}
    scene_rows: dict[str, np.ndarray] = {}  # scene -> mask of its GCP rows
    if gcps is None:
        for i in ids:
            count[i], notes[i], ev[i] = (
                None,
                "the delivery has no GCP table (tables.gcps): nothing to count",
                (),
            )
    else:
        df = gcps.df
        named = df["image_id"].tolist() if "image_id" in df else [None] * len(df)
        xs, ys = df["x"].to_numpy(float), df["y"].to_numpy(float)
        rows = df["_row"].to_numpy(np.int64)
        lists = [
            {p.strip() for p in str(v).split(";") if p.strip()} if v is not None else set()
            for v in named
        ]
        unnamed = np.array([not s for s in lists], dtype=bool)
        unknown = sorted({p for s in lists for p in s} - set(ids))
        rows_of: dict[str, list[int]] = {}
        for k, named_scenes in enumerate(lists):
            for sc in named_scenes:
                rows_of.setdefault(sc, []).append(k)
        for i in ids:
            by_name = np.zeros(len(df), dtype=bool)
            by_name[rows_of.get(i, [])] = True
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
                parts.append(
                    f"{int(inside.sum())} of the {int(unnamed.sum())} rows naming no scene inside its "
                    "orthoimage footprint"
                    if b is not None
                    else f"{int(unnamed.sum())} rows name no scene and its footprint is unknown ({why})"
                )
            if b is None and unnamed.any() and not by_name.any():
                count[i] = None
            else:
                count[i] = float(n)
            notes[i] = (
                f"{n} GCP(s): " + "; ".join(parts) if parts else f"no row of {gcps.file} names {i}"
            )
            if unknown:
                notes[i] += (
                    f" ({gcps.file} image_id names unknown scenes: {', '.join(unknown[:5])})"
                )
            ev[i] = (Evidence(gcps.file, gcps.sha256, tuple(int(r) for r in rows[hit])),)
            scene_rows[i] = hit
    declared: dict[str, Any] = {}
    decl_ev: dict[str, Evidence] = {}
    if scenes is not None and "gcp_count" in scenes.df:
        for i, v, row in zip(
            scenes.ids.astype(str),
            scenes.df["gcp_count"].tolist(),
            scenes.df["_row"].tolist(),
            strict=True,
        ):
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
            agree_notes[i] = (
                f"declared {declared[i]:g} (scenes.gcp_count), counted {count[i]:g}: {notes[i]}"
            )
    base = STRIP_AREA_KM2
    per = _param(ctx, "gcp_strip_per_area", "1", 2.0)
    area: dict[str, Any] = {}
    supp: dict[str, Any] = {}
    area_notes: dict[str, str] = {}
    for i in ids:
        b, why = feet.get(i, (None, "no images row"))
        a = _area_km2(b, d.crs_unit if d.manifest.project.crs else "m") if b is not None else None
        area[i] = a
        supp[i] = strip_supplement(a, base_area_km2=base, per_area=per) if a is not None else None
        area_notes[i] = (
            f"orthoimage footprint {a:.4g} km²; + {supp[i]:g} GCP(s) for a strip (Table 9: "
            f"+{per:g} per additional {base:g} km²)"
            if a is not None
            else f"no footprint area: {why or 'the project CRS is not in a length unit'}"
        )
    row_ev = {i: (*ev.get(i, ()), *((decl_ev[i],) if i in decl_ev else ())) for i in ids}
    img_ev: dict[str, tuple[Evidence, ...]] = {}
    if imgs is not None:
        img_ev = {
            str(i): (Evidence(imgs.file, imgs.sha256, (int(r),)),)
            for i, r in zip(imgs.ids, imgs.df["_row"], strict=True)
        }
    quads, quad_notes = _quadrants(ids, feet, gcps, scene_rows)
    on_gcps, on_notes, on_ev = _checkpoints_on_gcps(ctx, ids, gcps, scene_rows)
    s = pd.Series
    return [
        Measured(
            "scene.gcp_quadrants",
            "image",
            "1",
            s(quads, dtype=object),
            s(ev, dtype=object),
            notes=s(quad_notes, dtype=object),
        ),
        Measured(
            "scene.checkpoints_on_gcps",
            "image",
            "1",
            s(on_gcps, dtype=object),
            s(on_ev, dtype=object),
            notes=s(on_notes, dtype=object),
        ),
        Measured(
            "scene.gcp_count",
            "image",
            "1",
            s(count, dtype=object),
            s(ev, dtype=object),
            notes=s(notes, dtype=object),
        ),
        Measured(
            "scene.gcp_count_agrees",
            "image",
            "bool",
            s(agrees, dtype=object),
            s(row_ev, dtype=object),
            notes=s(agree_notes, dtype=object),
            na=s(na, dtype=object) if na else None,
        ),
        Measured(
            "scene.area",
            "image",
            "km²",
            s(area, dtype=object),
            s(img_ev, dtype=object),
            notes=s(area_notes, dtype=object),
        ),
        Measured(
            "scene.gcp_strip_supplement",
            "image",
            "1",
            s(supp, dtype=object),
            s(img_ev, dtype=object),
            notes=s(area_notes, dtype=object),
        ),
    ]


def _quadrants(
    ids: list[str], feet: dict[str, Any], gcps: Any, scene_rows: dict[str, np.ndarray]
) -> tuple[dict[str, Any], dict[str, str]]:
    """Per scene: quarters of its footprint holding one of its GCPs (None when either is unknown)."""
    vals: dict[str, Any] = {}
    notes: dict[str, str] = {}
    for i in ids:
        b, why = feet.get(i, (None, "no images row"))
        if gcps is None or i not in scene_rows:
            vals[i], notes[i] = None, "no GCP table"
            continue
        if b is None:
            vals[i], notes[i] = None, f"no orthoimage footprint: {why}"
            continue
        hit = scene_rows[i]
        xs, ys = gcps.df["x"].to_numpy(float)[hit], gcps.df["y"].to_numpy(float)[hit]
        cx, cy = (b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0
        inside = (xs >= b[0]) & (xs <= b[2]) & (ys >= b[1]) & (ys <= b[3])
        names = ("south-west", "south-east", "north-west", "north-east")
        held = {
            names[int(x >= cx) + 2 * int(y >= cy)]
            for x, y in zip(xs[inside], ys[inside], strict=True)
        }
        vals[i] = float(len(held))
        empty = [q for q in names if q not in held]
        notes[i] = f"{int(inside.sum())} of its {int(hit.sum())} GCPs inside the footprint; " + (
            f"no GCP in the {', '.join(empty)} quarter(s)" if empty else "a GCP in every quarter"
        )
    return vals, notes


def _checkpoints_on_gcps(
    ctx: ProviderContext, ids: list[str], gcps: Any, scene_rows: dict[str, np.ndarray]
) -> tuple[dict[str, Any], dict[str, str], dict[str, tuple[Evidence, ...]]]:
    """Per scene: its listed check points that are one of its GCPs (id, or position within
    blunder_factor x the combined precision, and never nearer than the distance that tells two points
    apart whatever precision the tables declare: :func:`~orthospec.measures.independence.separation`
    of the tolerance in force and the GSD). Table 9's master check is the contractor's production
    record, so its points are the delivery's own table (``internal_checkpoints`` when the checker
    measured its own points: those never reject the contractor's products)."""
    cps = ctx.delivery.table(INTERNAL)
    if cps is None:
        cps = ctx.delivery.table("checkpoints")
    factor = _param(ctx, "blunder_factor", "1", 3.0)
    # a declared precision of 0.1 mm must not shrink "the same point" to nothing (a GCP moved 1 cm)
    floor = separation(
        _param(ctx, "tolerance_xy", "m", math.nan),
        ctx.delivery.gsd_m,
        tolerance_factor=_param(ctx, "checkpoint_separation_factor", "1", 1.0),
        gsd_px=_param(ctx, "checkpoint_separation_px", "pixel", 2.0),
    )
    vals: dict[str, Any] = {}
    notes: dict[str, str] = {}
    ev: dict[str, tuple[Evidence, ...]] = {}
    if cps is None or "image_id" not in cps.df:
        why = "no check point table" if cps is None else f"{cps.file} has no image_id column"
        return dict.fromkeys(ids), dict.fromkeys(ids, why), {i: () for i in ids}
    cdf = cps.df
    c_img = cdf["image_id"].astype(str).to_numpy()
    cx, cy = cdf["x_ref"].to_numpy(float), cdf["y_ref"].to_numpy(float)
    cp_prec = (
        cdf["precision_xy"].to_numpy(float) if "precision_xy" in cdf else np.full(len(cdf), np.nan)
    )
    cp_prec = np.where(np.isnan(cp_prec), DEFAULT_PRECISION_M, cp_prec)
    cp_ids = cdf["point_id"].astype(str).to_numpy()
    for i in ids:
        mine = c_img == i
        if not mine.any():
            vals[i], notes[i], ev[i] = (
                None,
                f"no check point of {cps.file} is measured on {i} (image_id)",
                (),
            )
            continue
        if gcps is None or i not in scene_rows:
            vals[i], notes[i], ev[i] = None, "no GCP table to compare with", ()
            continue
        g = gcps.df[scene_rows[i]]
        gx, gy = g["x"].to_numpy(float), g["y"].to_numpy(float)
        g_prec = (
            g["precision_xy"].to_numpy(float) if "precision_xy" in g else np.full(len(g), np.nan)
        )
        g_prec = np.where(np.isnan(g_prec), DEFAULT_PRECISION_M, g_prec)
        g_ids = set(g["point_id"].astype(str))
        same: list[str] = []
        for k in np.flatnonzero(mine):
            if cp_ids[k] in g_ids:
                same.append(f"{cp_ids[k]} (a GCP id)")
                continue
            if len(gx):
                dist = np.hypot(gx - cx[k], gy - cy[k])
                limit = np.maximum(factor * np.hypot(g_prec, cp_prec[k]), floor)
                j = int(np.argmin(dist - limit))
                if dist[j] <= limit[j]:
                    same.append(f"{cp_ids[k]} ({dist[j]:.3f} m from GCP {g['point_id'].iloc[j]})")
        vals[i] = float(len(same))
        n = int(mine.sum())
        notes[i] = (
            f"{len(same)} of its {n} check points are GCPs of the scene: {', '.join(same[:5])}"
            if same
            else f"none of its {n} check points is one of its {len(g)} GCPs"
        )
        ev[i] = (
            Evidence(cps.file, cps.sha256, tuple(int(r) for r in cdf["_row"].to_numpy()[mine])),
            Evidence(gcps.file, gcps.sha256, tuple(int(r) for r in g["_row"])),
        )
    return vals, notes, ev
