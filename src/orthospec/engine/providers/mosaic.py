"""Mosaic measures (JRC §5.2.2 coverage, §11 and Table 11 seamlines) from delivered vectors and image footprints.

The area of interest in force (:func:`aoi_in_force`, also photo coverage's) is the checker's when its
file states one (its area, else the union of its block outlines), else the manifest's: the project's
`area_of_interest` vector file, else the union of the block polygons; the evidence says which.
"""

from __future__ import annotations

from typing import Any

import pandas as pd
import shapely
from shapely.geometry import Polygon, box

from ...delivery.outlines import finite_ring
from ...errors import MeasureError, OrthospecError
from ...measures.mosaic import seamline_coverage
from ...raster.reading import read_vector
from ...raster.roi import raster_bounds
from ..registry import Measured, ProviderContext, provider

MEASURES = {"mosaic.aoi_coverage": "%", "mosaic.seamline_coverage": "%", "mosaic.seamline_overlap": "%",
            "mosaic.seamlines_invalid": "1"}


def declared_aoi(ctx: ProviderContext) -> tuple[Any, tuple[Any, ...], str]:
    """(area, evidence, wording) of the area of interest the manifest declares."""
    d = ctx.delivery
    rel = d.manifest.project.area_of_interest
    if rel:
        geoms, _ = read_vector(d.path(rel, what="project.area_of_interest"), name=rel)
        if not geoms:
            raise MeasureError(f"{rel}: the area of interest has no geometry")
        return shapely.union_all(geoms), (d.evidence(rel),), f"area of interest {rel}"
    blocks = [b for b in d.manifest.blocks if b.polygon and len(b.polygon) >= 3]
    broken = [b.id for b in blocks if not finite_ring(b.polygon)]
    if broken:
        raise MeasureError(f"delivery.yaml blocks {', '.join(broken)}: a polygon vertex is not a finite number, "
                           "so the area of interest cannot be formed")
    polys = [Polygon(b.polygon) for b in blocks]
    if not polys:
        return None, (d.manifest_evidence("project.area_of_interest"),), ""
    return shapely.union_all(polys), (d.manifest_evidence("blocks"),), "union of the block polygons"


def aoi_in_force(ctx: ProviderContext) -> tuple[Any, tuple[Any, ...], str]:
    """(area, evidence, wording) the photo lay-down must cover (JRC §5.2.2 "all the surveyed area").

    The checker's ``area_of_interest`` when its file states one, else the union of the checker's
    block outlines when it states those (red team R13: the area is the buyer's, not what the
    contractor redraws); else the manifest's: project.area_of_interest, else the union of its
    block polygons (:func:`declared_aoi`). The same order on both sides: an area, else its blocks."""
    from ...delivery.outlines import ring_polygon

    stated = ctx.outlines
    in_force = ctx.area_of_interest_in_force()
    if stated is not None and in_force is not None:
        ring, ev = in_force
        return ring_polygon(ring), (ev,), f"area of interest of the {stated.source}"
    if stated is not None and stated.blocks:
        return (shapely.union_all([ring_polygon(r) for r, _ in stated.blocks.values()]),
                tuple(e for _, e in stated.blocks.values()), f"union of the block outlines of the {stated.source}")
    return declared_aoi(ctx)


def _footprints(ctx: ProviderContext) -> tuple[list[Any], list[str]]:
    """Image footprints (:func:`orthospec.raster.roi.raster_bounds`) and the images that could not
    be read (named in the coverage note: an unreadable image covers nothing)."""
    d = ctx.delivery
    t = d.table("images")
    if t is None:
        return [], []
    out, bad = [], []
    for rel in t.df["file"].astype(str):
        try:
            out.append(box(*raster_bounds(d.path(rel), name=rel)))
        except (OrthospecError, OSError):
            bad.append(rel)
    return out, bad


@provider(scope="delivery", measures=MEASURES)
def mosaic_measures(ctx: ProviderContext) -> list[Measured]:
    """Coverage of the area of interest by image footprints and by seamline polygons, overlaps."""
    d = ctx.delivery
    item = d.id
    vals: dict[str, Any] = dict.fromkeys(MEASURES)
    notes: dict[str, str] = {}
    errors: dict[str, str] = {}
    evs: dict[str, tuple[Any, ...]] = {}
    try:
        aoi, aoi_ev, source = aoi_in_force(ctx)
    except (OrthospecError, OSError) as exc:
        aoi, aoi_ev, source = None, (d.manifest_evidence("project.area_of_interest"),), ""
        for n in MEASURES:
            errors[n] = str(exc)
    if aoi is not None:
        feet, bad = _footprints(ctx)
        if feet:
            cov = shapely.union_all(feet).intersection(aoi).area / aoi.area * 100.0
            vals["mosaic.aoi_coverage"] = cov
            notes["mosaic.aoi_coverage"] = (f"image footprints cover {cov:.3f} % of the {source}"
                                            + (f"; unreadable: {', '.join(bad)}" if bad else ""))
            t = d.table("images")
            evs["mosaic.aoi_coverage"] = aoi_ev + t.evidence(t.df["_row"])
        seam = d.manifest.vectors.get("seamlines")
        if seam:
            try:
                geoms, _ = read_vector(d.path(seam, what="vectors.seamlines"), name=seam)
                sc = seamline_coverage(geoms, aoi)
                vals["mosaic.seamline_coverage"] = 100.0 - sc.gap_pct
                vals["mosaic.seamline_overlap"] = sc.overlap_pct
                vals["mosaic.seamlines_invalid"] = float(len(sc.invalid_polygons))
                notes["mosaic.seamline_coverage"] = (f"gap {sc.gap_area:.1f} m² ({sc.gap_pct:.4f} %) of the "
                                                     f"{source}")
                for n in ("mosaic.seamline_coverage", "mosaic.seamline_overlap", "mosaic.seamlines_invalid"):
                    evs[n] = (*aoi_ev, d.evidence(seam))
            except (OrthospecError, OSError, shapely.errors.ShapelyError) as exc:  # unreadable vector: error
                for n in ("mosaic.seamline_coverage", "mosaic.seamline_overlap", "mosaic.seamlines_invalid"):
                    errors[n] = f"{seam}: cannot read seamlines: {exc}"
        else:
            for n in ("mosaic.seamline_coverage", "mosaic.seamline_overlap", "mosaic.seamlines_invalid"):
                notes[n] = "the manifest gives no vectors.seamlines file"
    else:
        for n in MEASURES:
            notes.setdefault(n, "no area of interest: give project.area_of_interest or block polygons")
    out = []
    for n, unit in MEASURES.items():
        out.append(Measured(n, "delivery", unit, pd.Series({item: vals[n]}, dtype=object),
                            pd.Series({item: evs.get(n, aoi_ev)}, dtype=object),
                            notes=pd.Series({item: notes[n]}, dtype=object) if n in notes else None,
                            errors=pd.Series({item: errors[n]}, dtype=object) if n in errors else None))
    return out
