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
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from ...errors import OrthospecError
from ...provenance import Evidence
from ...raster.dem import dem_integrity
from ..registry import Measured, ProviderContext, provider

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
    """The union of the block outlines in force (the project zone whose completeness counts), or None."""
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
    spike_m = float(height.to("m").magnitude) if hasattr(height, "to") else float(height or 30.0)
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
