"""Whether the photos cover the area of interest, from the photo lay-down rather than a declared
flag.

* ``derived.photo_coverage`` (delivery): share of the area of interest in force
  (``mosaic.aoi_in_force``) covered by the photo lay-down - footprints from the exposure stations,
  flying heights and the camera's focal length, pixel size and format (JRC §5.2.2 "Side overlap must
  ensure that all the surveyed area will be covered with imagery"). It does not depend on the
  delivered orthoimages, so a delivery of extracts (§12.4) cannot switch the coverage check off by
  declaring ``product.extracts``. A photo whose lay-down GSD (H/f x pixel size) is more than
  ``GSD_TOLERANCE`` coarser than its own recorded GSD counts toward no coverage (red team R7:
  inflated flying heights hid a strip). A camera model of the published table (camera.py) lays down
  with its published format and pixel.

The arithmetic (ground scale, published format, inflated heights) is measures/laydown.py; the
footprints are measures/mosaic.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ...errors import MeasureError, OrthospecError
from ...measures import laydown
from ...measures.laydown import GSD_TOLERANCE
from ...measures.mosaic import photo_footprints, strip_headings
from ...units import convert
from ..registry import Measured, ProviderContext, provider
from .camera import FORMAT_COLUMNS, known_camera
from .pixel import measured_pixel_m

__all__ = ["GSD_TOLERANCE", "LayDown", "photo_coverage"]

COVERAGE = {"derived.photo_coverage": "%"}


@dataclass(frozen=True)
class LayDown:
    """The photo lay-down of one delivery: footprints, evidence, and why they cannot be computed."""

    footprints: list[Any]
    evidence: list[Any]
    #: why no footprint can be computed (None when they can)
    why: str | None = None
    #: images left out: no exposure station, flying height or camera with format, focal and pixel
    incomplete: list[str] = field(default_factory=list)
    #: images left out with their lay-down and reference GSD: a flying height the GSD contradicts
    inflated: list[str] = field(default_factory=list)


def _lay_down_tables(ctx: ProviderContext) -> tuple[Any, Any, Any, list[Any], str | None]:
    """The images, flights and cameras tables, their evidence, and why the lay-down cannot use them."""
    d = ctx.delivery
    imgs, flights, cams = d.table("images"), d.table("flights"), d.table("cameras")
    ev: list[Any] = [t.evidence(t.df["_row"]) for t in (imgs, flights, cams) if t is not None]
    ev = [e for tup in ev for e in tup]
    if imgs is None or flights is None or cams is None:
        absent = [
            n for n, t in (("images", imgs), ("flights", flights), ("cameras", cams)) if t is None
        ]
        why = f"the manifest declares no {', '.join(absent)} table: no photo lay-down"
        return imgs, flights, cams, ev, why
    need_img = [
        c for c in ("exposure_x", "exposure_y", "flying_height", "flight_id") if c not in imgs.df
    ]
    need_cam = [c for c in ("focal_length", "pixel_size", *FORMAT_COLUMNS) if c not in cams.df]
    if need_img or need_cam or "camera_id" not in flights.df:
        parts = ([f"{imgs.file} columns {', '.join(need_img)}"] if need_img else []) + (
            [f"{cams.file} columns {', '.join(need_cam)}"] if need_cam else []
        )
        why = "the photo lay-down needs " + "; ".join(parts or [f"{flights.file} column camera_id"])
        return imgs, flights, cams, ev, why
    return imgs, flights, cams, ev, None


def _camera_of_images(
    imgs: Any, flights: Any, cams: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per images row, from the camera of its flight: focal length (mm), pixel size (µm), format
    across and along track (pixels); a listed model's published format and pixel, not the declared
    ones (issue 25: a format declared 3 x larger hid a missing strip)."""
    cam_of_flight = dict(
        zip(flights.ids.astype(str), flights.df["camera_id"].astype(str), strict=True)
    )
    cam = cams.df.set_index(cams.ids.astype(str))
    cid = [cam_of_flight.get(str(f)) for f in imgs.df["flight_id"]]

    def col(name: str, unit: str | None) -> np.ndarray:
        v = np.array(
            [
                float(cam.at[c, name]) if c in cam.index and cam.at[c, name] is not None else np.nan
                for c in cid
            ],
            dtype=np.float64,
        )
        return v if unit is None else convert(v, cams.units.get(name, unit), unit)

    focal, pix = col("focal_length", "mm"), col("pixel_size", "µm")
    across_px, along_px = col(FORMAT_COLUMNS[0], None), col(FORMAT_COLUMNS[1], None)
    models = (
        dict(zip(cams.ids.astype(str), cams.df["model"].tolist(), strict=True))
        if "model" in cams.df
        else {}
    )
    for k, c in enumerate(cid):
        known = known_camera(models.get(str(c)))
        if known is None:
            continue
        across_px[k], along_px[k] = laydown.published_format(
            across_px[k], along_px[k], known.pixels
        )
        pix[k] = known.pixel_size_um
    return focal, pix, across_px, along_px


def _metres(t: Any, column: str) -> np.ndarray:
    return convert(
        pd.to_numeric(t.df[column], errors="coerce").to_numpy(float), t.units.get(column, "m"), "m"
    )


def _lay_down(ctx: ProviderContext) -> LayDown:
    """The photo footprints of the delivery's images (JRC §5.2.2), or why they cannot be computed."""
    imgs, flights, cams, ev, why = _lay_down_tables(ctx)
    if why is not None:
        return LayDown([], ev, why)
    x, y, hgt = (_metres(imgs, c) for c in ("exposure_x", "exposure_y", "flying_height"))
    focal, pix, across_px, along_px = _camera_of_images(imgs, flights, cams)
    scale = laydown.ground_scale(hgt, pix, focal)  # ground metres per pixel = H/f x pixel size
    across, along = across_px * scale, along_px * scale
    ok = laydown.placeable(x, y, across, along)
    ref = _reference_gsd(ctx, imgs)
    inflated = laydown.inflated(scale, ref, ok)
    ids = imgs.ids.astype(str).to_numpy()
    too_coarse = [
        f"{i} ({g:.3g} m vs {r:.3g} m)"
        for i, g, r in zip(ids[inflated], scale[inflated], ref[inflated], strict=True)
    ]
    ok &= ~inflated
    if not ok.any():
        return LayDown(
            [],
            ev,
            "no image has an exposure station, flying height and a camera with format, focal "
            "length and pixel size consistent with its GSD: the photo lay-down cannot be computed",
            inflated=too_coarse,
        )
    incomplete = ids[~ok & ~inflated].tolist()
    same = laydown.same_station_distance(across[ok], along[ok])
    groups = imgs.df["flight_id"].astype(str).to_numpy()[ok].tolist()
    heading = strip_headings(x[ok], y[ok], groups, min_distance=same)
    try:
        feet = photo_footprints(x[ok], y[ok], across[ok], along[ok], heading.tolist())
    except MeasureError as exc:
        return LayDown([], ev, str(exc), incomplete, too_coarse)
    return LayDown(feet, ev, None, incomplete, too_coarse)


def _reference_gsd(ctx: ProviderContext, imgs: Any) -> np.ndarray:
    """Per images row, in metres: the finest of its recorded acquisition GSD, the delivered GSD
    (``images.gsd``, ``product.gsd``) and the pixel size of its delivered raster as measured; NaN
    when none is known. A lay-down GSD much coarser than that is a flying height the delivery
    contradicts (see ``GSD_TOLERANCE``). The raster's own pixel size counts because every other
    number here is declared: inflating heights and declared GSDs together (red team R18) leaves the
    delivered 0.25 m pixels as they are."""
    n = len(imgs.df)
    cands = [
        np.full(n, ctx.delivery.gsd_m if ctx.delivery.gsd_m is not None else np.nan, dtype=float),
        _raster_pixel_sizes(ctx, imgs),
    ]
    for col in ("gsd", "acquisition_gsd"):
        if col in imgs.df:
            cands.append(
                convert(
                    pd.to_numeric(imgs.df[col], errors="coerce").to_numpy(float),
                    imgs.units.get(col, "m"),
                    "m",
                )
            )
    stack = np.column_stack(cands)
    out = np.full(n, np.nan)
    have = np.isfinite(stack).any(axis=1)
    out[have] = np.nanmin(stack[have], axis=1)
    return out


def _raster_pixel_sizes(ctx: ProviderContext, imgs: Any) -> np.ndarray:
    """Pixel size in metres of each images row's delivered file (the run's one reading of the
    files); NaN where the file is absent, unreadable or not in a length unit (its own raster rules
    report that)."""
    measured = measured_pixel_m(ctx)
    return np.array([measured.get(str(i), np.nan) for i in imgs.ids.tolist()], dtype=float)


@provider(scope="delivery", measures=COVERAGE)
def photo_coverage(ctx: ProviderContext) -> list[Measured]:
    """Share of the area of interest the photo lay-down covers (JRC §5.2.2)."""
    import shapely

    d = ctx.delivery
    value: float | None = None
    note: str | None
    try:
        from .mosaic import aoi_in_force

        aoi, aoi_ev, source = aoi_in_force(ctx)
    except (OrthospecError, OSError) as exc:
        aoi, aoi_ev, source, note = (
            None,
            (d.manifest_evidence("project.area_of_interest"),),
            "",
            str(exc),
        )
    else:
        note = (
            None
            if aoi is not None
            else "no area of interest: give project.area_of_interest or block polygons"
        )
    lay = _lay_down(ctx)
    feet, ev, why = lay.footprints, lay.evidence, lay.why
    if aoi is not None:
        if why is not None:
            note = why
        else:
            share = float(shapely.union_all(feet).intersection(aoi).area / aoi.area * 100.0)
            skipped, inflated = lay.incomplete, lay.inflated
            note = (
                f"{len(feet)} photo footprints (H/f x pixel size x format) cover {share:.3f} % "
                f"of the {source}"
            )
            if (skipped or inflated) and share < 100.0:
                # the photos left out might cover the gap: a lower bound below 100 % decides nothing
                if skipped:
                    note += (
                        f"; image(s) {', '.join(skipped[:5])} lack an exposure station or flying "
                        "height, so full coverage can be neither shown nor refuted"
                    )
                if inflated:
                    note += (
                        "; image(s) "
                        f"{', '.join(inflated[:5])}{' ...' if len(inflated) > 5 else ''} "
                        f"have a flying height whose H/f x pixel GSD is more than "
                        f"{(GSD_TOLERANCE - 1) * 100:.0f} % coarser than their acquisition_gsd, "
                        "declared GSD or delivered raster pixel, so their footprints are not "
                        "evidence of coverage (JRC §3.1, "
                        "§5.2.1): full coverage is not shown"
                    )
            else:
                value = share
                if skipped:
                    note += (
                        f" even without image(s) {', '.join(skipped[:5])} (no exposure station "
                        "or height)"
                    )
                if inflated:
                    note += (
                        f" even without image(s) {', '.join(inflated[:5])} (flying height "
                        "inconsistent "
                        "with the GSD)"
                    )
    return [
        Measured(
            "derived.photo_coverage",
            "delivery",
            "%",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: (*aoi_ev, *ev)}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]
