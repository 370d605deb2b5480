"""The delivered DEM file itself, for JRC Table 7 (§9.2 DEM: "complete, continuous and without any
gross anomalies"; "QC should confirm that the DEM is correctly georeferenced"), read through
:func:`orthospec.raster.dem.dem_integrity` (one pass per file).

* ``demfile.nodata_share`` (dem): share of no-data cells of the DEM file, % ("complete").
* ``demfile.spikes`` (dem): cells more than ``dem_spike_height`` above or below the median of their
  3 x 3 neighbourhood ("spikes/holes").
* ``demfile.crs_ok`` (dem): the DEM file's CRS (its horizontal part) is the map projection in force
  (parameter ``map_crs``); missing when the file has no CRS or no map projection is stated.

A DEM row without a delivered ``file`` is not applicable (nothing to read; the §9.5 meta-database
records and JRC-9.2-T7-DEM-VERTICAL-CHECK still apply).

Which blocks a DEM serves and whether a DEM is delivered or used, computed from the files rather
than trusting a declared flag:

* ``derived.dem_blocks`` (dem): the blocks a DEM serves (';'-separated), from the dem table's
  ``block`` column, else from the delivered DEM file's footprint against the block polygons. A
  failing DEM then rejects those blocks only (JRC Table 5, §12.7 "will reject all products for the
  block"), never every block of the delivery.
* ``derived.dem_delivered``, ``derived.dem_used`` and ``derived.dem_delivered_agrees`` (delivery):
  see :func:`dem_presence`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ...delivery.outlines import finite_ring
from ...errors import OrthospecError
from ...provenance import Evidence
from ...raster.dem import dem_integrity
from ..registry import Measured, ProviderContext, RowEvidence, provider
from .cells import filled as _filled

if TYPE_CHECKING:
    from shapely.geometry import Polygon

MEASURES = {"demfile.nodata_share": "%", "demfile.spikes": "1", "demfile.crs_ok": "bool"}


def _map_epsg(ctx: ProviderContext) -> int | None:
    raw = ctx.parameters.get("map_crs")
    if not raw:
        return None
    text = str(raw)
    try:
        return int(text.split(":", 1)[1]) if text.upper().startswith("EPSG:") else None
    except ValueError:
        return None


def _project_zone(ctx: ProviderContext) -> tuple[Any, str]:
    """The union of the block outlines in force (the project zone whose completeness counts), or
    None."""
    from shapely import union_all
    from shapely.geometry import Polygon

    rings = [r for r, _ in ctx.delivery.block_outlines().values() if r and len(r) >= 3]
    try:
        polys = [Polygon(r) for r in rings]
        zone = union_all(polys) if polys else None
    except (ValueError, TypeError):
        zone = None
    return zone, (
        "inside the blocks" if zone is not None else "(the whole file: no block outlines)"
    )


@provider(scope="dem", measures=MEASURES)
def dem_file(ctx: ProviderContext) -> list[Measured]:
    """No-data share, spikes/holes and CRS of each delivered DEM file."""
    d = ctx.delivery
    t = d.table("dem")
    ids: list[str] = t.ids.astype(str).tolist() if t is not None else []
    vals: dict[str, dict[str, Any]] = {n: {} for n in MEASURES}
    notes: dict[str, dict[str, str]] = {n: {} for n in MEASURES}
    errors: dict[str, str] = {}
    na: dict[str, str] = {}
    ev: dict[str, tuple[Evidence, ...]] = {}
    height = ctx.parameters.get("dem_spike_height")
    spike_m = (
        float(height.to("m").magnitude)
        if height is not None and hasattr(height, "to")
        else float(height or 30.0)
    )
    target = _map_epsg(ctx)
    zone, zone_text = _project_zone(ctx)
    if t is not None:
        files = t.df["file"].tolist() if "file" in t.df else [None] * len(ids)
        for i, rel, row in zip(ids, files, t.df["_row"].tolist(), strict=True):
            row_ev = Evidence(t.file, t.sha256, (int(row),))
            ev[i] = (row_ev,)
            if rel is None or not str(rel).strip():
                na[i] = f"no DEM file delivered ({t.file} row {row}: file is empty)"
                continue
            try:
                res = dem_integrity(
                    d.path(str(rel), file=t.file, row=int(row)),
                    name=str(rel),
                    spike_height=spike_m,
                    within=zone,
                )
                ev[i] = (row_ev, d.evidence(str(rel)))
            except (OrthospecError, OSError) as exc:
                errors[i] = f"{rel}: {exc}"
                continue
            vals["demfile.nodata_share"][i] = res.nodata_share
            notes["demfile.nodata_share"][i] = (
                f"{res.nodata_cells:,} of the {res.judged_cells:,} cells of {rel} "
                f"{zone_text} are no-data ({res.nodata_share:.3f} %)"
            )
            vals["demfile.spikes"][i] = float(res.spikes)
            shown = "; ".join(f"row {r}, column {c}: {dz:+.1f}" for r, c, dz in res.examples)
            notes["demfile.spikes"][i] = (
                f"{res.spikes:,} cell(s) of {rel} more than {spike_m:g} m from the median of "
                f"their 3 x 3 neighbourhood" + (f" ({shown})" if shown else "")
            )
            if res.epsg is None or target is None:
                vals["demfile.crs_ok"][i] = None
                notes["demfile.crs_ok"][i] = (
                    f"{rel} has no CRS with an EPSG code"
                    if res.epsg is None
                    else "no map projection in force (parameter map_crs)"
                )
            else:
                vals["demfile.crs_ok"][i] = res.epsg == target
                notes["demfile.crs_ok"][i] = (
                    f"{rel} is in EPSG:{res.epsg}, the map projection in force is EPSG:{target}"
                )
    s = pd.Series
    return [
        Measured(
            n,
            "dem",
            u,
            s({i: vals[n].get(i) for i in ids}, dtype=object),
            s(ev, dtype=object),
            notes=s(notes[n], dtype=object),
            errors=s(errors, dtype=object) if errors else None,
            na=s(na, dtype=object) if na else None,
        )
        for n, u in MEASURES.items()
    ]


DEM = {"derived.dem_blocks": "text"}


def _served_blocks(
    d: Any, rel: str, dem_id: str, polys: dict[str, Polygon]
) -> tuple[str | None, str]:
    """The blocks (';'-separated) whose polygon the footprint of DEM file ``rel`` overlaps, and how
    it was found. The footprint is the file's georeferenced bounds as raster/facts.py reads them
    (the one reading of a raster's header); a file that cannot be read or has no georeference serves
    none."""
    from shapely.geometry import box

    from ...raster.facts import read_facts

    try:
        facts = read_facts(d.path(rel, what=f"dem row for {dem_id}"), sha256=False, name=rel)
    except (OrthospecError, OSError) as exc:
        return None, f"cannot read the footprint of {rel}: {exc}"
    if facts.error is not None or facts.bounds is None:
        return None, f"cannot read the footprint of {rel}: {facts.error or facts.georeference}"
    foot = box(*facts.bounds)
    served = sorted(b for b, poly in polys.items() if foot.intersection(poly).area > 0)
    return ";".join(served) or None, (
        f"footprint of {rel} overlaps block(s) {', '.join(served)}"
        if served
        else f"footprint of {rel} overlaps no block polygon"
    )


@provider(scope="dem", measures=DEM)
def dem_blocks(ctx: ProviderContext) -> list[Measured]:
    """Blocks each DEM serves: its `block` value, else its file's footprint over the block polygons."""
    from shapely.geometry import Polygon

    d = ctx.delivery
    t = d.table("dem")
    if t is None:
        return [
            Measured(
                "derived.dem_blocks",
                "dem",
                "text",
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": "the manifest declares no 'dem' table"}, dtype=object),
            )
        ]
    # the outlines in force: the checker's file's when it states blocks (red team R13), else the
    # manifest's
    polys = {
        block: Polygon(ring)
        for block, (ring, _) in ctx.block_outlines().items()
        if finite_ring(ring)
    }
    ids = t.ids.astype(str).tolist()
    vals: dict[str, Any] = {}
    notes: dict[str, str] = {}
    files = t.df["file"].tolist() if "file" in t.df else [None] * len(ids)
    blocks_col = t.df["block"].tolist() if "block" in t.df else [None] * len(ids)
    for dem_id, blk, rel in zip(ids, blocks_col, files, strict=True):
        if blk is not None and not (isinstance(blk, float) and np.isnan(blk)) and str(blk).strip():
            vals[dem_id] = ";".join(x.strip() for x in str(blk).split(";") if x.strip())
            notes[dem_id] = f"{t.file} column block"
            continue
        vals[dem_id] = None
        if not rel or (isinstance(rel, float) and np.isnan(rel)) or not polys:
            notes[dem_id] = (
                f"{t.file} gives no block for {dem_id}"
                + ("" if polys else " and the manifest gives no block polygons")
                + ("" if rel and not isinstance(rel, float) else " and no DEM file")
            )
            continue
        vals[dem_id], notes[dem_id] = _served_blocks(d, str(rel), dem_id, polys)
    ev = RowEvidence(
        t.file, t.sha256, pd.Series(t.df["_row"].to_numpy(), index=t.ids.astype(str).to_numpy())
    )
    return [
        Measured(
            "derived.dem_blocks",
            "dem",
            "text",
            pd.Series(vals, dtype=object),
            ev,
            notes=pd.Series(notes, dtype=object),
        )
    ]


DEM_PRESENCE = {
    "derived.dem_delivered": "bool",
    "derived.dem_used": "bool",
    "derived.dem_delivered_agrees": "bool",
}
#: scenes columns that record a DEM used to orthorectify the scene (JRC Table 7 "DEM", §9.5)
SCENE_DEM_COLUMNS = ("dem_grid_size", "dem_accuracy", "dem_qc_result")


def _dem_files(d: Any, t: Any) -> tuple[list[str], list[str]]:
    """The DEM files the dem table names, and for each whether it is present and readable (read
    once, header only, through raster/facts.py)."""
    from ...raster.facts import read_facts

    named: list[str] = []
    if t is not None and "file" in t.df:
        named = [str(v).strip() for v in t.df["file"].tolist() if _filled(v)]
    states = []
    for rel in named:
        try:
            f = read_facts(d.path(rel, what="dem file"), sha256=False, name=rel)
        except OrthospecError as exc:
            states.append(f"{rel}: {exc}")
            continue
        states.append(f"{rel} ({'readable' if f.readable else f.error})")
    return named, states


def _scenes_recording_dem(scenes: Any) -> tuple[list[str], list[Any]]:
    """Scene ids that record the DEM they were orthorectified with (``SCENE_DEM_COLUMNS``), and the
    evidence of those rows."""
    recorded: list[str] = []
    ev: list[Any] = []
    if scenes is not None:
        cols = [c for c in SCENE_DEM_COLUMNS if c in scenes.df]
        for col in cols:
            hit = scenes.df[col].map(_filled).astype(bool)
            if hit.any():
                recorded += scenes.ids.astype(str)[hit.to_numpy(bool)].tolist()
                ev += list(scenes.evidence(scenes.df["_row"][hit]))
    return sorted(set(recorded)), ev


def _presence_parts(
    t: Any, states: list[str] | None, declared: Any, recorded: list[str]
) -> list[str]:
    """The parts of the presence note: the DEM files named (``states``, None when none is), the dem
    table's rows, the scenes that record a DEM."""
    parts = []
    if states is not None:
        parts.append(f"the dem table names DEM file(s): {'; '.join(states[:5])}")
    elif declared is True:
        parts.append("delivery.yaml declares product.dem_delivered: true")
    else:
        parts.append("no DEM file is named in the delivery")
    if t is not None and len(t.df):
        parts.append(f"{t.file} records {len(t.df)} DEM(s)")
    if recorded:
        parts.append(
            f"scene(s) {', '.join(recorded[:5])} record the DEM they were orthorectified with "
            f"({'/'.join(SCENE_DEM_COLUMNS)})"
        )
    return parts


@provider(scope="delivery", measures=DEM_PRESENCE)
def dem_presence(ctx: ProviderContext) -> list[Measured]:
    """Whether a DEM is delivered and whether one was used, from the files (issue 25, "flags that switch
    rules off"), never from ``product.dem_delivered`` alone.

    * ``derived.dem_delivered``: the dem table names a DEM file (the delivery lists a DEM among its
      files: JRC §12.7 "Where the DEM is also a deliverable"), or the manifest declares
      ``product.dem_delivered: true`` (an admission is never ignored). The note says whether each
      named file is present and readable.
    * ``derived.dem_used``: a DEM is delivered, or the dem table has rows, or a scene records the
      DEM it was orthorectified with (``scenes.dem_grid_size``, ``dem_accuracy``,
      ``dem_qc_result``): the DEM checks of Tables 5 and 7 then apply, whatever tables the
      contractor removed.
    * ``derived.dem_delivered_agrees``: the declared ``product.dem_delivered`` is the computed fact
      (not applicable when nothing is declared).
    """
    d = ctx.delivery
    t = d.table("dem")
    scenes = d.table("scenes")
    declared = getattr(d.manifest.product, "dem_delivered", None)
    ev: list[Any] = [d.manifest_evidence("product.dem_delivered")]
    if t is not None:
        ev += list(t.evidence(t.df["_row"]))
    named, states = _dem_files(d, t)
    recorded, scene_ev = _scenes_recording_dem(scenes)
    ev += scene_ev
    delivered = bool(named) or declared is True
    used = delivered or (t is not None and len(t.df) > 0) or bool(recorded)
    parts = _presence_parts(t, states if named else None, declared, recorded)
    note = "; ".join(parts)
    agrees = None if declared is None else bool(declared) == delivered
    agree_note = (
        "product.dem_delivered not declared"
        if declared is None
        else f"declared {str(declared).lower()}, the files say {str(delivered).lower()} "
        f"({parts[0]})"
    )
    evidence = pd.Series({d.id: tuple(ev)}, dtype=object)
    na = (
        pd.Series({d.id: "the contractor declares no product.dem_delivered"}, dtype=object)
        if declared is None
        else None
    )
    return [
        Measured(
            "derived.dem_delivered",
            "delivery",
            "bool",
            pd.Series({d.id: delivered}, dtype=object),
            evidence,
            notes=pd.Series({d.id: note}, dtype=object),
        ),
        Measured(
            "derived.dem_used",
            "delivery",
            "bool",
            pd.Series({d.id: used}, dtype=object),
            evidence,
            notes=pd.Series({d.id: note}, dtype=object),
        ),
        Measured(
            "derived.dem_delivered_agrees",
            "delivery",
            "bool",
            pd.Series({d.id: agrees}, dtype=object),
            evidence,
            notes=pd.Series({d.id: agree_note}, dtype=object),
            na=na,
        ),
    ]
