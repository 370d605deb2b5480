"""Measures derived from the delivery's records: per-flight attitude, camera calibration age, GSD
from flying height (Passini/Jacobsen: GSD = H / f x pixel size)."""

from __future__ import annotations

import datetime as dt
from typing import Any

import numpy as np
import pandas as pd

from ...provenance import Evidence
from ...units import convert
from ..registry import Measured, ProviderContext, provider


@provider(scope="flight", measures={"flight.roll_mean_abs": "deg", "flight.roll_max_abs": "deg",
                                    "flight.images": "1"})
def flight_attitude(ctx: ProviderContext) -> list[Measured]:
    """Mean and maximum absolute roll of the photos of each flight (JRC §5.2.4)."""
    d = ctx.delivery
    imgs, flights = d.table("images"), d.table("flights")
    names = ("flight.roll_mean_abs", "flight.roll_max_abs", "flight.images")
    ids = flights.ids.tolist() if flights is not None else []
    if imgs is None or "flight_id" not in imgs.df:
        why = "no images table" if imgs is None else f"{imgs.file} has no flight_id column"
        return [Measured(n, "flight", u, pd.Series({i: None for i in ids}, dtype=object),
                         pd.Series({i: () for i in ids}, dtype=object),
                         notes=pd.Series({i: why for i in ids}, dtype=object))
                for n, u in zip(names, ("deg", "deg", "1"), strict=True)]
    df = imgs.df
    roll = df["roll"].abs() if "roll" in df else pd.Series(np.nan, index=df.index)
    g = pd.DataFrame({"f": df["flight_id"].astype(str), "r": roll, "row": df["_row"]}).groupby("f")
    mean, mx, n = g["r"].mean(), g["r"].max(), g["r"].size()
    rows = g["row"].agg(list)
    ev = {
        f: (Evidence(imgs.file, imgs.sha256, tuple(int(r) for r in rows.get(f, []))),) for f in ids
    }
    notes = {f: "no photos of this flight in the images table" for f in ids if f not in rows.index}
    out = []
    for name, s, unit in (
        (names[0], mean, "deg"),
        (names[1], mx, "deg"),
        (names[2], n.astype(float), "1"),
    ):
        out.append(
            Measured(
                name,
                "flight",
                unit,
                pd.Series({f: s.get(f) for f in ids}, dtype=object),
                pd.Series(ev, dtype=object),
                notes=pd.Series(notes, dtype=object) if notes else None,
            )
        )
    return out


def _reference_date(ctx: ProviderContext) -> tuple[dt.date | None, str]:
    dates = ctx.delivery.manifest.dates
    for key in ("acquired_from", "acquired", "flown", "delivered"):
        v = dates.get(key)
        if v is None:
            continue
        if isinstance(v, dt.datetime):
            return v.date(), key
        if isinstance(v, dt.date):
            return v, key
        try:
            return dt.date.fromisoformat(str(v)[:10]), key
        except ValueError:
            continue
    return None, ""


@provider(scope="camera", measures={"camera.calibration_age": "year"})
def camera_age(ctx: ProviderContext) -> list[Measured]:
    """Years from the calibration certificate to the start of acquisition (JRC §4.2, §4.3)."""
    d = ctx.delivery
    cams = d.table("cameras")
    if cams is None:
        return [
            Measured(
                "camera.calibration_age",
                "camera",
                "year",
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": "no cameras table"}, dtype=object),
            )
        ]
    ref, key = _reference_date(ctx)
    vals: dict[str, Any] = {}
    notes: dict[str, str] = {}
    for cid, cal in zip(
        cams.ids, cams.df.get("calibration_date", pd.Series([None] * len(cams.df))), strict=True
    ):
        if cal is None or ref is None:
            vals[cid] = None
            notes[cid] = (
                "no calibration_date"
                if cal is None
                else "delivery.yaml dates give no acquisition date"
            )
            continue
        vals[cid] = (ref - dt.date.fromisoformat(str(cal))).days / 365.25
    ev = {
        cid: (
            Evidence(cams.file, cams.sha256, (int(r),)),
            d.manifest_evidence(f"dates.{key}" if key else "dates"),
        )
        for cid, r in zip(cams.ids, cams.df["_row"], strict=True)
    }
    return [
        Measured(
            "camera.calibration_age",
            "camera",
            "year",
            pd.Series(vals, dtype=object),
            pd.Series(ev, dtype=object),
            notes=pd.Series(notes, dtype=object) if notes else None,
        )
    ]


@provider(scope="image", measures={"geometry.gsd_from_flying_height": "m"})
def gsd_from_height(ctx: ProviderContext) -> list[Measured]:
    """Ground pixel of each photo from its flying height and its camera: H / f x pixel size."""
    d = ctx.delivery
    imgs, cams, flights = d.table("images"), d.table("cameras"), d.table("flights")
    name = "geometry.gsd_from_flying_height"
    if imgs is None or cams is None:
        why = "needs the images and cameras tables"
        return [
            Measured(
                name,
                "image",
                "m",
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": why}, dtype=object),
            )
        ]
    cdf = cams.df.set_index(cams.ids)
    f_mm = (
        convert(cdf["focal_length"].to_numpy(float), cams.units.get("focal_length", "mm"), "m")
        if "focal_length" in cdf
        else np.full(len(cdf), np.nan)
    )
    px_m = (
        convert(cdf["pixel_size"].to_numpy(float), cams.units.get("pixel_size", "µm"), "m")
        if "pixel_size" in cdf
        else np.full(len(cdf), np.nan)
    )
    scale = pd.Series(px_m / f_mm, index=cdf.index)  # metres of ground per metre of height
    cam_row = dict(zip(cams.ids, cams.df["_row"], strict=True))
    cam_of_flight: dict[str, str] = {}
    if flights is not None:
        cam_of_flight = dict(zip(flights.ids, flights.df["camera_id"].astype(str), strict=True))
    df = imgs.df
    vals: dict[str, float | None] = {}
    ev: dict[str, tuple[Evidence, ...]] = {}
    notes: dict[str, str] = {}
    only = cdf.index[0] if len(cdf) == 1 else None
    for iid, row, h, fl in zip(
        imgs.ids,
        df["_row"],
        df.get("flying_height", pd.Series([np.nan] * len(df))),
        df.get("flight_id", pd.Series([None] * len(df))),
        strict=True,
    ):
        cam = cam_of_flight.get(str(fl)) if fl is not None else None
        cam = cam or only
        items: list[Evidence] = [Evidence(imgs.file, imgs.sha256, (int(row),))]
        if cam is None or cam not in scale.index:
            vals[iid], notes[iid] = (
                None,
                "cannot tell which camera took this photo (flights.camera_id)",
            )
        elif h is None or np.isnan(h):
            vals[iid], notes[iid] = None, "no flying_height"
        else:
            vals[iid] = float(
                convert([h], imgs.units.get("flying_height", "m"), "m")[0] * scale[cam]
            )
            items.append(Evidence(cams.file, cams.sha256, (int(cam_row[cam]),)))
        ev[iid] = tuple(items)
    return [
        Measured(
            name,
            "image",
            "m",
            pd.Series(vals, dtype=object),
            pd.Series(ev, dtype=object),
            notes=pd.Series(notes, dtype=object) if notes else None,
        )
    ]
