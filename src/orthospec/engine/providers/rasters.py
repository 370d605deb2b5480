"""Image-scope measures read from the delivered rasters themselves (JRC §3.2, §6.3-§6.5, §9.2).

One parallel pass (worker processes or Dask) over the files the images table lists; a file that
is missing, empty or corrupt gives `readable = false` and `error` for every other measure of that
image, and the rest of the delivery is still checked.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ...delivery.crs import CrsProblem, epsg_name
from ...errors import OrthospecError
from ...measures.copies import Content, find_copies
from ...provenance import Evidence
from ...raster.facts import RasterFacts
from ...raster.filechecks import check_name, listing_consistency
from ...raster.parallel import ImageReport, make_progress, scan_images
from ...units import convert
from ..registry import Measured, ProviderContext, provider

IMAGE_MEASURES: dict[str, str] = {
    "raster.exists": "bool",
    "raster.readable": "bool",
    "raster.format": "text",
    "raster.compression": "text",
    "raster.lossless": "bool",
    "raster.tiled": "bool",
    "raster.bit_depth": "1",
    "raster.bit_depth_container": "1",
    "raster.used_bits": "1",
    "raster.band_count": "1",
    "raster.bands": "text",
    "raster.crs_epsg": "1",
    "raster.crs_ok": "bool",
    "raster.pixel_size": "m",
    "raster.pixel_size_diff": "%",
    "raster.nodata_declared": "bool",
    "raster.nodata_share": "%",
    "raster.name_ok": "bool",
    "raster.georeferenced": "bool",
    "raster.saturation_low": "%",
    "raster.saturation_high": "%",
    "raster.saturation_low_max_band": "%",
    "raster.saturation_high_max_band": "%",
    "raster.cv_percent_min": "%",
    "raster.cv_percent_max": "%",
    "raster.cv_percent": "%",
    "raster.std_max": "DN",
    "raster.noise_std": "DN",
    "raster.noise_std_8bit": "DN",
    "raster.dark_margin": "%",
    "raster.bright_margin": "%",
    "raster.misregistration": "px",
    "raster.mean_dn": "DN",
    "raster.std_dn": "DN",
    "raster.reported_mean_diff": "DN",
    "raster.reported_std_diff": "DN",
    # issue 25: declared image values compared with what the file and its pixels say
    "raster.gsd_declared_diff": "%",
    "raster.bit_depth_agrees": "bool",
    "raster.reported_min_diff": "DN",
    "raster.reported_max_diff": "DN",
    "raster.cloud_cover": "%",
    "raster.cloud_cover_declared_diff": "%",
    "raster.nonfinite_pixels": "1",
}
DELIVERY_MEASURES = {"raster.unlisted_files": "1", "raster.listed_missing": "1"}
CLOUD_MEAN = {"raster.cloud_cover_mean": "%"}
#: measures whose rules judge delivered files only (`when: raster.exists == true`): an absent file's
#: "not found" is JRC-9.2-T7-READABLE's finding, not an error of theirs
EXISTING_ONLY = frozenset({"raster.gsd_declared_diff"})
DUPLICATE_MEASURES = {"raster.file_unique": "bool"}
CONTENT_MEASURES = {"raster.content_unique": "bool"}
#: images.csv columns compared with what the file says (declared image values, issue 25)
DECLARED_COLUMNS = ("mean_dn", "std_dn", "min_dn", "max_dn", "gsd", "bit_depth", "cloud_cover")
SMALL_DELIVERY_BYTES = 64 << 20
_IMAGE_EXT = {
    ".tif",
    ".tiff",
    ".jp2",
    ".j2k",
    ".img",
    ".vrt",
    ".png",
    ".jpg",
    ".jpeg",
    ".ecw",
    ".sid",
}


def _epsg(text: str | None) -> int | None:
    """EPSG code of the map projection in force (parameter ``map_crs``), or None when the profile
    states none: ``raster.crs_ok`` is then unknown (missing), never a comparison with the manifest's
    ``project.crs``, which is the contractor's (red team R16)."""
    if not text:
        return None
    try:
        return int(epsg_name(text).split(":", 1)[1])
    except CrsProblem:
        return None


def _pooled(bands: list[dict[str, Any]]) -> tuple[float | None, float | None]:
    """Mean and population std over all bands' valid pixels, exactly, from per-band moments."""
    n = sum(b.get("valid") or 0 for b in bands)
    if not n:
        return None, None
    mean = sum((b["valid"] or 0) * b["mean"] for b in bands if b.get("mean") is not None) / n
    ex2 = (
        sum(
            (b["valid"] or 0) * (b["std"] ** 2 + b["mean"] ** 2)
            for b in bands
            if b.get("mean") is not None
        )
        / n
    )
    return mean, math.sqrt(max(ex2 - mean * mean, 0.0))


def scanned(ctx: ProviderContext) -> dict[str, Any]:
    """The one scan of the listed images in this run (memoised): ``frame`` (measure values), ``facts``
    (image id -> :class:`RasterFacts`), ``pixels`` (content hash, thumbnail), ``errors``, ``table``...;
    ``{"missing": why}`` when the delivery has no images table. Other providers read the files'
    facts here instead of opening the files again."""
    return _scan(ctx)


def _scan(ctx: ProviderContext) -> dict[str, Any]:
    """Scan every listed image once; keep only each image's measure values (one table).

    Each report is reduced to its row of measure values as it arrives (scan_images' on_report)
    and dropped: the run holds one small row per image, not its checks, histograms and bands.
    """
    if "rasters" in ctx.memo:
        return ctx.memo["rasters"]
    d = ctx.delivery
    t = d.table("images")
    if t is None:
        ctx.memo["rasters"] = {"missing": "the manifest declares no 'images' table"}
        return ctx.memo["rasters"]
    ids = t.ids.tolist()
    files = t.df["file"].astype(str).tolist()
    paths: dict[str, Path | OrthospecError] = {}
    jailed: dict[str, Path] = {}  # file text -> its checked path: each distinct text checked once
    for i, f in zip(ids, files, strict=True):
        if f in jailed:
            paths[i] = jailed[f]
            continue
        try:
            paths[i] = jailed[f] = d.path(f, what=f"images row for {i}")
        except OrthospecError as exc:  # path escaping the delivery: an error for that image only
            paths[i] = exc
    is_file = {f: p.is_file() for f, p in jailed.items()}
    text = dict(zip(ids, files, strict=True))
    existing = {
        i: p for i, p in paths.items() if not isinstance(p, OrthospecError) and is_file[text[i]]
    }
    scanned = list(existing)
    # one scan per file: rows naming one file (a table padded with 10^5 rows) share its report
    resolved: dict[str, Path] = {}  # path text -> the file it names (rows often repeat one text)
    by_file: dict[Path, list[int]] = {}
    for k, p in enumerate(existing.values()):
        key = resolved.get(str(p)) or resolved.setdefault(str(p), p.resolve())
        by_file.setdefault(key, []).append(k)
    scan_paths = [existing[scanned[ks[0]]] for ks in by_file.values()]
    scan_rows = list(by_file.values())
    product = d.manifest.product
    opts = ctx.options
    progress = make_progress() if opts.progress else None
    workers = opts.workers
    if workers is None and sum(p.stat().st_size for p in scan_paths) < SMALL_DELIVERY_BYTES:
        workers = 1  # process start-up costs more than it saves on a small delivery
    reported = {k: t.df[k].tolist() for k in DECLARED_COLUMNS if k in t.df.columns}
    if "gsd" in reported:  # in metres, like the pixel size it is compared with
        reported["gsd"] = convert(
            pd.to_numeric(t.df["gsd"], errors="coerce").to_numpy(float),
            t.units.get("gsd", "m"),
            "m",
        ).tolist()
    where = dict(zip(ids, range(len(ids)), strict=True))
    gsd = d.gsd_m
    rows: list[tuple[Any, ...] | None] = [None] * len(scanned)
    errors: dict[str, str] = {}
    sha: dict[str, str] = {}
    facts: dict[str, RasterFacts] = {}
    pixels: dict[str, dict[str, Any]] = {}
    notes: dict[str, dict[str, str]] = {}
    wkts: dict[str, str] = {}
    declared = {"gsd": gsd, "bit_depth": product.bit_depth}
    # scans run (possibly in other processes) on absolute paths; what enters the QCR is relative
    # to the delivery root, so qcr.json does not depend on where the delivery or the caller is
    root_prefix = f"{d.root}{os.sep}"

    def collect(k_file: int, rep: ImageReport) -> None:
        # what depends on the file only is built once per file, then shared by the rows naming it
        fact = None
        if rep.facts is not None:
            f = RasterFacts.from_dict(rep.facts)
            wkt = (
                f.crs_wkt if f.crs_wkt is None else wkts.setdefault(f.crs_wkt, f.crs_wkt)
            )  # one copy per CRS
            fact = replace(
                f,
                crs_wkt=wkt,
                path=Path(f.path).relative_to(d.root).as_posix()
                if f.path.startswith(root_prefix)
                else f.path,
            )
        radiometry = rep.radiometry or {}
        thumb = radiometry.get("thumbnail")
        pixel = {
            "hash": radiometry.get("pixels_hash"),
            "cell": radiometry.get("thumbnail_cell_px"),
            "thumb": None
            if thumb is None
            else np.array(
                [[np.nan if v is None else v for v in row] for row in thumb], dtype=np.float32
            ),
        }
        flat = rep.to_dict()
        if rep.sha256:
            d.remember_sha256(Path(rep.path).relative_to(d.root).as_posix(), rep.sha256)
        for k in scan_rows[k_file]:
            collect_row(k, rep, fact, pixel, flat)

    def collect_row(
        k: int,
        rep: ImageReport,
        fact: RasterFacts | None,
        pixel: dict[str, Any],
        flat: dict[str, Any],
    ) -> None:
        item = scanned[k]
        if rep.sha256:
            sha[item] = rep.sha256
        rep_reported = {}
        for key, column in reported.items():
            v = column[where[item]]
            if v is not None and not pd.isna(v):
                rep_reported[key] = v
        if fact is not None:
            facts[item] = fact
        pixels[item] = pixel
        vals = _values(rep, rep_reported, declared, flat)
        for name, text in _value_notes(rep, rep_reported, declared, vals).items():
            notes.setdefault(name, {})[item] = text
        if rep.error is not None:
            errors[item] = rep.error.replace(root_prefix, "")
            vals = {n: None for n in IMAGE_MEASURES} | {
                "raster.exists": True,
                "raster.readable": False,
                "raster.name_ok": vals["raster.name_ok"],
            }
        rows[k] = tuple(vals.get(n) for n in IMAGE_MEASURES)

    scan_images(
        [str(p) for p in scan_paths],
        workers=workers or None,
        scheduler=opts.scheduler,
        cache_dir=opts.cache_dir,
        bit_depth=product.bit_depth,
        progress=progress,
        expect_epsg=_epsg(ctx.parameters.get("map_crs")),
        expect_gsd=gsd,
        on_report=collect,
    )
    absent = [i for i in ids if i not in existing]
    for i in absent:
        listed = paths[i]
        errors[i] = (
            str(listed)
            if isinstance(listed, OrthospecError)
            else f"{files[where[i]]}: listed in {t.file} but not found in the delivery"
        )
        rows.append(
            tuple(
                False if n in ("raster.exists", "raster.readable") else None for n in IMAGE_MEASURES
            )
        )
    # dtype object keeps each value as measured (an int stays an int, None stays None)
    frame = pd.DataFrame(
        rows,
        index=pd.Index(scanned + absent, dtype=object),
        columns=list(IMAGE_MEASURES),
        dtype=object,
    )
    errors = {i: errors[i] for i in frame.index if i in errors}  # table order, not completion order
    on_disk = sorted(
        p.relative_to(d.root).as_posix()
        for p in d.root.rglob("*")
        if p.is_file() and p.suffix.lower() in _IMAGE_EXT
    )
    listing = listing_consistency(files, on_disk)
    ctx.memo["rasters"] = {
        "frame": frame,
        "errors": errors,
        "sha256": sha,
        "paths": paths,
        "rows": dict(zip(ids, t.df["_row"], strict=True)),
        "table": t,
        "resolved": resolved,
        "listing": listing,
        "facts": facts,
        "pixels": pixels,
        "notes": notes,
    }
    return ctx.memo["rasters"]


def _declared_vs_file(
    rep: ImageReport,
    reported: dict[str, Any],
    declared: dict[str, Any],
    bands: list[dict[str, Any]],
) -> dict[str, Any]:
    """The image values a row (else the manifest) declares, compared with what its file says."""
    facts = rep.facts or {}
    radiometry = rep.radiometry or {}
    out: dict[str, Any] = {}
    size, metres = facts.get("pixel_size"), facts.get("unit_metres")
    said = reported.get("gsd", declared.get("gsd"))
    if size and metres and said is not None and said > 0:
        out["raster.gsd_declared_diff"] = max(
            abs(said - v * metres) / (v * metres) * 100.0 for v in size
        )
    bits = reported.get("bit_depth", declared.get("bit_depth"))
    if bits is not None and facts.get("bit_depth_container") is not None:
        nbits, container = facts.get("nbits"), facts["bit_depth_container"]
        used = max((b.get("used_bits") or 0 for b in bands), default=0)
        out["raster.bit_depth_agrees"] = (
            (int(bits) == nbits) if nbits else bool(used <= bits <= container)
        )
    lows = [b["min"] for b in bands if b.get("min") is not None]
    highs = [b["max"] for b in bands if b.get("max") is not None]
    if lows and reported.get("min_dn") is not None:
        out["raster.reported_min_diff"] = abs(min(lows) - reported["min_dn"])
    if highs and reported.get("max_dn") is not None:
        out["raster.reported_max_diff"] = abs(max(highs) - reported["max_dn"])
    cloud = radiometry.get("cloud_pct")
    out["raster.cloud_cover"] = cloud
    if cloud is not None and reported.get("cloud_cover") is not None:
        out["raster.cloud_cover_declared_diff"] = abs(cloud - reported["cloud_cover"])
    return out


def _value_notes(
    rep: ImageReport, reported: dict[str, Any], declared: dict[str, Any], vals: dict[str, Any]
) -> dict[str, str]:
    """Why a declared-vs-file value is what it is (shown in the record)."""
    out: dict[str, str] = {}
    facts = rep.facts or {}
    size, metres = facts.get("pixel_size"), facts.get("unit_metres")
    said = reported.get("gsd", declared.get("gsd"))
    source = "images.gsd" if "gsd" in reported else "delivery.yaml product.gsd"
    if vals.get("raster.gsd_declared_diff") is not None:
        px = " x ".join(f"{v * metres:.6g}" for v in size or ())
        out["raster.gsd_declared_diff"] = (
            f"declared {said:.6g} m ({source}), the file's pixel is {px} m"
        )
    elif size and not metres:
        out["raster.gsd_declared_diff"] = (
            f"the file's CRS has no length unit ({facts.get('pixel_unit')}): no pixel size in metres"
        )
    elif said is None:
        out["raster.gsd_declared_diff"] = "no GSD declared (images.gsd or product.gsd)"
    if vals.get("raster.bit_depth_agrees") is not None:
        bits = reported.get("bit_depth", declared.get("bit_depth"))
        nb = facts.get("nbits")
        used = max(
            (b.get("used_bits") or 0 for b in (rep.radiometry or {}).get("bands", [])), default=0
        )
        out["raster.bit_depth_agrees"] = (
            f"declared {bits:g} bits; the file states NBITS={nb}"
            if nb
            else f"declared {bits:g} bits; the file holds {facts.get('dtypes', ['?'])[0]} samples "
            f"({facts.get('bit_depth_container')}-bit container) using {used} bits"
        )
    cloud = vals.get("raster.cloud_cover")
    radiometry = rep.radiometry or {}
    if cloud is not None:
        text = (
            f"measured {cloud:.2f} % bright, white pixels (cloud, or snow: red, green and blue cannot tell "
            f"them apart) on {radiometry.get('cloud_samples')} sampled pixels"
        )
        if reported.get("cloud_cover") is not None:
            text += f"; declared {reported['cloud_cover']:g} % (images.cloud_cover)"
        out["raster.cloud_cover"] = out["raster.cloud_cover_declared_diff"] = text
    elif radiometry:
        out["raster.cloud_cover"] = (
            "no red, green and blue bands with a known grey range: cloud cover not measured"
        )
    low = radiometry.get("low_nodata")
    if low:
        bands = ", ".join(low.get("bands") or [])
        if low.get("pixels_nodata_in_every_band"):
            told = [v for v in (low.get("saturation_low_told_pct") or {}).values() if v is not None]
            out["raster.saturation_low_max_band"] = (
                f"band(s) {bands}: the nodata value is the lowest grey level, and "
                f"{low['pixels_nodata_in_every_band_pct']:.3f} % of the pixels are at it in every band: saturated "
                "black and no-data cannot be told apart there (at least "
                f"{max(told, default=0.0):.3f} % of the other pixels are saturated black in one band)"
            )
        else:
            out["raster.saturation_low_max_band"] = (
                f"band(s) {bands}: the nodata value is the lowest grey level; no pixel is at it in every band, so "
                "each pixel at it is saturated black, not no-data (counted)"
            )
    return out


def _saturation_low(d: dict[str, Any], low_nodata: dict[str, Any] | None) -> float | None:
    """Worst band's dark-tail share; where a band's nodata is its lowest grey level (issue 26), the
    share of pixels at that level while another band is valid; missing when some pixels are at
    nodata in every band (saturated black and no-data cannot be told apart there)."""
    worst = d.get("image.saturation_low_pct_max_band")
    if not low_nodata:
        return worst
    if low_nodata.get("pixels_nodata_in_every_band"):
        return None
    told = [v for v in (low_nodata.get("saturation_low_told_pct") or {}).values() if v is not None]
    return max([v for v in (worst, *told) if v is not None], default=None)


def _values(
    rep: ImageReport,
    reported: dict[str, Any],
    declared: dict[str, Any],
    flat: dict[str, Any] | None = None,
) -> dict[str, Any]:
    d = rep.to_dict() if flat is None else flat
    gsd = declared.get("gsd")
    bands = (rep.radiometry or {}).get("bands", [])
    mean, std = _pooled(bands)
    bit_depth = (
        max((b.get("bit_depth") or 0 for b in bands), default=None)
        or d.get("nbits")
        or d.get("bit_depth_container")
    )
    noise = d.get("image.noise_sigma_homogeneous_max")
    scale = 255.0 / (2**bit_depth - 1) if bit_depth else None
    ps = d.get("pixel_size_x")
    out = {
        "raster.exists": True,
        "raster.readable": rep.error is None,
        "raster.format": d.get("driver"),
        "raster.compression": d.get("compression"),
        "raster.lossless": d.get("lossless"),
        "raster.tiled": None if d.get("layout") is None else d.get("layout") == "tiled",
        "raster.bit_depth": bit_depth,
        "raster.bit_depth_container": d.get("bit_depth_container"),
        "raster.used_bits": d.get("image.used_bits_max"),
        "raster.band_count": d.get("band_count"),
        "raster.bands": ";".join(d.get("colour_interpretation") or []) or None,
        "raster.crs_epsg": d.get("epsg"),
        "raster.crs_ok": d.get("crs_ok"),
        "raster.georeferenced": d.get("crs") is not None,
        "raster.pixel_size": ps if d.get("pixel_size_unit") in ("metre", "meter", "m") else None,
        "raster.pixel_size_diff": (abs(ps - gsd) / gsd * 100.0) if ps and gsd else None,
        "raster.nodata_declared": d.get("nodata_declared"),
        "raster.nodata_share": None
        if d.get("image.nodata_fraction") is None
        else 100.0 * d["image.nodata_fraction"],
        "raster.name_ok": d.get("name_ok"),
        "raster.nonfinite_pixels": d.get("image.nonfinite_pixels", 0 if rep.radiometry else None),
        "raster.saturation_low": d.get("image.saturation_low_pct"),
        "raster.saturation_high": d.get("image.saturation_high_pct"),
        "raster.saturation_low_max_band": _saturation_low(
            d, (rep.radiometry or {}).get("low_nodata")
        ),
        "raster.saturation_high_max_band": d.get("image.saturation_high_pct_max_band"),
        "raster.cv_percent_min": d.get("image.cv_percent_min"),
        "raster.cv_percent_max": d.get("image.cv_percent_max"),
        "raster.cv_percent": d.get("luminosity.cv_percent", d.get("image.cv_percent_min")),
        "raster.std_max": d.get("image.std_max"),
        "raster.noise_std": noise,
        "raster.noise_std_8bit": None if noise is None or scale is None else noise * scale,
        "raster.dark_margin": d.get("image.dark_margin_pct_min"),
        "raster.bright_margin": d.get("image.bright_margin_pct_min"),
        "raster.misregistration": d.get("image.misregistration_px_max"),
        "raster.mean_dn": mean,
        "raster.std_dn": std,
        "raster.reported_mean_diff": None
        if mean is None or reported.get("mean_dn") is None
        else abs(mean - reported["mean_dn"]),
        "raster.reported_std_diff": None
        if std is None or reported.get("std_dn") is None
        else abs(std - reported["std_dn"]),
    }
    out.update(_declared_vs_file(rep, reported, declared, bands))
    return out


@provider(scope="image", measures=IMAGE_MEASURES)
def raster_measures(ctx: ProviderContext) -> list[Measured]:
    """File checks and exact radiometry of every listed image (streamed, parallel, cached)."""
    got = _scan(ctx)
    if "missing" in got:
        return [
            Measured(
                n,
                "image",
                u,
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": got["missing"]}, dtype=object),
            )
            for n, u in IMAGE_MEASURES.items()
        ]
    t = got["table"]
    frame: pd.DataFrame = got["frame"]
    errors: dict[str, str] = got["errors"]
    listed_files = dict(zip(t.ids.tolist(), t.df["file"].tolist(), strict=True))
    evidence: dict[str, tuple[Evidence, ...]] = {}
    name_notes: dict[str, str] = {}
    names_ok: dict[str, bool] = {}
    for item in frame.index:
        listed = Evidence(t.file, t.sha256, (int(got["rows"][item]),))
        rel = listed_files[item]
        name = check_name(str(rel).replace("\\", "/").rsplit("/", 1)[-1])
        if not name.ok:
            name_notes[item] = f"file name {name.name!r}: " + "; ".join(name.problems)
        if (
            frame.at[item, "raster.exists"] is False
        ):  # listed, not in the delivery: no file evidence
            evidence[item] = (listed,)
            names_ok[item] = name.ok
        else:
            evidence[item] = (listed, Evidence(str(rel), got["sha256"].get(item, ""), ()))
    values = {n: frame[n].to_dict() for n in IMAGE_MEASURES}
    values["raster.name_ok"].update(names_ok)
    out = []
    ev = pd.Series(evidence, dtype=object)
    value_notes: dict[str, dict[str, str]] = got.get("notes", {})
    for n, u in IMAGE_MEASURES.items():
        errs = None
        if errors and n not in ("raster.exists", "raster.readable", "raster.name_ok"):
            errs = pd.Series(errors, dtype=object)
            if (
                n in EXISTING_ONLY
            ):  # its rule applies to delivered files only: an absent one is no error here
                errs = errs[[frame.at[i, "raster.exists"] is not False for i in errs.index]]
        notes = (
            pd.Series(errors, dtype=object)
            if errors and n in ("raster.exists", "raster.readable")
            else None
        )
        if n == "raster.name_ok" and name_notes:
            notes = pd.Series(name_notes, dtype=object)
        elif n in value_notes:
            notes = pd.Series(value_notes[n], dtype=object)
        out.append(
            Measured(
                n, "image", u, pd.Series(values[n], dtype=object), ev, notes=notes, errors=errs
            )
        )
    return out


#: names a note lists of the other rows sharing a file or a content; the rest are counted
NAMES_SHOWN = 5


def _names(shown: list[str], total: int) -> str:
    return ", ".join(shown) + (f" and {total - len(shown)} more" if total > len(shown) else "")


def _sharing(
    ids: list[str],
    files: dict[str, str],
    file_key: dict[str, Any],
    sha: dict[str, str],
) -> dict[str, list[str]]:
    """item -> why its row is not its own file: the other rows naming the same file, the rows whose
    file has the same content (SHA-256), each list capped at NAMES_SHOWN names and counted.

    Linear in the rows: rows are grouped once by file and by content, and each row's note is drawn
    from its groups' first members (a group of 10^5 rows naming one file costs 10^5, not 10^10).
    """
    by_file: dict[Any, list[str]] = {}
    by_sha: dict[str, dict[Any, list[str]]] = {}  # content -> file -> rows, in table order
    for i in ids:
        k = file_key.get(i)
        if k is not None:
            by_file.setdefault(k, []).append(i)
        if sha.get(i) is not None:
            by_sha.setdefault(sha[i], {}).setdefault(k, []).append(i)
    why: dict[str, list[str]] = {}
    for i in ids:
        k = file_key.get(i)
        reasons = []
        same = by_file.get(k, []) if k is not None else []
        if len(same) > 1:
            shown = [j for j in same[: NAMES_SHOWN + 1] if j != i][:NAMES_SHOWN]
            reasons.append(
                f"names the same file {files[i]} as image(s) {_names(shown, len(same) - 1)}"
            )
        digest = sha.get(i)
        if digest is not None:
            groups = by_sha[digest]
            total = sum(len(g) for g in groups.values()) - len(groups.get(k, []))
            if total:
                shown = []
                for other, rows in groups.items():  # at most NAMES_SHOWN + 1 groups are visited
                    if other == k:
                        continue
                    shown.extend(rows[: NAMES_SHOWN - len(shown)])
                    if len(shown) == NAMES_SHOWN:
                        break
                reasons.append(
                    f"its file {files[i]} has the same content (SHA-256 {digest}) as the file of "
                    f"image(s) {_names([f'{j} ({files[j]})' for j in shown], total)}"
                )
        if reasons:
            why[i] = reasons
    return why


def _unique_prefix(
    got: dict[str, Any],
) -> tuple[
    list[str], dict[str, str], dict[str, Any], dict[str, tuple[Evidence, ...]], dict[str, list[str]]
]:
    """What file_unique and content_unique share: rows, files, file keys, evidence, same-file/content notes."""
    t = got["table"]
    ids = [str(i) for i in t.ids.tolist()]
    resolved: dict[str, Path] = got["resolved"]
    file_key = {
        str(i): resolved.get(str(p)) or resolved.setdefault(str(p), p.resolve())
        for i, p in got["paths"].items()
        if isinstance(p, Path)
    }
    files = dict(zip(ids, t.df["file"].astype(str).tolist(), strict=True))
    sha: dict[str, str] = got["sha256"]
    evidence: dict[str, tuple[Evidence, ...]] = {}
    for i in ids:
        listed = Evidence(t.file, t.sha256, (int(got["rows"][i]),))
        digest = sha.get(i)
        evidence[i] = (listed,) + ((Evidence(files[i], digest, ()),) if digest else ())
    return ids, files, file_key, evidence, _sharing(ids, files, file_key, sha)


@provider(scope="image", measures=DUPLICATE_MEASURES)
def duplicate_measures(ctx: ProviderContext) -> list[Measured]:
    """Each image row has a file of its own (red team R12; JRC §12.4 Table 12, §6.4).

    Two rows naming one file, or two files with the same SHA-256 (a missing image replaced by a
    copy of its neighbour), cannot both be the ortho-image of their own ground: ``False`` on
    every such row, the note naming the other image(s). A file that is absent or was not hashed
    (empty, unreadable) has no content to compare: ``None`` (the rule is ``missing``), unless
    its row names the same file as another row.
    """
    got = _scan(ctx)
    if "missing" in got:
        return [
            Measured(
                n,
                "image",
                u,
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": got["missing"]}, dtype=object),
            )
            for n, u in DUPLICATE_MEASURES.items()
        ]
    ids, files, _, evidence, sharing = _unique_prefix(got)
    values: dict[str, bool | None] = {}
    notes: dict[str, str] = {}
    for i in ids:
        digest = got["sha256"].get(i)
        why = sharing.get(i, [])
        if why:
            values[i] = False
            notes[i] = "; ".join(why)
        elif digest is None:
            values[i] = None
            notes[i] = f"{files[i]}: no file content to compare (absent, empty or unreadable)"
        else:
            values[i] = True
    return [
        Measured(
            "raster.file_unique",
            "image",
            "bool",
            pd.Series(values, dtype=object),
            pd.Series(evidence, dtype=object),
            notes=pd.Series(notes, dtype=object) if notes else None,
        )
    ]


@provider(scope="delivery", measures=DELIVERY_MEASURES)
def listing_measures(ctx: ProviderContext) -> list[Measured]:
    """Files on disk vs the images table, both directions (JRC §6.4: names match the metadata table)."""
    got = _scan(ctx)
    d = ctx.delivery
    if "missing" in got:
        return [
            Measured(
                n,
                "delivery",
                u,
                pd.Series({d.id: None}, dtype=object),
                pd.Series({d.id: (d.manifest_evidence("tables"),)}, dtype=object),
                notes=pd.Series({d.id: got["missing"]}, dtype=object),
            )
            for n, u in DELIVERY_MEASURES.items()
        ]
    lc = got["listing"]
    t = got["table"]
    ev = pd.Series({d.id: t.evidence(t.df["_row"])}, dtype=object)
    unlisted = list(lc.unlisted)
    missing = list(lc.listed_missing)
    return [
        Measured(
            "raster.unlisted_files",
            "delivery",
            "1",
            pd.Series({d.id: float(len(unlisted))}, dtype=object),
            ev,
            notes=pd.Series({d.id: "not in the images table: " + ", ".join(unlisted)}, dtype=object)
            if unlisted
            else None,
        ),
        Measured(
            "raster.listed_missing",
            "delivery",
            "1",
            pd.Series({d.id: float(len(missing))}, dtype=object),
            ev,
            notes=pd.Series({d.id: "listed but absent: " + ", ".join(missing)}, dtype=object)
            if missing
            else None,
        ),
    ]


def _number(ctx: ProviderContext, name: str, default: float) -> float:
    v = ctx.parameters.get(name)
    v = getattr(v, "magnitude", v)
    return (
        float(v)
        if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
        else default
    )


@provider(scope="image", measures=CONTENT_MEASURES)
def content_measures(ctx: ProviderContext) -> list[Measured]:
    """Each image row holds a picture of its own (JRC §12.4 Table 12 "Ortho-image"; issue 25).

    ``False`` when the row names the same file as another row, its file has the same SHA-256 as
    another's (red team R12), its decoded pixels equal another image's whatever the file's
    compression, tiling or georeference (one scene's pixels under another scene's georeference),
    or it is a near copy of another image (thumbnail correlation of at least the profile's
    ``copy_correlation_min`` after aligning a whole-cell shift, not explained by the two
    georeferences: measures/copies.py). The note names the other image(s). ``None`` (missing)
    when the file could not be read: there is no content to compare.
    """
    got = _scan(ctx)
    if "missing" in got:
        return [
            Measured(
                n,
                "image",
                u,
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": got["missing"]}, dtype=object),
            )
            for n, u in CONTENT_MEASURES.items()
        ]
    ids, files, file_key, evidence, sharing = _unique_prefix(got)
    sha: dict[str, str] = got["sha256"]
    facts: dict[str, RasterFacts] = got["facts"]
    pixels: dict[str, dict[str, Any]] = got["pixels"]
    contents = []
    seen: set[str] = set()
    for i in ids:
        px, f = pixels.get(i), facts.get(i)
        if px is None or f is None or i in got["errors"]:
            continue
        if sha.get(i) in seen:  # one file content compared once: its other rows are flagged above
            continue
        if sha.get(i) is not None:
            seen.add(sha[i])
        contents.append(
            Content(
                i, px["hash"], px["thumb"], px["cell"], f.count, f.bounds, f.pixel_size, f.crs_name
            )
        )
    copies = find_copies(contents, min_correlation=_number(ctx, "copy_correlation_min", 0.99))
    first = {}  # content -> the row compared for it
    for c in contents:
        if sha.get(c.id) is not None:
            first[sha[c.id]] = c.id
    cells = {i: (pixels.get(i) or {}).get("cell") for i in ids}
    values: dict[str, bool | None] = {}
    notes: dict[str, str] = {}
    for i in ids:
        why = list(sharing.get(i, []))
        compared = first.get(sha[i], i) if sha.get(i) is not None else i

        def known(j: str, i: str = i) -> bool:  # already named as the same file or the same content
            return (file_key.get(j) is not None and file_key.get(j) == file_key.get(i)) or (
                sha.get(j) is not None and sha.get(j) == sha.get(i)
            )

        matches = [m for m in copies.get(compared, []) if not known(m.other)]
        if matches:
            shown = matches[:NAMES_SHOWN]
            why.append(
                "its pixels are a copy of image(s) "
                + "; ".join(m.describe(cells.get(i)) for m in shown)
                + (f"; and {len(matches) - NAMES_SHOWN} more" if len(matches) > NAMES_SHOWN else "")
            )
        if why:
            values[i] = False
            notes[i] = "; ".join(why)
        elif i not in pixels or pixels[i].get("hash") is None or i in got["errors"]:
            values[i] = None
            notes[i] = f"{files[i]}: no decoded pixels to compare (absent, empty or unreadable)"
        else:
            values[i] = True
    return [
        Measured(
            "raster.content_unique",
            "image",
            "bool",
            pd.Series(values, dtype=object),
            pd.Series(evidence, dtype=object),
            notes=pd.Series(notes, dtype=object) if notes else None,
        )
    ]


@provider(scope="delivery", measures=CLOUD_MEAN)
def cloud_mean(ctx: ProviderContext) -> list[Measured]:
    """Mean of the measured cloud cover over the delivered images (JRC §6.3 "or/and in average")."""
    got = _scan(ctx)
    d = ctx.delivery
    if "missing" in got:
        return [
            Measured(
                "raster.cloud_cover_mean",
                "delivery",
                "%",
                pd.Series({d.id: None}, dtype=object),
                pd.Series({d.id: (d.manifest_evidence("tables"),)}, dtype=object),
                notes=pd.Series({d.id: got["missing"]}, dtype=object),
            )
        ]
    col = got["frame"]["raster.cloud_cover"]
    t = got["table"]
    measured = [
        float(v)
        for v in col.tolist()
        if v is not None and not (isinstance(v, float) and math.isnan(v))
    ]
    unmeasured = [
        str(i) for i, v in col.items() if v is None or (isinstance(v, float) and math.isnan(v))
    ]
    value = None if unmeasured or not measured else sum(measured) / len(measured)
    note = (
        f"mean of the measured cloud cover of {len(measured)} image(s)"
        if value is not None
        else f"cloud cover not measured for image(s) {', '.join(unmeasured[:5])}: the mean is unknown"
    )
    return [
        Measured(
            "raster.cloud_cover_mean",
            "delivery",
            "%",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: t.evidence(t.df["_row"])}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]
