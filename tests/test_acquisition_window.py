"""The acquisition window (JRC §3.4; issue 25 observation, issue 26 "§3.4 acquisition window as an ITT
parameter").

Observed: images acquired 15 months outside the window delivery.yaml declares raised nothing. Now the
window in force is the ITT's (parameters acquisition_window_start / _end, set_by: itt) and each
image's own record (exposure time, scene date, else its flight's day) is judged against it; the
manifest's declared window is evidence compared with the same records. Edits on copies of the
shipped examples; expected day counts come from ``datetime`` arithmetic on the planted dates.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import pytest
import yaml
from tests.checking import (
    CHECKERS,
    DATE,
    EXAMPLES,
    check_with,
    manifest,
    read_table,
    records,
    resigned,
    write_manifest,
    write_table,
)
from tests.checking import copy_example as _copy

from orthospec.engine.providers.acquisition import days_outside

#: the satellite-pass scenes were taken 2026-05-21 and 2026-05-28
WINDOW = ["acquisition_window_start=2026-05-01", "acquisition_window_end=2026-06-30"]


def _move_scene(d: Path, image_id: str, day: dt.date) -> None:
    """Record ``image_id`` as taken on ``day`` in both its records (images and scenes)."""
    header, rows = read_table(d, "images")
    for r in rows:
        if r["image_id"] == image_id:
            r["exposure_time"] = f"{day.isoformat()}T10:42:11Z"
    write_table(d, "images", header, rows)
    header, rows = read_table(d, "scenes")
    for r in rows:
        if r["image_id"] == image_id:
            r["acquisition_date"] = day.isoformat()
    write_table(d, "scenes", header, rows)


def _rule(doc: dict[str, Any], rule: str) -> dict[str, dict[str, Any]]:
    return {r["item"]: r for r in records(doc) if r["rule"] == rule}


def _check(d: Path, params: list[str] | None = None) -> dict[str, Any]:
    return check_with(
        d, "jrc-v3", checker=CHECKERS / d.name, date=DATE, params=params or []
    ).document


@pytest.mark.parametrize(
    ("day", "start", "end", "expected"),
    [
        (dt.date(2026, 5, 1), dt.date(2026, 5, 1), dt.date(2026, 6, 30), 0),  # first day inclusive
        (dt.date(2026, 6, 30), dt.date(2026, 5, 1), dt.date(2026, 6, 30), 0),  # last day inclusive
        (dt.date(2026, 4, 30), dt.date(2026, 5, 1), dt.date(2026, 6, 30), 1),
        (dt.date(2027, 8, 28), dt.date(2026, 5, 1), dt.date(2026, 6, 30), 424),
        (dt.date(2020, 1, 1), None, dt.date(2026, 6, 30), 0),  # open start
    ],
)
def test_days_outside_the_window(
    day: dt.date, start: dt.date | None, end: dt.date | None, expected: int
) -> None:
    assert days_outside(day, start, end) == expected


def test_images_15_months_outside_the_declared_window_are_a_finding(tmp_path: Path) -> None:
    """Issue 25: S02_SC2 recorded 15 months after the declared 2026-05-21..28 window: not ACCEPTED."""
    d = _copy("satellite-pass", tmp_path)
    _move_scene(d, "S02_SC2", dt.date(2027, 8, 28))
    doc = _check(d)
    got = _rule(doc, "JRC-3.4-DECLARED-WINDOW")["D-2026-031"]
    assert got["verdict"] == "fail" and got["measured"]["value"] == 1
    assert (
        "S02_SC2 (2027-08-28)" in got["message"]
        and f"up to {(dt.date(2027, 8, 28) - dt.date(2026, 5, 28)).days} days" in got["message"]
    )
    assert doc["verdict"] == "rejected"


def test_the_shipped_examples_keep_to_their_declared_windows() -> None:
    for example in ("aerial-pass", "satellite-pass"):
        doc = check_with(
            EXAMPLES / example, "jrc-v3", checker=CHECKERS / example, date=DATE
        ).document
        got = _rule(doc, "JRC-3.4-DECLARED-WINDOW")
        assert [r["verdict"] for r in got.values()] == ["pass"], got


def test_the_itt_window_rejects_the_image_taken_outside_it(tmp_path: Path) -> None:
    d = _copy("satellite-pass", tmp_path)
    _move_scene(d, "S02_SC2", dt.date(2026, 7, 3))
    # the contractor moves its declared window along: the declaration is evidence, not the window in force
    m = manifest(d)
    m["dates"]["acquired_to"] = dt.date(2026, 7, 3)
    write_manifest(d, m)
    doc = _check(d, WINDOW)
    got = _rule(doc, "JRC-3.4-ACQUISITION-WINDOW")
    assert got["S02_SC2"]["verdict"] == "fail"
    assert got["S02_SC2"]["measured"]["value"] == (dt.date(2026, 7, 3) - dt.date(2026, 6, 30)).days
    assert {i: r["verdict"] for i, r in got.items() if i != "S02_SC2"} == dict.fromkeys(
        ("S01_SC1", "S01_SC2", "S01_SC3", "S02_SC1", "S02_SC3"), "pass"
    )
    assert _rule(doc, "JRC-3.4-DECLARED-WINDOW")["D-2026-031"]["verdict"] == "pass"
    assert "S02_SC2" in doc["rollup"]["rejected"].get("image", [])
    assert doc["verdict"] == "rejected"


def test_without_an_itt_window_the_rule_is_not_applicable(tmp_path: Path) -> None:
    """The shipped checker file states the ITT window; a checker file without it leaves the rule out."""
    checker = CHECKERS / "satellite-pass"
    params = yaml.safe_load((checker / "checker.yaml").read_text(encoding="utf-8"))["parameters"]
    assert {"acquisition_window_start", "acquisition_window_end"} <= set(params)
    bare = {k: v for k, v in params.items() if not k.startswith("acquisition_window")}
    out = resigned(checker, EXAMPLES / "satellite-pass", tmp_path / "checker.yaml", parameters=bare)
    doc = check_with(EXAMPLES / "satellite-pass", "jrc-v3", checker=out, date=DATE).document
    assert {r["verdict"] for r in _rule(doc, "JRC-3.4-ACQUISITION-WINDOW").values()} == {
        "not_applicable"
    }
    shipped = _rule(_check(EXAMPLES / "satellite-pass"), "JRC-3.4-ACQUISITION-WINDOW")
    assert {r["verdict"] for r in shipped.values()} == {"pass"}


def test_records_that_disagree_leave_the_date_missing(tmp_path: Path) -> None:
    d = _copy("satellite-pass", tmp_path)
    header, rows = read_table(d, "scenes")
    for r in rows:
        if r["image_id"] == "S01_SC2":
            r["acquisition_date"] = "2026-05-24"  # images.exposure_time still says 2026-05-21
    write_table(d, "scenes", header, rows)
    got = _rule(_check(d, WINDOW), "JRC-3.4-ACQUISITION-WINDOW")["S01_SC2"]
    assert got["verdict"] == "missing"
    assert "images.exposure_time 2026-05-21, scenes.acquisition_date 2026-05-24" in got["message"]


def test_a_photo_without_exposure_time_takes_its_flights_day(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    header, rows = read_table(d, "images")
    first = rows[0]
    first["exposure_time"] = ""
    write_table(d, "images", header, rows)
    _, flights = read_table(d, "flights")
    fday = next(f["start_time"][:10] for f in flights if f["flight_id"] == first["flight_id"])
    doc = _check(d, ["acquisition_window_start=2026-04-01", f"acquisition_window_end={fday}"])
    got = _rule(doc, "JRC-3.4-ACQUISITION-WINDOW")[first["image_id"]]
    assert (
        got["verdict"] == "pass"
        and f"acquired {fday} (flight {first['flight_id']}" in got["message"]
    )


def test_a_window_bound_that_is_no_date_is_an_error(tmp_path: Path) -> None:
    doc = _check(
        EXAMPLES / "satellite-pass",
        ["acquisition_window_start=spring", "acquisition_window_end=2026-06-30"],
    )
    got = _rule(doc, "JRC-3.4-ACQUISITION-WINDOW")
    assert {r["verdict"] for r in got.values()} == {"error"}
    assert (
        "acquisition_window_start = 'spring' is not a date" in next(iter(got.values()))["message"]
    )
