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
* ``derived.photo_coverage`` (delivery): share of the area of interest in force (``mosaic.aoi_in_force``)
  covered by the photo lay-down - footprints from the exposure stations, flying heights and the camera's focal
  length, pixel size and format (JRC §5.2.2 "Side overlap must ensure that all the surveyed area
  will be covered with imagery"). It does not depend on the delivered orthoimages, so a delivery
  of extracts (§12.4) cannot switch the coverage check off by declaring ``product.extracts``.
  A photo whose lay-down GSD (H/f x pixel size) is more than ``GSD_TOLERANCE`` coarser than its
  own recorded GSD counts toward no coverage (red team R7: inflated flying heights hid a strip).
* ``derived.master_images`` (delivery): number of scenes declared master image
  (``scenes.is_master``), so that un-declaring a master that the scenes still record (its check
  date, or another scene's ``master_image_id``) cannot switch the Table 9 master-image rules off
  unseen (red team R8); not applicable when no scene shows a master-image workflow (§9.4).
* ``derived.is_master`` (image) and ``derived.master_images_agree`` (delivery): which scenes are
  master images is the checker's knowledge (parameter ``master_images``, scene ids); when stated, the
  Table 9 master-image rules judge those scenes whatever ``scenes.is_master`` says, and the flags
  are compared with it (red team R8: a master un-flagged with every trace erased escaped them).
  Without the parameter ``derived.is_master`` is the contractor's ``scenes.is_master``.
* ``derived.dem_blocks`` (dem): the blocks a DEM serves (';'-separated), from the dem table's
  ``block`` column, else from the delivered DEM file's footprint against the block polygons. A
  failing DEM then rejects those blocks only (JRC Table 5, §12.7 "will reject all products for
  the block"), never every block of the delivery.
* ``derived.project_crs_agrees`` (delivery): the manifest's ``project.crs`` (the CRS its
  coordinates and block outlines are written in) names the map projection in force, the ITT
  parameter ``map_crs`` (JRC §12.4 Table 12; red team R16: the contractor relabelled every image
  and project.crs alike). Absent or unreadable is False, never "not applicable".
* ``derived.block_outlines_agree`` and ``derived.area_of_interest_agrees`` (delivery): when the
  checker's file states block outlines / an area of interest (delivery/checker.py), those are in
  force (``Delivery.block_outlines``: the check points' blocks, the DEM's blocks, the area the
  photos must cover) and the manifest's are declarations compared with them (red team R13: B02's
  outline shrunk to hide a coverage hole; R17: B01's redrawn over B02's worst points). A declared
  outline agrees within ``OUTLINE_TOLERANCE``; a block only one side lists is a disagreement. Not
  applicable when the checker's file states none (the manifest's are then in force).
* ``derived.pansharpened`` (delivery): the product is pan-sharpened, computed from the bands and
  pixel sizes (a multispectral product finer than the scenes' native multispectral pixel), so a
  declared ``product.pansharpened: false`` cannot switch off JRC §10.5 ("Pan-sharpening of
  satellite data"); ``derived.pansharpened_agrees`` compares it with the declaration.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ...delivery.outlines import finite_ring
from ...errors import MeasureError, OrthospecError
from ...measures.classes import classify
from ...measures.mosaic import photo_footprints, strip_headings
from ...units import convert
from ..registry import Measured, ProviderContext, RowEvidence, provider

DELIVERY = {"derived.orthorectification": "text"}
COVERAGE = {"derived.photo_coverage": "%"}
MASTER = {"derived.master_images": "1"}
MASTER_FLAG = {"derived.is_master": "bool"}
MASTER_AGREE = {"derived.master_images_agree": "bool"}
PROJECT_CRS = {"derived.project_crs_agrees": "bool"}
OUTLINES_AGREE = {"derived.block_outlines_agree": "bool"}
AOI_AGREE = {"derived.area_of_interest_agrees": "bool"}
#: A declared outline agrees with the one in force when the area between them (symmetric difference)
#: is at most this share of the in-force outline's area, and no point of one lies farther from the
#: other (Hausdorff distance) than this share of the square root of that area. Both relative, so the
#: test reads the same in any map unit; 1 % admits rounded coordinates, a ring started at another
#: vertex or densified, not a redrawn boundary (a corridor reaching 1 % of a 6 x 7 km block's size,
#: 65 m, into its neighbour already fails the distance test whatever its area).
OUTLINE_TOLERANCE = 0.01
#: A photo counts toward coverage only when its lay-down GSD (H/f x pixel size, the scale of its
#: footprint) is at most this factor times its reference GSD (the finest of ``images.acquisition_gsd``,
#: ``images.gsd``, ``product.gsd`` and its delivered raster's measured pixel size). 20 %: the
# ground-pixel size of one photo
#: varies with the terrain under it (H is above mean ground) and §5.2.1 only asks for the
#: "predefined GSD" (should, no tolerance); aerial-pass agrees within 0.1 %, the red team's
#: inflated heights were 150 % too coarse. Only a coarser (larger) footprint is refused: a smaller
#: one can only lower the coverage, never hide a gap.
GSD_TOLERANCE = 1.2
DEM = {"derived.dem_blocks": "text"}
#: camera format columns (pixels across and along track) the photo lay-down needs
FORMAT_COLUMNS = ("format_across_px", "format_along_px")
IMAGE = {"derived.resolution_class": "text", "derived.resolution_class_agrees": "bool"}
PANSHARPENED = {"derived.pansharpened": "bool", "derived.pansharpened_agrees": "bool"}
#: a product at most 1/1.5 of the native multispectral pixel is read as fused with the PAN band
PAN_MARGIN = 1.5


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
        note = (
            f"blocks[].method: {known[0]}"
            if len(known) == 1
            else "delivery.yaml gives no product.orthorectification and the blocks' methods "
            + ("disagree (" + ", ".join(known) + ")" if known else "are not given")
        )
    return [
        Measured(
            "derived.orthorectification",
            "delivery",
            "text",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]


def measured_pixel_m(ctx: ProviderContext) -> dict[str, float]:
    """Per image id: the coarser axis of its delivered file's pixel, in metres (the one reading of the
    files, raster/facts.py, through the run's scan); images whose file is absent, unreadable or not
    in a length unit are left out (their own raster rules report them)."""
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

    Measured, not declared (issue 25): the delivered file's own pixel (its geotransform) decides,
    or the scene's input pixel (``scenes.input_pixel_size``) when that is finer: the class is the
    finest the evidence shows, so declaring a coarser input pixel (4 m for a 0.5 m raster) cannot
    move a VHR scene into a class with fewer obligations. Without a readable file the declared
    columns are used, in order: ``scenes.input_pixel_size``, ``images.acquisition_gsd``, ``images.gsd``."""
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
                f"scenes.input_pixel_size {v:.4g} m, finer than the file's pixel {measured[i]:.4g} m"
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
    notes = {}
    for i, c, v in zip(items, classes, in_unit, strict=True):
        if np.isnan(v):
            notes[i] = (
                "no pixel size (scenes.input_pixel_size, images.acquisition_gsd or images.gsd)"
            )
        elif c is None:
            notes[i] = (
                f"pixel size {v:.4g} {unit} falls in no class of `classes: resolution` (a gap of §9.1)"
            )
        else:
            notes[i] = f"pixel size {v:.4g} {unit} ({source.get(i, '?')}) -> {c}"
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
            notes=pd.Series(notes, dtype=object),
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


def _lay_down(ctx: ProviderContext) -> tuple[list[Any], list[Any], str | None]:
    """Photo footprints, evidence, and why they cannot be computed (None when they can)."""
    d = ctx.delivery
    imgs, flights, cams = d.table("images"), d.table("flights"), d.table("cameras")
    ev: list[Any] = [t.evidence(t.df["_row"]) for t in (imgs, flights, cams) if t is not None]
    ev = [e for tup in ev for e in tup]
    if imgs is None or flights is None or cams is None:
        absent = [
            n for n, t in (("images", imgs), ("flights", flights), ("cameras", cams)) if t is None
        ]
        return [], ev, f"the manifest declares no {', '.join(absent)} table: no photo lay-down"
    need_img = [
        c for c in ("exposure_x", "exposure_y", "flying_height", "flight_id") if c not in imgs.df
    ]
    need_cam = [c for c in ("focal_length", "pixel_size", *FORMAT_COLUMNS) if c not in cams.df]
    if need_img or need_cam or "camera_id" not in flights.df:
        parts = ([f"{imgs.file} columns {', '.join(need_img)}"] if need_img else []) + (
            [f"{cams.file} columns {', '.join(need_cam)}"] if need_cam else []
        )
        return (
            [],
            ev,
            "the photo lay-down needs " + "; ".join(parts or [f"{flights.file} column camera_id"]),
        )
    df = imgs.df
    cam_of_flight = dict(
        zip(flights.ids.astype(str), flights.df["camera_id"].astype(str), strict=True)
    )
    cam = cams.df.set_index(cams.ids.astype(str))
    x = pd.to_numeric(df["exposure_x"], errors="coerce").to_numpy(float)
    y = pd.to_numeric(df["exposure_y"], errors="coerce").to_numpy(float)
    x, y = (
        convert(x, imgs.units.get("exposure_x", "m"), "m"),
        convert(y, imgs.units.get("exposure_y", "m"), "m"),
    )
    hgt = convert(
        pd.to_numeric(df["flying_height"], errors="coerce").to_numpy(float),
        imgs.units.get("flying_height", "m"),
        "m",
    )
    cid = [cam_of_flight.get(str(f)) for f in df["flight_id"]]

    def col(name: str, unit: str | None) -> np.ndarray:
        v = np.array(
            [
                float(cam.at[c, name]) if c in cam.index and cam.at[c, name] is not None else np.nan
                for c in cid
            ],
            dtype=float,
        )
        return v if unit is None else convert(v, cams.units.get(name, unit), unit)

    focal, pix = col("focal_length", "mm"), col("pixel_size", "µm")
    across_px, along_px = col(FORMAT_COLUMNS[0], None), col(FORMAT_COLUMNS[1], None)
    # a camera model of the published table: its own format and pixel, not the declared ones (issue 25:
    # a format declared 3 x larger hid a missing strip)
    models = (
        dict(zip(cams.ids.astype(str), cams.df["model"].tolist(), strict=True))
        if "model" in cams.df
        else {}
    )
    for k, c in enumerate(cid):
        known = known_camera(models.get(str(c)))
        if known is None:
            continue
        big, small = max(known["pixels"]), min(known["pixels"])
        wide = not (
            np.isfinite(along_px[k]) and np.isfinite(across_px[k]) and along_px[k] > across_px[k]
        )
        across_px[k], along_px[k] = (big, small) if wide else (small, big)
        pix[k] = known["pixel_size_um"]
    scale = hgt * (pix * 1e-6) / (focal * 1e-3)  # ground metres per pixel = H/f x pixel size
    across, along = across_px * scale, along_px * scale
    ok = (
        np.isfinite(np.column_stack([x, y, across, along])).all(axis=1) & (across > 0) & (along > 0)
    )
    ref = _reference_gsd(ctx, imgs)
    inflated = ok & np.isfinite(ref) & (scale > GSD_TOLERANCE * ref)
    ids = imgs.ids.astype(str).to_numpy()
    ctx.memo["derived.lay_down_inflated"] = [
        f"{i} ({g:.3g} m vs {r:.3g} m)"
        for i, g, r in zip(ids[inflated], scale[inflated], ref[inflated], strict=True)
    ]
    ok &= ~inflated
    if not ok.any():
        return (
            [],
            ev,
            (
                "no image has an exposure station, flying height and a camera with format, focal "
                "length and pixel size consistent with its GSD: the photo lay-down cannot be computed"
            ),
        )
    ctx.memo["derived.lay_down_incomplete"] = ids[~ok & ~inflated].tolist()
    # stations closer than 5 % of a footprint's length are one station recorded twice (a copied row)
    same = 0.05 * float(np.nanmedian(np.minimum(across[ok], along[ok])))
    heading = strip_headings(
        x[ok], y[ok], df["flight_id"].astype(str).to_numpy()[ok].tolist(), min_distance=same
    )
    try:
        return photo_footprints(x[ok], y[ok], across[ok], along[ok], heading), ev, None
    except MeasureError as exc:
        return [], ev, str(exc)


def _camera_key(model: Any) -> str:
    import re

    text = str(model or "").lower().replace("ultracam", "uc")
    return re.sub(r"[^a-z0-9]", "", text)


_CAMERAS: dict[str, dict[str, Any]] | None = None


def known_camera(model: Any) -> dict[str, Any] | None:
    """The published format of a large-format camera model (specs/cameras.yaml: Passini, Jacobsen & Day,
    Table 1), or None for a model the table does not list. Names match without case, spaces or
    punctuation, "UltraCam" read as "UC" (``UltraCam Eagle`` is ``UC Eagle``)."""
    global _CAMERAS
    if not model or not str(model).strip():
        return None
    if _CAMERAS is None:
        import yaml

        from ...resources import specs_dir

        raw = yaml.safe_load((specs_dir() / "cameras.yaml").read_text(encoding="utf-8"))
        _CAMERAS = {
            _camera_key(c["id"]): {
                "id": c["id"],
                "pixels": (int(c["pixels_x"]), int(c["pixels_y"])),
                "pixel_size_um": float(c["pixel_size_um"]),
                "focal_length_mm": tuple(float(f) for f in c["focal_length_mm"]),
            }
            for c in raw["cameras"]
        }
    return _CAMERAS.get(_camera_key(model))


def _reference_gsd(ctx: ProviderContext, imgs: Any) -> np.ndarray:
    """Per images row, in metres: the finest of its recorded acquisition GSD, the delivered GSD
    (``images.gsd``, ``product.gsd``) and the pixel size of its delivered raster as measured; NaN
    when none is known. A lay-down GSD much coarser than that is a flying height the delivery
    contradicts (see ``GSD_TOLERANCE``). The raster's own pixel size counts because every other
    number here is declared: inflating heights and declared GSDs together (red team R18) leaves
    the delivered 0.25 m pixels as they are."""
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
    """Pixel size in metres of each images row's delivered file (the run's one reading of the files);
    NaN where the file is absent, unreadable or not in a length unit (its own raster rules report that)."""
    measured = measured_pixel_m(ctx)
    return np.array([measured.get(str(i), np.nan) for i in imgs.ids.tolist()], dtype=float)


@provider(scope="delivery", measures=COVERAGE)
def photo_coverage(ctx: ProviderContext) -> list[Measured]:
    """Share of the area of interest the photo lay-down covers (JRC §5.2.2)."""
    import shapely

    d = ctx.delivery
    value: float | None = None
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
    feet, ev, why = _lay_down(ctx)
    if aoi is not None:
        if why is not None:
            note = why
        else:
            share = float(shapely.union_all(feet).intersection(aoi).area / aoi.area * 100.0)
            skipped = ctx.memo.get("derived.lay_down_incomplete") or []
            inflated = ctx.memo.get("derived.lay_down_inflated") or []
            note = f"{len(feet)} photo footprints (H/f x pixel size x format) cover {share:.3f} % of the {source}"
            if (skipped or inflated) and share < 100.0:
                # the photos left out might cover the gap: a lower bound below 100 % decides nothing
                if skipped:
                    note += (
                        f"; image(s) {', '.join(skipped[:5])} lack an exposure station or flying height, "
                        "so full coverage can be neither shown nor refuted"
                    )
                if inflated:
                    note += (
                        f"; image(s) {', '.join(inflated[:5])}{' ...' if len(inflated) > 5 else ''} "
                        f"have a flying height whose H/f x pixel GSD is more than "
                        f"{(GSD_TOLERANCE - 1) * 100:.0f} % coarser than their acquisition_gsd, "
                        "declared GSD or delivered raster pixel, so their footprints are not "
                        "evidence of coverage (JRC §3.1, "
                        "§5.2.1): full coverage is not shown"
                    )
            else:
                value = share
                if skipped:
                    note += f" even without image(s) {', '.join(skipped[:5])} (no exposure station or height)"
                if inflated:
                    note += (
                        f" even without image(s) {', '.join(inflated[:5])} (flying height inconsistent "
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


def _disagreement(declared: Any, in_force: Any) -> str | None:
    """None when ``declared`` agrees with ``in_force`` within ``OUTLINE_TOLERANCE``, else how far apart."""
    import math

    area = float(in_force.area)
    sym = float(declared.symmetric_difference(in_force).area)
    far = float(declared.hausdorff_distance(in_force))
    limit = OUTLINE_TOLERANCE * math.sqrt(area)
    if sym <= OUTLINE_TOLERANCE * area and far <= limit:
        return None
    return (
        f"differs by {sym / area * 100:.3g} % of the area in force (symmetric difference; at most "
        f"{OUTLINE_TOLERANCE * 100:g} %) and by up to {far:.6g} map units (Hausdorff distance; at most {limit:.6g})"
    )


@provider(scope="delivery", measures=OUTLINES_AGREE)
def block_outlines_agree(ctx: ProviderContext) -> list[Measured]:
    """The manifest's block outlines are the ones the checker's file puts in force (JRC §12.4 "block/site")."""
    from ...delivery.outlines import ring_polygon

    d = ctx.delivery
    stated = ctx.outlines
    ev: tuple[Any, ...] = (d.manifest_evidence("blocks"),)
    na = None
    value: bool | None
    if stated is None or not stated.blocks:
        value, note = (
            None,
            "the checker's file states no block outlines: the manifest's are in force",
        )
        na = pd.Series({d.id: note}, dtype=object)
    else:
        ev += tuple(e for _, e in stated.blocks.values())
        declared = {b.id: (i, b.polygon) for i, b in enumerate(d.manifest.blocks)}
        problems = []
        for block in sorted(set(declared) | set(stated.blocks)):
            if block not in declared:
                problems.append(
                    f"block {block}: the {stated.source} gives its outline, delivery.yaml lists no "
                    "such block"
                )
            elif block not in stated.blocks:
                problems.append(
                    f"block {block} (delivery.yaml blocks[{declared[block][0]}]): the {stated.source} "
                    "gives no outline for it, so none of its check points lies in a block in force"
                )
            elif not finite_ring(declared[block][1]):
                problems.append(
                    f"block {block}: delivery.yaml blocks[{declared[block][0]}] declares no valid polygon"
                )
            else:
                why = _disagreement(
                    ring_polygon(declared[block][1]), ring_polygon(stated.blocks[block][0])
                )
                if why:
                    problems.append(
                        f"block {block}: delivery.yaml blocks[{declared[block][0]}].polygon {why}"
                    )
        value = not problems
        note = (
            "; ".join(problems[:5])
            + (f"; and {len(problems) - 5} more" if len(problems) > 5 else "")
            if problems
            else f"the {len(stated.blocks)} block outline(s) of delivery.yaml agree with the "
            f"{stated.source} (within {OUTLINE_TOLERANCE * 100:g} %)"
        )
    return [
        Measured(
            "derived.block_outlines_agree",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=na,
        )
    ]


@provider(scope="delivery", measures=AOI_AGREE)
def area_of_interest_agrees(ctx: ProviderContext) -> list[Measured]:
    """The manifest's area of interest is the one the checker's file puts in force (JRC §5.2.2).

    Declared: project.area_of_interest, else the union of the manifest's block polygons; in force:
    the checker's area_of_interest, else the union of its block outlines (``mosaic.aoi_in_force``).
    Not applicable when the checker states neither, or when it states an area and the manifest
    declares no area file (the union of blocks is then no statement about the area)."""
    d = ctx.delivery
    stated = ctx.outlines
    rel = d.manifest.project.area_of_interest
    ev: tuple[Any, ...] = (d.manifest_evidence("project.area_of_interest"),)
    na: str | None = None
    value: bool | None = None
    if stated is None:
        note = na = (
            "the checker's file states no area of interest or block outlines: the manifest's are in force"
        )
    elif stated.area_of_interest is not None and not rel:
        note = na = (
            f"delivery.yaml declares no project.area_of_interest; the {stated.source}'s is in force "
            "and nothing is declared to compare with it"
        )
    else:
        from .mosaic import aoi_in_force, declared_aoi

        try:
            in_force, in_force_ev, in_force_what = aoi_in_force(ctx)
            declared, declared_ev, declared_what = declared_aoi(ctx)
        except (OrthospecError, OSError) as exc:
            note = f"cannot form the declared area of interest: {exc}"
        else:
            ev = (*declared_ev, *in_force_ev)
            if declared is None:
                note = na = "delivery.yaml declares no area of interest and no block polygon"
            else:
                why = _disagreement(declared, in_force)
                value = why is None
                note = (
                    f"the {declared_what} (delivery.yaml) is not the {in_force_what}: it {why}"
                    if why
                    else f"the {declared_what} (delivery.yaml) agrees with the {in_force_what} "
                    f"(within {OUTLINE_TOLERANCE * 100:g} %)"
                )
    return [
        Measured(
            "derived.area_of_interest_agrees",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=None if na is None else pd.Series({d.id: na}, dtype=object),
        )
    ]


#: scenes columns that show a master-image workflow (JRC Table 9 "Accuracy of the master image")
MASTER_EVIDENCE = ("master_image_id", "master_pixel_size", "master_check_date")


def _filled(v: Any) -> bool:
    return v is not None and not (isinstance(v, float) and np.isnan(v)) and bool(str(v).strip())


def _flagged_master(t: Any) -> pd.Series:
    """Per scenes row: the contractor flags it ``is_master`` (true or 1)."""
    if "is_master" not in t.df:
        return pd.Series(False, index=t.df.index)
    return t.df["is_master"].map(
        lambda v: v is True or (isinstance(v, (int, float, np.bool_)) and v == 1)
    )


def named_masters(ctx: ProviderContext) -> list[str] | None:
    """The master images the checker names (parameter ``master_images``: scene ids separated by ';' or
    ','), or None when nobody on the checker's side names them."""
    raw = ctx.parameters.get("master_images")
    if raw is None:
        return None
    names = sorted({p.strip() for p in str(raw).replace(",", ";").split(";") if p.strip()})
    return names or None


@provider(scope="image", measures=MASTER_FLAG)
def is_master(ctx: ProviderContext) -> list[Measured]:
    """Per scene: it is a master image (JRC Table 9). The checker's ``master_images`` when stated,
    else the contractor's ``scenes.is_master`` (red team R8: un-flagging a master switched its rules off)."""
    t = ctx.delivery.table("scenes")
    if t is None:
        empty = pd.Series(dtype=object)
        return [Measured("derived.is_master", "image", "bool", empty, empty.copy())]
    ids = t.ids.astype(str).to_numpy()
    rows = pd.Series(t.df["_row"].to_numpy(), index=ids)
    rows = rows[~rows.index.duplicated()]
    named = named_masters(ctx)
    if named is None:
        raw = (
            t.df["is_master"].to_numpy(dtype=object)
            if "is_master" in t.df
            else np.full(len(ids), None)
        )
        values = pd.Series(
            [None if v is None or (isinstance(v, float) and np.isnan(v)) else bool(v) for v in raw],
            index=ids,
            dtype=object,
        )
        notes = pd.Series(
            f"declared in {t.file} is_master (the checker names no master_images)",
            index=rows.index,
            dtype=object,
        )
    else:
        values = pd.Series([i in named for i in ids], index=ids, dtype=object)
        notes = pd.Series(
            {
                i: (
                    "a master image named by the checker (master_images)"
                    if i in named
                    else "not among the master images the checker names (master_images)"
                )
                for i in rows.index
            },
            dtype=object,
        )
    values = values[~values.index.duplicated()]
    return [
        Measured(
            "derived.is_master",
            "image",
            "bool",
            values,
            RowEvidence(t.file, t.sha256, rows),
            notes=notes,
        )
    ]


@provider(scope="delivery", measures=MASTER_AGREE)
def master_images_agree(ctx: ProviderContext) -> list[Measured]:
    """The scenes the contractor flags master are the ones the checker names (JRC Table 9 "identify as
    master image"); not applicable when the checker names none."""
    d = ctx.delivery
    t = d.table("scenes")
    named = named_masters(ctx)
    if named is None:
        why = "the checker names no master image (parameter master_images)"
        return [
            Measured(
                "derived.master_images_agree",
                "delivery",
                "bool",
                pd.Series({d.id: None}, dtype=object),
                pd.Series({d.id: ()}, dtype=object),
                notes=pd.Series({d.id: why}, dtype=object),
                na=pd.Series({d.id: why}, dtype=object),
            )
        ]
    ids = t.ids.astype(str) if t is not None else pd.Series(dtype=str)
    flagged = sorted(ids[_flagged_master(t).to_numpy(bool)].tolist()) if t is not None else []
    unknown = [n for n in named if n not in set(ids.tolist())]
    problems = []
    if unknown:
        problems.append(
            f"named by the checker but no row of the scenes table: {', '.join(unknown)}"
        )
    if not_flagged := [n for n in named if n not in flagged and n not in unknown]:
        problems.append(f"named by the checker but not flagged is_master: {', '.join(not_flagged)}")
    if extra := [f for f in flagged if f not in named]:
        problems.append(f"flagged is_master but not named by the checker: {', '.join(extra)}")
    where = t.file if t is not None else "the delivery (no scenes table)"
    note = (
        f"{where}: " + "; ".join(problems)
        if problems
        else f"{where} flags is_master exactly the checker's master images ({', '.join(named)})"
    )
    ev = t.evidence(t.df["_row"]) if t is not None else (d.manifest_evidence("tables"),)
    return [
        Measured(
            "derived.master_images_agree",
            "delivery",
            "bool",
            pd.Series({d.id: not problems}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]


@provider(scope="delivery", measures=MASTER)
def master_images(ctx: ProviderContext) -> list[Measured]:
    """Number of scenes declared master image (JRC Table 9 "identify as master image").

    Not applicable when no scene shows a master-image workflow: §9.4 "only in rare cases will
    images be corrected to a "master image"", so a delivery corrected to absolute positions needs
    none. Any trace of one (a scene flagged ``is_master``, or ``master_image_id``,
    ``master_pixel_size`` or ``master_check_date`` filled) makes the declaration required, so
    clearing ``is_master`` on a checked master (red team R8) gives 0, not "not applicable"."""
    d = ctx.delivery
    t = d.table("scenes")
    na = None
    if t is None:
        value, ev, note = (
            None,
            (d.manifest_evidence("tables"),),
            "the manifest declares no 'scenes' table",
        )
        na = pd.Series(
            {d.id: "no scenes table: no satellite master image to identify"}, dtype=object
        )
    else:
        flag = _flagged_master(t)
        masters = t.ids.astype(str)[flag.to_numpy(bool)].tolist()
        traces = pd.Series(False, index=t.df.index)
        for col in MASTER_EVIDENCE:
            if col in t.df:
                traces |= t.df[col].map(_filled).astype(bool)
        traced = t.ids.astype(str)[traces.to_numpy(bool)].tolist()
        value = float(len(masters))
        ev = t.evidence(t.df["_row"][flag | traces] if masters or traced else t.df["_row"])
        if masters:
            note = f"master image(s) {', '.join(masters[:5])} ({t.file} is_master)"
        elif traced:
            note = (
                f"no row of {t.file} has is_master true, but scene(s) {', '.join(traced[:5])} record a master "
                f"image ({'/'.join(MASTER_EVIDENCE)})"
            )
        else:
            note = f"no scene of {t.file} is or refers to a master image"
            na = pd.Series(
                {
                    d.id: "no master-image workflow: no scene has is_master, master_image_id, "
                    "master_pixel_size or master_check_date (JRC §9.4: absolute correction)"
                },
                dtype=object,
            )
    return [
        Measured(
            "derived.master_images",
            "delivery",
            "1",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=na,
        )
    ]


@provider(scope="delivery", measures=PROJECT_CRS)
def project_crs_agrees(ctx: ProviderContext) -> list[Measured]:
    """The manifest's project.crs is the map projection in force (parameter map_crs, JRC Table 12)."""
    from ...delivery.crs import CrsProblem, same_crs

    d = ctx.delivery
    in_force = ctx.parameters.get("map_crs")
    declared = d.manifest.project.crs
    ev = (d.manifest_evidence("project.crs"),)
    na = None
    value: bool | None
    if in_force is None:
        value, note = (
            None,
            "no map projection in force (the profile's parameter map_crs has no value)",
        )
        na = pd.Series({d.id: note}, dtype=object)
    elif not declared:
        value, note = (
            False,
            (
                f"delivery.yaml states no project.crs: the CRS of its coordinates and block "
                f"outlines is not stated; the map projection in force is {in_force}"
            ),
        )
    else:
        try:
            value = same_crs(declared, in_force)
        except CrsProblem as exc:
            value, note = False, f"delivery.yaml project.crs: {exc}"
        else:
            note = (
                f"delivery.yaml project.crs {declared} is the map projection in force {in_force}"
                if value
                else f"delivery.yaml project.crs is {declared}, the map projection in force is {in_force}: the "
                "delivery's coordinates and block outlines are not in the ITT's projection"
            )
    return [
        Measured(
            "derived.project_crs_agrees",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=na,
        )
    ]


@provider(scope="dem", measures=DEM)
def dem_blocks(ctx: ProviderContext) -> list[Measured]:
    """Blocks each DEM serves: its `block` value, else its file's footprint over the block polygons."""
    from shapely.geometry import Polygon, box

    from ...raster.reading import open_read_only, read_only_env

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
    # the outlines in force: the checker's file's when it states blocks (red team R13), else the manifest's
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
    with read_only_env():
        for dem_id, blk, rel in zip(ids, blocks_col, files, strict=True):
            if (
                blk is not None
                and not (isinstance(blk, float) and np.isnan(blk))
                and str(blk).strip()
            ):
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
            try:
                with open_read_only(
                    d.path(str(rel), what=f"dem row for {dem_id}"), name=str(rel)
                ) as ds:
                    foot = box(*ds.bounds)
            except (OrthospecError, OSError) as exc:
                notes[dem_id] = f"cannot read the footprint of {rel}: {exc}"
                continue
            served = sorted(b for b, poly in polys.items() if foot.intersection(poly).area > 0)
            vals[dem_id] = ";".join(served) or None
            notes[dem_id] = (
                f"footprint of {rel} overlaps block(s) {', '.join(served)}"
                if served
                else f"footprint of {rel} overlaps no block polygon"
            )
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


def _table_metres(t: Any, col: str) -> pd.Series:
    """One numeric column of a table in metres, indexed by item id (first row per id)."""
    vals = convert(
        pd.to_numeric(t.df[col], errors="coerce").to_numpy(dtype=float), t.units.get(col, "m"), "m"
    )
    s = pd.Series(vals, index=t.ids.astype(str).to_numpy())
    return s[~s.index.duplicated()]


def _image_pansharpened(
    n_bands: int | None, gsd: float, ms: float, declared: bool | None
) -> tuple[bool | None, str]:
    """One image: pan-sharpened or not, and why (see :func:`pansharpened`)."""
    if n_bands is None:
        return None, "band count unknown (image file, images.bands or product.bands)"
    if n_bands < 2:
        return False, f"{n_bands} band: not a multispectral product"
    if not np.isfinite(gsd):
        return None, "no delivered pixel size (images.gsd or product.gsd)"
    if not np.isfinite(ms):
        return None, "no native multispectral pixel size: deliver scenes.ms_pixel_size"
    if gsd <= ms / PAN_MARGIN:
        return True, (
            f"{n_bands} bands at {gsd:.4g} m, finer than the {ms:.4g} m multispectral pixel / "
            f"{PAN_MARGIN:g}: the detail comes from the PAN band"
        )
    if gsd >= ms:
        return (
            False,
            f"{n_bands} bands at {gsd:.4g} m, not finer than the {ms:.4g} m multispectral pixel",
        )
    if declared is not None:
        return declared, (
            f"{n_bands} bands at {gsd:.4g} m, between the {ms:.4g} m multispectral pixel and "
            f"{ms / PAN_MARGIN:.4g} m (plain resampling possible): the declared "
            f"product.pansharpened decides"
        )
    return None, (
        f"{n_bands} bands at {gsd:.4g} m, between the {ms:.4g} m multispectral pixel and "
        f"{ms / PAN_MARGIN:.4g} m: the data do not decide and product.pansharpened is not declared"
    )


def _file_band_counts(ctx: ProviderContext, ids: list[str]) -> tuple[dict[str, int], list[Any]]:
    """Colour bands (alpha excluded) of the delivered image files of ``ids``: the file, not the
    declared ``images.bands``, decides whether the product is multispectral. Unreadable files are
    left to the declared bands (their own rules report them)."""
    from .rasters import scanned

    d = ctx.delivery
    imgs = d.table("images")
    if imgs is None or "file" not in imgs.df or not ids:
        return {}, []
    got = scanned(ctx)
    if "missing" in got:
        return {}, []
    out: dict[str, int] = {}
    ev: list[Any] = []
    for i in ids:
        f = got["facts"].get(i)
        if f is None or not f.readable or i in got["errors"]:
            continue
        out[i] = sum(1 for c in f.colorinterp if c != "alpha")
        ev.append(d.evidence(f.path))
    return out, ev


@provider(scope="delivery", measures=PANSHARPENED)
def pansharpened(ctx: ProviderContext) -> list[Measured]:
    """The delivered product is pan-sharpened (JRC §10.5), computed from bands and pixel sizes.

    Per image: true when the product is multispectral (>= 2 colour bands: in the delivered file,
    else ``images.bands``, else ``product.bands``) at a pixel size (``images.gsd``, else
    ``product.gsd``) at most the native
    multispectral pixel of its scene (``scenes.ms_pixel_size``) divided by 1.5. Resampling the MS
    bands alone to a grid a little finer than their own pixel (1.24 m -> 1.0 m for a round output
    pixel) is ordinary resampling, not fusion; but a product 1.5 x finer than the MS bands carries
    detail they do not have, and every VHR/HR pan/MS pair has a ratio of at least 2 (WorldView-3
    0.31/1.24 m, Pleiades 0.7/2.8 m, SPOT 6/7 1.5/6 m, Landsat 15/30 m), so a true pan-sharpened
    product is always on the true side of the margin. (A product merely upsampled 1.5 x from its MS
    bands also counts: §10.3 "preservation of the spatial resolution of the panchromatic image" is
    then exactly what the inspector must look at.) False for a single-band product or one not
    finer than the MS pixel; between the two the data do not decide and the declared
    ``product.pansharpened`` is used (with a note), else missing. The delivery is pan-sharpened when
    any image is; false when every image is decided false; else missing with the column to deliver.
    """
    d = ctx.delivery
    m = d.manifest
    imgs, scenes = d.table("images"), d.table("scenes")
    declared = getattr(m.product, "pansharpened", None)
    ev: list[Any] = [
        d.manifest_evidence("product.bands"),
        d.manifest_evidence("product.gsd"),
        d.manifest_evidence("product.pansharpened"),
    ]
    ev += [e for t in (imgs, scenes) if t is not None for e in t.evidence(t.df["_row"])]
    ids: list[str] = sorted(set(imgs.ids.astype(str)) if imgs is not None else set())
    if scenes is not None:
        ids = sorted(set(ids) | set(scenes.ids.astype(str)))
    product_bands = len(m.product.bands) if m.product.bands else None
    gsd_default = d.gsd_m if d.gsd_m is not None else np.nan
    gsd = pd.Series(gsd_default, index=ids, dtype=float)
    bands: dict[str, int | None] = {i: product_bands for i in ids}
    if imgs is not None and "gsd" in imgs.df:
        g = _table_metres(imgs, "gsd").reindex(ids)
        gsd[g.notna()] = g[g.notna()]
    if imgs is not None and "bands" in imgs.df:
        col = pd.Series(imgs.df["bands"].to_numpy(), index=imgs.ids.astype(str).to_numpy())
        for i, v in col[~col.index.duplicated()].items():
            parts = [b for b in str(v).split(";") if b.strip()] if isinstance(v, str) else []
            if parts:
                bands[i] = len(parts)
    ms = (
        _table_metres(scenes, "ms_pixel_size").reindex(ids)
        if scenes is not None and "ms_pixel_size" in scenes.df
        else pd.Series(np.nan, index=ids, dtype=float)
    )
    file_bands, file_ev = _file_band_counts(ctx, [i for i in ids if np.isfinite(ms[i])])
    ev += file_ev
    bands.update(file_bands)
    per = {i: _image_pansharpened(bands[i], float(gsd[i]), float(ms[i]), declared) for i in ids}
    yes = [i for i, (v, _) in per.items() if v is True]
    undecided = [i for i, (v, _) in per.items() if v is None]
    if not ids:
        value: bool | None = None
        note = "the delivery has no images or scenes table: pan-sharpening cannot be computed"
    elif yes:
        value, note = (
            True,
            f"{len(yes)} of {len(ids)} image(s) pan-sharpened, e.g. {yes[0]}: {per[yes[0]][1]}",
        )
    elif undecided:
        value, note = (
            None,
            f"{len(undecided)} image(s) undecided, e.g. {undecided[0]}: {per[undecided[0]][1]}",
        )
    else:
        value, note = False, f"no image pan-sharpened, e.g. {ids[0]}: {per[ids[0]][1]}"
    agrees: bool | None = None if declared is None or value is None else bool(declared) == value
    if agrees is False:
        note += f"; the manifest declares product.pansharpened: {str(declared).lower()}, which the data contradict"
    agree_note = (
        f"declared {str(declared).lower()}, computed {str(value).lower()}"
        if agrees is not None
        else "product.pansharpened not declared"
        if declared is None
        else "the computed value is missing"
    )
    na = (
        pd.Series({d.id: "the contractor declares no product.pansharpened"}, dtype=object)
        if declared is None
        else None
    )
    evidence = pd.Series({d.id: tuple(ev)}, dtype=object)
    return [
        Measured(
            "derived.pansharpened",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            evidence,
            notes=pd.Series({d.id: note}, dtype=object),
        ),
        Measured(
            "derived.pansharpened_agrees",
            "delivery",
            "bool",
            pd.Series({d.id: agrees}, dtype=object),
            evidence,
            notes=pd.Series({d.id: agree_note}, dtype=object),
            na=na,
        ),
    ]


DEM_PRESENCE = {
    "derived.dem_delivered": "bool",
    "derived.dem_used": "bool",
    "derived.dem_delivered_agrees": "bool",
}
#: scenes columns that record a DEM used to orthorectify the scene (JRC Table 7 "DEM", §9.5)
SCENE_DEM_COLUMNS = ("dem_grid_size", "dem_accuracy", "dem_qc_result")


@provider(scope="delivery", measures=DEM_PRESENCE)
def dem_presence(ctx: ProviderContext) -> list[Measured]:
    """Whether a DEM is delivered and whether one was used, from the files (issue 25, "flags that switch
    rules off"), never from ``product.dem_delivered`` alone.

    * ``derived.dem_delivered``: the dem table names a DEM file (the delivery lists a DEM among its
      files: JRC §12.7 "Where the DEM is also a deliverable"), or the manifest declares
      ``product.dem_delivered: true`` (an admission is never ignored). The note says whether each named
      file is present and readable.
    * ``derived.dem_used``: a DEM is delivered, or the dem table has rows, or a scene records the DEM it
      was orthorectified with (``scenes.dem_grid_size``, ``dem_accuracy``, ``dem_qc_result``): the
      DEM checks of Tables 5 and 7 then apply, whatever tables the contractor removed.
    * ``derived.dem_delivered_agrees``: the declared ``product.dem_delivered`` is the computed fact
      (not applicable when nothing is declared).
    """
    from ...raster.facts import read_facts

    d = ctx.delivery
    t = d.table("dem")
    scenes = d.table("scenes")
    declared = getattr(d.manifest.product, "dem_delivered", None)
    ev: list[Any] = [d.manifest_evidence("product.dem_delivered")]
    named: list[str] = []
    if t is not None:
        ev += list(t.evidence(t.df["_row"]))
        if "file" in t.df:
            named = [str(v).strip() for v in t.df["file"].tolist() if _filled(v)]
    states = []
    for rel in named:
        try:
            f = read_facts(d.path(rel, what="dem file"), sha256=False, name=rel)
        except OrthospecError as exc:
            states.append(f"{rel}: {exc}")
            continue
        states.append(f"{rel} ({'readable' if f.readable else f.error})")
    recorded: list[str] = []
    if scenes is not None:
        cols = [c for c in SCENE_DEM_COLUMNS if c in scenes.df]
        for col in cols:
            hit = scenes.df[col].map(_filled).astype(bool)
            if hit.any():
                recorded += scenes.ids.astype(str)[hit.to_numpy(bool)].tolist()
                ev += list(scenes.evidence(scenes.df["_row"][hit]))
    recorded = sorted(set(recorded))
    delivered = bool(named) or declared is True
    used = delivered or (t is not None and len(t.df) > 0) or bool(recorded)
    parts = []
    if named:
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
    note = "; ".join(parts)
    agrees = None if declared is None else bool(declared) == delivered
    agree_note = (
        "product.dem_delivered not declared"
        if declared is None
        else f"declared {str(declared).lower()}, the files say {str(delivered).lower()} ({parts[0]})"
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


CAMERA = {"derived.camera_agrees": "bool"}


@provider(scope="camera", measures=CAMERA)
def camera_agrees(ctx: ProviderContext) -> list[Measured]:
    """The declared format and pixel size of a camera are its model's published ones (specs/cameras.yaml,
    Passini, Jacobsen & Day Table 1). The photo lay-down (derived.photo_coverage) uses the published
    values for a listed model whatever the table declares (issue 25: a format declared 3 x larger hid a
    missing strip); this measure reports the declaration the table contradicts. Not applicable to a
    model the table does not list."""
    t = ctx.delivery.table("cameras")
    if t is None:
        empty = pd.Series(dtype=object)
        return [Measured("derived.camera_agrees", "camera", "bool", empty, empty.copy())]
    ids = t.ids.astype(str).tolist()
    values: dict[str, bool | None] = {}
    notes: dict[str, str] = {}
    na: dict[str, str] = {}
    for k, i in enumerate(ids):
        row = t.df.iloc[k]
        model = row.get("model") if "model" in t.df else None
        known = known_camera(model)
        if known is None:
            values[i] = None
            na[i] = f"camera model {model!r} is not in the published table (specs/cameras.yaml)"
            continue
        problems = []
        declared = sorted(float(row[c]) for c in FORMAT_COLUMNS if c in t.df and _filled(row[c]))
        if len(declared) == 2 and declared != sorted(float(v) for v in known["pixels"]):
            problems.append(
                f"format {declared[1]:.0f} x {declared[0]:.0f} px declared, the {known['id']}'s is "
                f"{max(known['pixels'])} x {min(known['pixels'])} px"
            )
        if "pixel_size" in t.df and _filled(row["pixel_size"]):
            px = float(
                convert(
                    np.array([float(row["pixel_size"])]), t.units.get("pixel_size", "µm"), "µm"
                )[0]
            )
            if abs(px - known["pixel_size_um"]) > 0.01 * known["pixel_size_um"]:
                problems.append(
                    f"pixel {px:g} µm declared, the {known['id']}'s is {known['pixel_size_um']:g} µm"
                )
        values[i] = not problems
        notes[i] = (
            (
                "; ".join(problems)
                + " (Passini, Jacobsen & Day Table 1): the photo lay-down uses the "
                "published values"
            )
            if problems
            else f"declared format and pixel are the {known['id']}'s"
        )
    rows = pd.Series(t.df["_row"].to_numpy(), index=ids)
    return [
        Measured(
            "derived.camera_agrees",
            "camera",
            "bool",
            pd.Series(values, dtype=object),
            RowEvidence(t.file, t.sha256, rows),
            notes=pd.Series(notes, dtype=object),
            na=pd.Series(na, dtype=object) if na else None,
        )
    ]
