"""The JRC Table 4 GCP pattern of each aerial block, from gcps.csv, the block outline and the photo centres
(automating JRC-T4-GCP-PATTERN-MANUAL).

* ``gcp_pattern.gaps`` (block): places of the Table 4 pattern of the block's flight configuration
  (``aerotriangulation.configuration``) that the block's GCPs leave empty, named in the note:

  - DGPS flights (``dgps_cba``, ``dgps_otf``, ``dgps_ins``): "One double GCP in each corner of a block
    and one double in the middle": each corner of the outline (its vertices, simplified by 2 % of the
    block's size) and its middle need two GCPs within ``CORNER_RADIUS`` of the block's size;
  - block adjustment without DGPS (``at_no_dgps``): "One GCP every five base lengths (minimum) on the
    perimeter of the block and one GCP across all flight strips, every four base lengths": at least
    perimeter / (5 B) GCPs within one base length B of the outline, and, inside, one GCP per strip for
    every four base lengths of strip beyond the first; B is the median distance between successive
    photo centres of a strip (``images.exposure_x/_y`` in exposure order; a jump over twice the median
    starts a new strip);
  - a single model: not applicable (its minimum of four is JRC-T4-GCP-SINGLE-MODEL).

  Missing when the configuration, the outline or (without DGPS) the photo centres are not given.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
import shapely
from shapely.geometry import Polygon

from ...provenance import Evidence
from ..registry import Measured, ProviderContext, provider

NAME = "gcp_pattern.gaps"
#: a GCP belongs to a corner (or the middle) when within this share of the block's size (sqrt of its area)
CORNER_RADIUS = 0.15
DGPS = ("dgps_cba", "dgps_otf", "dgps_ins")


def dgps_gaps(poly: Polygon, gx: np.ndarray, gy: np.ndarray) -> list[str]:
    """Corners and middle of ``poly`` without a double GCP."""
    size = math.sqrt(poly.area)
    simple = poly.simplify(0.02 * size, preserve_topology=True)
    corners = list(simple.exterior.coords)[:-1]
    middle = poly.centroid if poly.contains(poly.centroid) else poly.representative_point()
    places = [(f"corner ({x:.0f}, {y:.0f})", x, y) for x, y in corners] + [
        ("middle", middle.x, middle.y)
    ]
    out = []
    for label, x, y in places:
        n = int((np.hypot(gx - x, gy - y) <= CORNER_RADIUS * size).sum())
        if n < 2:
            out.append(f"{label}: {n} GCP(s), a double needed")
    return out


def strips(ex: np.ndarray, ey: np.ndarray) -> tuple[float, list[float]] | None:
    """(base length, strip lengths) from photo centres in exposure order; None with fewer than 2 photos."""
    if len(ex) < 2:
        return None
    steps = np.hypot(np.diff(ex), np.diff(ey))
    base = float(np.median(steps))
    if base <= 0:
        return None
    lengths, run = [], 0.0
    for s in steps:
        if s > 2.0 * base:  # a new strip
            lengths.append(run)
            run = 0.0
        else:
            run += float(s)
    lengths.append(run)
    return base, lengths


def no_dgps_gaps(
    poly: Polygon, gx: np.ndarray, gy: np.ndarray, base: float, lengths: list[float]
) -> list[str]:
    """Perimeter and cross-strip GCPs missing for a block adjusted without DGPS (Table 4)."""
    ring = poly.exterior
    pts = shapely.points(gx, gy)
    on_edge = shapely.distance(pts, ring) <= base if len(gx) else np.zeros(0, dtype=bool)
    out = []
    need_perimeter = math.ceil(ring.length / (5.0 * base))
    have = int(on_edge.sum())
    if have < need_perimeter:
        out.append(
            f"perimeter: {have} GCP(s) within a base length ({base:.0f}) of the outline, "
            f"{need_perimeter} needed (one every five base lengths of its {ring.length:.0f})"
        )
    need_inside = sum(max(0, math.ceil(length / (4.0 * base)) - 1) for length in lengths)
    inside = int((~on_edge & shapely.contains(poly, pts)).sum()) if len(gx) else 0
    if inside < need_inside:
        out.append(
            f"across the strips: {inside} GCP(s) inside the block, {need_inside} needed (one per strip "
            f"every four base lengths, {len(lengths)} strip(s))"
        )
    return out


@provider(scope="block", measures={NAME: "1"})
def gcp_pattern(ctx: ProviderContext) -> list[Measured]:
    """Places of the Table 4 GCP pattern each block leaves empty."""
    d = ctx.delivery
    blocks = d.block_ids
    outlines = d.block_outlines()
    at, gcps = d.table("aerotriangulation"), d.table("gcps")
    config: dict[str, Any] = {}
    if at is not None and "configuration" in at.df:
        config = dict(zip(at.df["block"].astype(str), at.df["configuration"].tolist(), strict=True))
    vals: dict[str, Any] = {}
    notes: dict[str, str] = {}
    na: dict[str, str] = {}
    ev: dict[str, tuple[Evidence, ...]] = {}
    for b in blocks:
        items: list[Evidence] = []
        cfg = config.get(b)
        if at is not None:
            items.append(at.evidence(at.df.loc[at.df["block"].astype(str) == b, "_row"])[0])
        if b in outlines:
            items.append(outlines[b][1])
        ev[b] = tuple(items)
        if cfg is None:
            vals[b], notes[b] = (
                None,
                "no flight configuration for the block (aerotriangulation.configuration)",
            )
            continue
        if cfg == "single_model":
            na[b] = "a single model: JRC-T4-GCP-SINGLE-MODEL counts its four GCPs"
            continue
        if b not in outlines:
            vals[b], notes[b] = None, "no block outline"
            continue
        poly = Polygon(outlines[b][0])
        if gcps is None:
            gx = gy = np.zeros(0)
        else:
            mine = gcps.df["block"].astype(str) == b
            gx, gy = gcps.df.loc[mine, "x"].to_numpy(float), gcps.df.loc[mine, "y"].to_numpy(float)
            ev[b] += (gcps.evidence(gcps.df.loc[mine, "_row"])[0],)
        if cfg in DGPS:
            gaps = dgps_gaps(poly, gx, gy)
            what = "a double GCP in each corner and in the middle"
        else:  # at_no_dgps
            got = _photo_strips(ctx, b)
            if got is None:
                vals[b], notes[b] = (
                    None,
                    "no photo centres (images.exposure_x/_y) to find the base length",
                )
                continue
            gaps = no_dgps_gaps(poly, gx, gy, *got)
            what = "GCPs every five base lengths on the perimeter and across the strips every four"
        vals[b] = float(len(gaps))
        notes[b] = f"{cfg}: {what}: " + (
            "; ".join(gaps) if gaps else f"met by the block's {len(gx)} GCPs"
        )
    s = pd.Series
    return [
        Measured(
            NAME,
            "block",
            "1",
            s({b: vals.get(b) for b in blocks}, dtype=object),
            s(ev, dtype=object),
            notes=s(notes, dtype=object),
            na=s(na, dtype=object) if na else None,
        )
    ]


def _photo_strips(ctx: ProviderContext, block: str) -> tuple[float, list[float]] | None:
    imgs = ctx.delivery.table("images")
    if imgs is None or not {"exposure_x", "exposure_y"} <= set(imgs.df):
        return None
    df = imgs.df[imgs.df["block"].astype(str) == block]
    order = (
        ["flight_id", "exposure_time"]
        if "exposure_time" in df
        else ["flight_id"]
        if "flight_id" in df
        else []
    )
    df = df.sort_values([c for c in order if c in df] + ["_row"], kind="stable")
    ok = df["exposure_x"].notna() & df["exposure_y"].notna()
    return strips(
        df.loc[ok, "exposure_x"].to_numpy(float), df.loc[ok, "exposure_y"].to_numpy(float)
    )
