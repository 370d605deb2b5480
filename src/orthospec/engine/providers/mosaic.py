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

from ...delivery.outlines import finite_ring, ring_polygon
from ...errors import MeasureError, OrthospecError
from ...measures.mosaic import seamline_coverage
from ...provenance import Evidence
from ...raster.reading import read_vector
from ..registry import Measured, ProviderContext, provider

MEASURES = {
    "mosaic.aoi_coverage": "%",
    "mosaic.seamline_coverage": "%",
    "mosaic.seamline_overlap": "%",
    "mosaic.seamlines_invalid": "1",
}


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
        raise MeasureError(
            f"delivery.yaml blocks {', '.join(broken)}: a polygon vertex is not a finite number, "
            "so the area of interest cannot be formed"
        )
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
        return (
            shapely.union_all([ring_polygon(r) for r, _ in stated.blocks.values()]),
            tuple(e for _, e in stated.blocks.values()),
            f"union of the block outlines of the {stated.source}",
        )
    return declared_aoi(ctx)


def _footprints(ctx: ProviderContext) -> tuple[list[Any], list[str]]:
    """Image footprints (the files' bounds, from the run's one reading of them: raster/facts.py) and
    the images that could not be read (named in the coverage note: an unreadable image covers nothing)."""
    from .rasters import scanned

    got = scanned(ctx)
    if "missing" in got:
        return [], []
    t = got["table"]
    out, bad = [], []
    for i, rel in zip(t.ids.astype(str).tolist(), t.df["file"].astype(str).tolist(), strict=True):
        f = got["facts"].get(i)
        if f is None or f.bounds is None:
            bad.append(rel)
        else:
            out.append(box(*f.bounds))
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
            notes["mosaic.aoi_coverage"] = f"image footprints cover {cov:.3f} % of the {source}" + (
                f"; unreadable: {', '.join(bad)}" if bad else ""
            )
            t = d.table("images")
            evs["mosaic.aoi_coverage"] = aoi_ev + (
                t.evidence(t.df["_row"]) if t is not None else ()
            )
        seam = d.manifest.vectors.get("seamlines")
        if seam:
            try:
                geoms, _ = read_vector(d.path(seam, what="vectors.seamlines"), name=seam)
                sc = seamline_coverage(geoms, aoi)
                vals["mosaic.seamline_coverage"] = 100.0 - sc.gap_pct
                vals["mosaic.seamline_overlap"] = sc.overlap_pct
                vals["mosaic.seamlines_invalid"] = float(len(sc.invalid_polygons))
                notes["mosaic.seamline_coverage"] = (
                    f"gap {sc.gap_area:.1f} m² ({sc.gap_pct:.4f} %) of the {source}"
                )
                for n in (
                    "mosaic.seamline_coverage",
                    "mosaic.seamline_overlap",
                    "mosaic.seamlines_invalid",
                ):
                    evs[n] = (*aoi_ev, d.evidence(seam))
            except (
                OrthospecError,
                OSError,
                shapely.errors.ShapelyError,
            ) as exc:  # unreadable vector: error
                for n in (
                    "mosaic.seamline_coverage",
                    "mosaic.seamline_overlap",
                    "mosaic.seamlines_invalid",
                ):
                    errors[n] = f"{seam}: cannot read seamlines: {exc}"
        else:
            for n in (
                "mosaic.seamline_coverage",
                "mosaic.seamline_overlap",
                "mosaic.seamlines_invalid",
            ):
                notes[n] = "the manifest gives no vectors.seamlines file"
    else:
        for n in MEASURES:
            notes.setdefault(
                n, "no area of interest: give project.area_of_interest or block polygons"
            )
    out = []
    for n, unit in MEASURES.items():
        out.append(
            Measured(
                n,
                "delivery",
                unit,
                pd.Series({item: vals[n]}, dtype=object),
                pd.Series({item: evs.get(n, aoi_ev)}, dtype=object),
                notes=pd.Series({item: notes[n]}, dtype=object) if n in notes else None,
                errors=pd.Series({item: errors[n]}, dtype=object) if n in errors else None,
            )
        )
    return out


LOCATION = {"raster.in_area": "bool"}


def outline_crs(ctx: ProviderContext) -> str | None:
    """The CRS block outlines and the area of interest are written in: the map projection in force
    (parameter ``map_crs``; the checker's outlines are in it), else the manifest's ``project.crs``."""
    return ctx.parameters.get("map_crs") or ctx.delivery.manifest.project.crs or None


def _footprint(f: Any, target: str | None, same: dict[str, bool | str]) -> tuple[Any, str | None]:
    """The raster's bounds as a polygon in ``target`` CRS (reprojected when its own differs), or
    (None, why). ``same`` caches, per CRS text, whether it is the target (every image of a delivery
    usually shares one CRS; pyproj parses it once)."""
    if f.bounds is None:
        return None, f"the file has no georeference ({f.georeference or f.error})"
    if target is None:
        return None, "no map projection in force and no project.crs: the outlines' CRS is unknown"
    if f.crs_wkt is None:
        return None, "the file has no CRS"
    from ...delivery.crs import CrsProblem, same_crs

    if f.crs_wkt not in same:
        try:
            same[f.crs_wkt] = same_crs(f.crs_wkt, target)
        except CrsProblem as exc:
            same[f.crs_wkt] = f"cannot compare the file's CRS with {target}: {exc}"
    known = same[f.crs_wkt]
    if isinstance(known, str):
        return None, known
    if known:
        return box(*f.bounds), None
    from rasterio.warp import transform_bounds

    from ...raster.reading import gdal_errors

    try:
        with gdal_errors(file=f.path, what="footprint"):
            return box(*transform_bounds(f.crs_wkt, target, *f.bounds, densify_pts=21)), None
    except MeasureError as exc:  # PROJ cannot place it (mapped by the one boundary)
        return None, f"cannot reproject the footprint from {f.crs_name} to {target}: {exc}"


@provider(scope="image", measures=LOCATION)
def raster_location(ctx: ProviderContext) -> list[Measured]:
    """Each delivered image lies where it claims (issue 25; JRC §12.4 Table 12 "Ortho-image ...
    georeferenced to the (national) map projection").

    True when the file's footprint (its own bounds, from :mod:`orthospec.raster.facts`, in the
    outlines' CRS) overlaps the outline in force of its block (``images.block``), else the area of
    interest in force; False when it lies wholly outside (the note gives the distance). Missing when
    the footprint or the outline is unknown. The block column and the outlines are declarations or
    the checker's; the footprint is the file's."""
    from .rasters import scanned

    d = ctx.delivery
    got = scanned(ctx)
    if "missing" in got:
        return [
            Measured(
                "raster.in_area",
                "image",
                "bool",
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": got["missing"]}, dtype=object),
            )
        ]
    t = got["table"]
    ids = [str(i) for i in t.ids.tolist()]
    blocks = dict(zip(ids, t.df["block"].tolist(), strict=True)) if "block" in t.df else {}
    polys = {b: ring_polygon(r) for b, (r, _) in d.block_outlines().items() if finite_ring(r)}
    outline_ev = {b: e for b, (_, e) in d.block_outlines().items()}
    aoi_error = None
    try:
        aoi, aoi_ev, aoi_what = aoi_in_force(ctx)
    except (OrthospecError, OSError) as exc:
        aoi, aoi_ev, aoi_what, aoi_error = None, (), "", str(exc)
    target = outline_crs(ctx)
    same: dict[str, bool | str] = {}
    values: dict[str, bool | None] = {}
    notes: dict[str, str] = {}
    evidence: dict[str, tuple[Any, ...]] = {}
    rows = got["rows"]
    for i in ids:
        listed = Evidence(t.file, t.sha256, (int(rows[i]),))
        f = got["facts"].get(i)
        block = blocks.get(i)
        block = (
            None
            if block is None or (isinstance(block, float) and block != block)
            else str(block).strip()
        )
        ev: tuple[Evidence, ...]
        if block in polys:
            area, ev, what = polys[block], (outline_ev[block],), f"the outline of block {block}"
        elif aoi is not None:
            area, ev, what = (
                aoi,
                aoi_ev,
                f"the {aoi_what}" + (f" (block {block} has no outline)" if block else ""),
            )
        else:
            area, ev, what = None, (), ""
        file_ev = (
            (Evidence(f.path, f.sha256 or got["sha256"].get(i, ""), ()),) if f is not None else ()
        )
        evidence[i] = (listed, *file_ev, *ev)
        if f is None or i in got["errors"]:
            values[i], notes[i] = None, "the file could not be read: its footprint is unknown"
            continue
        if area is None:
            values[i] = None
            notes[i] = (
                aoi_error
                or f"no outline for block {block} and no area of interest: nothing to place it in"
            )
            continue
        foot, why = _footprint(f, target, same)
        if foot is None:
            values[i], notes[i] = None, str(why)
            continue
        shared = float(foot.intersection(area).area)
        values[i] = shared > 0.0
        if shared > 0.0:
            notes[i] = f"{100.0 * shared / foot.area:.1f} % of the file's footprint lies in {what}"
        else:
            notes[i] = (
                f"the file's footprint {tuple(round(v, 2) for v in foot.bounds)} lies "
                f"{float(foot.distance(area)):.1f} map units outside {what}"
            )
    return [
        Measured(
            "raster.in_area",
            "image",
            "bool",
            pd.Series(values, dtype=object),
            pd.Series(evidence, dtype=object),
            notes=pd.Series(notes, dtype=object),
        )
    ]
