"""When each image was acquired, against the acquisition window in force (JRC §3.4).

§3.4 makes "Defining the window for the acquisition which can vary depending on the project's scope
(e.g. leaf-on imagery)" a decision of the tender: the window in force is the ITT's (parameters
``acquisition_window_start`` / ``acquisition_window_end``, ``set_by: itt``), never the contractor's.
The manifest's ``dates.acquired_from`` / ``acquired_to`` is the contractor's declaration: evidence,
compared with the images' own records (issue 25: images acquired 15 months outside the declared
window raised nothing).

* ``acquisition.date`` (image): the image's acquisition date from its most specific record: the
  exposure time (``images.exposure_time``), else the scene's ``scenes.acquisition_date``, else its
  flight's start and finish (``flights``, through ``images.flight_id``: a flight over midnight
  gives no single date). Records of one image that disagree leave the date unknown (``missing``).
* ``acquisition.days_outside_window`` (image): days before the window's first day or after its last
  (0 inside; both ends inclusive); ``missing`` when the image's date is unknown.
* ``acquisition.outside_declared_window`` (delivery): images whose date lies outside the window
  the manifest declares, named in the note; not applicable when the manifest declares none.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

import pandas as pd

from ...provenance import Evidence
from ..registry import Measured, ProviderContext, provider
from .shared import Shared

IMAGE = {"acquisition.date": "date", "acquisition.days_outside_window": "d"}
DELIVERY = {"acquisition.outside_declared_window": "1"}
START, END = "acquisition_window_start", "acquisition_window_end"


def _day(v: Any) -> dt.date | None:
    """The calendar day (UTC) of a date or ISO 8601 date-time cell; None when empty or unreadable."""
    if v is None or (isinstance(v, float) and v != v):
        return None
    if isinstance(v, dt.datetime):
        return (v.astimezone(dt.UTC) if v.tzinfo else v).date()
    if isinstance(v, dt.date):
        return v
    text = str(v).strip()
    if not text:
        return None
    try:
        t = dt.datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        return None
    return (t.astimezone(dt.UTC) if t.tzinfo else t).date()


def _table_days(
    ctx: ProviderContext, table: str, column: str
) -> tuple[dict[str, dt.date], dict[str, Evidence]]:
    t = ctx.delivery.table(table)
    if t is None or column not in t.df:
        return {}, {}
    days, ev = {}, {}
    for item, v, row in zip(
        t.ids.astype(str), t.df[column].tolist(), t.df["_row"].tolist(), strict=True
    ):
        day = _day(v)
        if day is not None:
            days[item] = day
            ev[item] = Evidence(t.file, t.sha256, (int(row),))
    return days, ev


def _flight_days(ctx: ProviderContext) -> tuple[dict[str, set[dt.date]], dict[str, Evidence]]:
    """Flight id -> the days its start and finish fall on."""
    t = ctx.delivery.table("flights")
    if t is None:
        return {}, {}
    out: dict[str, set[dt.date]] = {}
    ev = {}
    cols = [t.df[c].tolist() for c in ("start_time", "finish_time") if c in t.df]
    for k, (fid, row) in enumerate(zip(t.ids.astype(str), t.df["_row"].tolist(), strict=True)):
        days = {day for col in cols if (day := _day(col[k])) is not None}
        if days:
            out[fid] = days
            ev[fid] = Evidence(t.file, t.sha256, (int(row),))
    return out, ev


#: computed once per run: both providers read it
_IMAGE_DATES: Shared[
    tuple[list[str], dict[str, dt.date | None], dict[str, str], dict[str, tuple[Evidence, ...]]]
] = Shared("acquisition.image_dates", lambda ctx: _image_dates(ctx))


def image_dates(
    ctx: ProviderContext,
) -> tuple[list[str], dict[str, dt.date | None], dict[str, str], dict[str, tuple[Evidence, ...]]]:
    """(image ids, date or None, note, evidence) from the images', scenes' and flights' records
    (computed once per run: both providers read it)."""
    return _IMAGE_DATES.get(ctx)


def _image_dates(
    ctx: ProviderContext,
) -> tuple[list[str], dict[str, dt.date | None], dict[str, str], dict[str, tuple[Evidence, ...]]]:
    d = ctx.delivery
    imgs = d.table("images")
    ids: list[str] = imgs.ids.astype(str).tolist() if imgs is not None else []
    scenes = d.table("scenes")
    if scenes is not None:
        ids += [i for i in scenes.ids.astype(str).tolist() if i not in set(ids)]
    exposure, ev_exp = _table_days(ctx, "images", "exposure_time")
    scene_day, ev_scene = _table_days(ctx, "scenes", "acquisition_date")
    flight_of: dict[str, str] = {}
    if imgs is not None and "flight_id" in imgs.df:
        flight_of = {
            str(i): str(f)
            for i, f in zip(imgs.ids, imgs.df["flight_id"], strict=True)
            if f is not None
        }
    flight_days, ev_flight = _flight_days(ctx)
    dates: dict[str, dt.date | None] = {}
    notes: dict[str, str] = {}
    evidence: dict[str, tuple[Evidence, ...]] = {}
    for i in ids:
        said: list[tuple[str, dt.date, Evidence]] = []
        if i in exposure:
            said.append(("images.exposure_time", exposure[i], ev_exp[i]))
        if i in scene_day:
            said.append(("scenes.acquisition_date", scene_day[i], ev_scene[i]))
        evidence[i] = tuple(e for _, _, e in said)
        if said:
            days = {day for _, day, _ in said}
            if len(days) > 1:
                dates[i] = None
                notes[i] = "the records disagree: " + ", ".join(f"{w} {day}" for w, day, _ in said)
            else:
                dates[i] = said[0][1]
                notes[i] = f"acquired {said[0][1]} ({said[0][0]})"
            continue
        fl = flight_of.get(i)
        if fl in flight_days and len(flight_days[fl]) == 1:
            (day,) = flight_days[fl]
            dates[i], notes[i] = day, f"acquired {day} (flight {fl} start/finish)"
            evidence[i] = (ev_flight[fl],)
        else:
            dates[i] = None
            notes[i] = (
                f"flight {fl} spans {', '.join(map(str, sorted(flight_days[fl])))}: no single date"
                if fl in flight_days
                else "no acquisition time: images.exposure_time, scenes.acquisition_date or the flight's times"
            )
            if fl in ev_flight:
                evidence[i] = (ev_flight[fl],)
    return ids, dates, notes, evidence


def _window_bound(ctx: ProviderContext, name: str) -> tuple[dt.date | None, str | None]:
    raw = ctx.parameters.get(name)
    if raw is None or (isinstance(raw, str) and not raw.strip()):
        return None, None
    day = _day(raw)
    if day is None:
        return None, f"parameter {name} = {raw!r} is not a date (YYYY-MM-DD)"
    return day, None


def days_outside(day: dt.date, start: dt.date | None, end: dt.date | None) -> int:
    """Days before ``start`` or after ``end`` (0 inside; an open end never counts)."""
    if start is not None and day < start:
        return (start - day).days
    if end is not None and day > end:
        return (day - end).days
    return 0


@provider(scope="image", measures=IMAGE)
def acquisition_window(ctx: ProviderContext) -> list[Measured]:
    """Each image's acquisition date and its distance outside the ITT's acquisition window (JRC §3.4)."""
    ids, dates, notes, evidence = image_dates(ctx)
    start, bad_start = _window_bound(ctx, START)
    end, bad_end = _window_bound(ctx, END)
    outside: dict[str, Any] = {}
    out_notes: dict[str, str] = {}
    errors: dict[str, str] = {}
    for i in ids:
        day = dates[i]
        if bad_start or bad_end:
            outside[i] = None
            errors[i] = "; ".join(x for x in (bad_start, bad_end) if x)
        elif day is None:
            outside[i], out_notes[i] = None, notes[i]
        elif start is None and end is None:
            outside[i], out_notes[i] = None, "the ITT states no acquisition window"
        else:
            n = days_outside(day, start, end)
            outside[i] = float(n)
            window = f"{start or '…'} to {end or '…'}"
            out_notes[i] = (
                f"{notes[i]}, inside the ITT window {window}"
                if n == 0
                else f"{notes[i]}: {n} day(s) {'before' if start and day < start else 'after'} the ITT "
                f"window {window}"
            )
    ev = pd.Series({i: evidence[i] for i in ids}, dtype=object)
    iso: dict[str, str | None] = {i: (day.isoformat() if (day := dates[i]) else None) for i in ids}
    return [
        Measured(
            "acquisition.date",
            "image",
            "date",
            pd.Series(iso, dtype=object),
            ev,
            notes=pd.Series(notes, dtype=object),
        ),
        Measured(
            "acquisition.days_outside_window",
            "image",
            "d",
            pd.Series(outside, dtype=object),
            ev,
            notes=pd.Series(out_notes, dtype=object),
            errors=pd.Series(errors, dtype=object) if errors else None,
        ),
    ]


@provider(scope="delivery", measures=DELIVERY)
def declared_window(ctx: ProviderContext) -> list[Measured]:
    """Images whose recorded acquisition date lies outside the window the manifest declares."""
    d = ctx.delivery
    name = "acquisition.outside_declared_window"
    dates_decl = d.manifest.dates
    start, end = _day(dates_decl.get("acquired_from")), _day(dates_decl.get("acquired_to"))
    if start is None and end is None:
        single = _day(dates_decl.get("acquired"))
        start = end = single
    ev: tuple[Evidence, ...] = (d.manifest_evidence("dates"),)
    if start is None and end is None:
        return [
            Measured(
                name,
                "delivery",
                "1",
                pd.Series({d.id: None}, dtype=object),
                pd.Series({d.id: ev}, dtype=object),
                na=pd.Series(
                    {
                        d.id: "delivery.yaml declares no acquisition window (dates.acquired_from / "
                        "acquired_to): nothing to compare"
                    },
                    dtype=object,
                ),
            )
        ]
    ids, dates, _, evidence = image_dates(ctx)
    known = [i for i in ids if dates[i] is not None]
    off = [(i, days_outside(dates[i], start, end)) for i in known]  # type: ignore[arg-type]
    off = [(i, n) for i, n in off if n > 0]
    unknown = [i for i in ids if dates[i] is None]
    window = f"{start or '…'} to {end or '…'}"
    if off:
        worst = max(n for _, n in off)
        shown = ", ".join(f"{i} ({dates[i]})" for i, _ in off[:10]) + (
            f" and {len(off) - 10} more" if len(off) > 10 else ""
        )
        note = (
            f"{len(off)} of {len(known)} dated images lie outside the declared window {window} (up to {worst} "
            f"days): {shown}"
        )
    else:
        note = f"all {len(known)} dated images lie inside the declared window {window}"
    if unknown:
        note += f"; {len(unknown)} image(s) without an acquisition date"
    rows = tuple(e for i, _ in off for e in evidence[i])
    value = float(len(off)) if known else None
    return [
        Measured(
            name,
            "delivery",
            "1",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev + rows}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]
