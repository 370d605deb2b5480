"""JRC items that had no rule (issue 26 "Eleven mandatory checkable JRC items have no rule"), now encoded:
§7.3 point identifier unique across GCPs and check points, §7.1 map digitisation error, §6.2.2 scanner
test schedule, §12.7 space-resection images each a block (and the §11 mosaic metadata rules, on a planted mosaic).

Each is planted on a copy of a shipped example and run through the real check with the checker's
file re-signed on the copy; expected values follow from the edit (which id, which scale, which date).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from tests.checking import (
    CHECKERS,
    DATE,
    EXAMPLES,
    check_with,
    read_table,
    records,
    resigned,
    write_table,
)
from tests.checking import copy_example as _copy

from orthospec.engine.providers.ground_reference import kind_of_text


def _check(d: Path) -> dict[str, Any]:
    checker = CHECKERS / d.name
    if d.parent != EXAMPLES:
        checker = resigned(checker, d, d.parent / "checker.yaml")
    return check_with(d, "jrc-v3", checker=checker, date=DATE).document


def _rule(doc: dict[str, Any], rule: str) -> dict[str, dict[str, Any]]:
    return {r["item"]: r for r in records(doc) if r["rule"] == rule}


def _manifest(d: Path) -> dict[str, Any]:
    return yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))


def _write_manifest(d: Path, m: dict[str, Any]) -> None:
    (d / "delivery.yaml").write_text(yaml.safe_dump(m, sort_keys=False), encoding="utf-8")


# --- §7.3 point identifier unique to project ----------------------------------------------------------


def test_a_check_point_reusing_a_gcp_id_is_a_finding(tmp_path: Path) -> None:
    """Issue 26: a check point reusing a GCP id was accepted (here one of the contractor's internal-QC
    check points, which the delivery's checkpoints table holds beside the checker's own)."""
    d = _copy("aerial-pass", tmp_path)
    header, rows = read_table(d, "checkpoints")
    assert any(r["point_id"] == "B03-Q01" for r in rows)
    for r in rows:
        if r["point_id"] == "B03-Q01":
            r["point_id"] = "B03-G01a"
    write_table(d, "checkpoints", header, rows)
    doc = _check(d)
    got = _rule(doc, "JRC-7.3-POINT-ID-UNIQUE")["D-2026-014"]
    assert got["verdict"] == "fail" and got["measured"]["value"] == 1
    assert "B03-G01a" in got["message"]
    assert doc["verdict"] == "rejected"
    shipped = _rule(_check(EXAMPLES / "aerial-pass"), "JRC-7.3-POINT-ID-UNIQUE")["D-2026-014"]
    assert shipped["verdict"] == "pass"


# --- §7.1 digitisation error of map-derived control -----------------------------------------------------


@pytest.mark.parametrize(
    ("scale", "precision", "verdict"),
    [
        ("10000", "0.02", "fail"),  # 0.02 mm x 10,000 = 0.2 m > 0.02 m stated
        ("10000", "0.20", "pass"),  # allows for exactly the digitisation error
        ("", "0.20", "missing"),  # no map scale: cannot be told
    ],
)
def test_map_control_allows_for_the_digitisation_error(
    tmp_path: Path, scale: str, precision: str, verdict: str
) -> None:
    d = _copy("aerial-pass", tmp_path)
    header, rows = read_table(d, "gcps")
    for r in rows:
        if r["point_id"] == "B02-G01a":
            r.update(source_type="map", map_scale=scale, precision_xy=precision)
    write_table(d, "gcps", [*header, "map_scale"], [{"map_scale": "", **r} for r in rows])
    got = _rule(_check(d), "JRC-7.1-MAP-DIGITISATION")
    assert got["B02-G01a"]["verdict"] == verdict
    assert {r["verdict"] for i, r in got.items() if i != "B02-G01a"} == {"not_applicable"}


@pytest.mark.parametrize(
    ("text", "kind"),
    [
        ("GNSS RTK (SAPOS HEPS), signalised, 2026-03", "survey"),
        ("scaled from the 1:5,000 topographic map", "map"),
        ("Total station from geodetic control", "survey"),
        ("photogrammetric mapping service archive", "photogrammetric"),  # "mapping" is not a map
        ("GNSS point read off a map", None),  # two kinds: unknown
        ("field corner", None),
    ],
)
def test_the_kind_of_a_free_text_source(text: str, kind: str | None) -> None:
    assert kind_of_text(text) == kind


def test_a_map_source_in_free_text_cannot_dodge_the_map_rules(tmp_path: Path) -> None:
    """Without source_type, the words of `source` decide; a 'topographic map' GCP is map control."""
    d = _copy("aerial-pass", tmp_path)
    header, rows = read_table(d, "gcps")
    for r in rows:
        r["source_type"] = ""
        if r["point_id"] == "B01-G02b":
            r["source"] = "scaled from the 1:10,000 topographic map"
    write_table(d, "gcps", header, rows)
    doc = _check(d)
    got = _rule(doc, "JRC-7.1-MAP-DIGITISATION")
    assert got["B01-G02b"]["verdict"] == "missing"  # a map point without its map scale
    assert got["B01-G01a"]["verdict"] == "not_applicable"  # "GNSS RTK ...": survey
    assert (
        _rule(doc, "JRC-7.1-MAP-CONTROL-5X")["B01-G02b"]["verdict"] == "pass"
    )  # 0.02 m <= 0.5 m / 5


# --- §6.2.2 scanner tests before and at the end of the project --------------------------------------------


def _film(d: Path, tests: list[str], scans: tuple[str, str]) -> None:
    m = _manifest(d)
    m["sensor"]["digital"] = False
    m["tables"]["scanner_tests"] = "tables/scanner_tests.csv"
    _write_manifest(d, m)
    write_table(
        d,
        "scanner_tests",
        ["test_id", "scanner", "date", "grid_points", "rmse_x", "rmse_y", "max_residual"],
        [
            {
                "test_id": f"T{k}",
                "scanner": "PS-1",
                "date": t,
                "grid_points": "25",
                "rmse_x": "2.0",
                "rmse_y": "2.1",
                "max_residual": "6.0",
            }
            for k, t in enumerate(tests, start=1)
        ],
    )
    header, rows = read_table(d, "images")
    for k, r in enumerate(rows):
        r["scan_date"] = scans[0] if k == 0 else scans[1]
    write_table(d, "images", [*header, "scan_date"] if "scan_date" not in header else header, rows)


@pytest.mark.parametrize(
    ("tests", "gaps", "said"),
    [
        (["2026-04-20", "2026-05-10"], 0, ""),
        (["2026-04-20", "2026-04-20"], 1, "no test on or after the last scan (2026-05-08)"),
        (["2026-05-02"], 2, "no test on or before the first scan (2026-05-01)"),
    ],
)
def test_scanner_tests_before_and_at_the_end_of_scanning(
    tmp_path: Path, tests: list[str], gaps: int, said: str
) -> None:
    d = _copy("aerial-pass", tmp_path)
    _film(d, tests, ("2026-05-01", "2026-05-08"))
    got = _rule(_check(d), "JRC-6.2.2-SCANNER-TESTS-REPEATED")["D-2026-014"]
    assert got["measured"]["value"] == gaps
    assert got["verdict"] == ("pass" if gaps == 0 else "warn")
    assert said in got["message"]


# --- §12.7 space resection: each image a block ---------------------------------------------------------


def test_space_resection_images_pooled_in_one_block(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    m = _manifest(d)
    m["blocks"][0]["method"] = "space resection"
    _write_manifest(d, m)
    _, images = read_table(d, "images")
    n = sum(r["block"] == "B01" for r in images)
    doc = _check(d)
    got = _rule(doc, "JRC-12.7-SPACE-RESECTION-BLOCKS")
    assert got["B01"]["verdict"] == "fail" and got["B01"]["measured"]["value"] == n
    assert {got[b]["verdict"] for b in ("B02", "B03")} == {"not_applicable"}
    assert doc["verdict"] == "rejected"


# --- §11 mosaic metadata ---------------------------------------------------------------------------------


def test_a_mosaic_owes_its_tiles_layer_and_radiometric_processing(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    m = _manifest(d)
    m["product"]["mosaic"] = True
    _write_manifest(d, m)
    doc = _check(d)
    assert _rule(doc, "JRC-11-TILES-SHAPEFILE")[m["id"]]["verdict"] == "warn"
    assert _rule(doc, "JRC-11-RADIOMETRIC-PROCESSING-INFO")[m["id"]]["verdict"] == "warn"
    (d / "documents" / "radiometry.md").write_text(
        "# Radiometric processing\n\nHistogram matching per flight.\n", encoding="utf-8"
    )
    m["documents"]["radiometric_processing"] = "documents/radiometry.md"
    _write_manifest(d, m)
    assert _rule(_check(d), "JRC-11-RADIOMETRIC-PROCESSING-INFO")[m["id"]]["verdict"] == "pass"
    shipped = _check(EXAMPLES / "aerial-pass")
    assert _rule(shipped, "JRC-11-TILES-SHAPEFILE")["D-2026-014"]["verdict"] == "not_applicable"
