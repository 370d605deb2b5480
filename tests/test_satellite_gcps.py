"""Satellite GCP counts from gcps.csv, not from the meta-database (issue 26), and the Table 9 strip
supplement; with the closed vocabulary, the issue 25 observation "Method as free text".

Edits are made on copies of satellite-pass (the checker pins only checkpoints.csv); expected counts
come from the rows the test leaves in gcps.csv, expected supplements from the Table 9 wording
("plus 2 per additional 100km² of strip scene") applied by hand.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest
import rasterio
from affine import Affine
from tests.checking import (
    CHECKERS,
    DATE,
    EXAMPLES,
    check_with,
    read_table,
    records,
    write_table,
)

from orthospec.engine.providers.satellite import strip_supplement


def _copy(tmp_path: Path) -> Path:
    d = tmp_path / "satellite-pass"
    shutil.copytree(EXAMPLES / "satellite-pass", d)
    return d


def _keep_gcps(d: Path, scene: str, n: int) -> None:
    """Keep only the first ``n`` GCP rows of ``scene`` in gcps.csv (scenes.gcp_count untouched)."""
    header, rows = read_table(d, "gcps")
    seen = 0
    out = []
    for r in rows:
        if r["image_id"] == scene:
            seen += 1
            if seen > n:
                continue
        out.append(r)
    write_table(d, "gcps", header, out)


def _set_scene(d: Path, scene: str, **cells: str) -> None:
    header, rows = read_table(d, "scenes")
    for r in rows:
        if r["image_id"] == scene:
            r.update(cells)
    write_table(d, "scenes", header, rows)


def _check(d: Path) -> dict[str, Any]:
    return check_with(d, "jrc-v3", checker=CHECKERS / "satellite-pass", date=DATE).document


def _rule(doc: dict[str, Any], rule: str) -> dict[str, dict[str, Any]]:
    return {r["item"]: r for r in records(doc) if r["rule"] == rule}


@pytest.mark.parametrize(("area", "expected"), [
    (64.0, 0.0), (100.0, 0.0), (100.5, 2.0), (200.0, 2.0), (250.0, 4.0), (300.0, 4.0), (301.0, 6.0),
])
def test_strip_supplement_two_per_additional_100_km2(area: float, expected: float) -> None:
    assert strip_supplement(area) == expected


def test_the_shipped_counts_are_the_gcp_files() -> None:
    doc = _check(EXAMPLES / "satellite-pass")
    _, gcps = read_table(EXAMPLES / "satellite-pass", "gcps")
    got = {i: r["measured"]["value"] for i, r in _rule(doc, "JRC-T9-GCP-COUNT-RECORDED").items()}
    counted = {i: r["measured"]["value"] for i, r in {**_rule(doc, "JRC-T9-GCP-VHR-RPC"),
                                                      **_rule(doc, "JRC-T9-GCP-VHR-BLOCK")}.items()
               if r["verdict"] != "not_applicable"}
    assert counted == {s: sum(g["image_id"] == s for g in gcps) for s in counted}
    assert set(got.values()) == {True}


def test_a_scene_refined_on_one_gcp_while_declaring_four_is_rejected(tmp_path: Path) -> None:
    """Issue 26: the Table 9 minimum read the declared scenes.gcp_count (4) and passed."""
    d = _copy(tmp_path)
    _keep_gcps(d, "S02_SC1", 1)
    doc = _check(d)
    rpc = _rule(doc, "JRC-T9-GCP-VHR-RPC")["S02_SC1"]
    assert rpc["verdict"] == "fail" and rpc["measured"]["value"] == 1
    recorded = _rule(doc, "JRC-T9-GCP-COUNT-RECORDED")["S02_SC1"]
    assert (
        recorded["verdict"] == "warn"
        and "declared 4 (scenes.gcp_count), counted 1" in recorded["message"]
    )
    assert "S02_SC1" in doc["rollup"]["rejected"]["image"] and doc["verdict"] == "rejected"


@pytest.mark.parametrize("method", ["RPC", "Rpc", " rpc "])
def test_method_as_free_text_on_a_one_gcp_scene_is_rejected(tmp_path: Path, method: str) -> None:
    """Issue 25 "Method as free text": `RPC` on a 1-GCP scene turned every Table 9 GCP rule not
    applicable and the delivery was ACCEPTED; the spelling is now read as `rpc`."""
    d = _copy(tmp_path)
    _keep_gcps(d, "S02_SC1", 1)
    _set_scene(d, "S02_SC1", correction_method=method, gcp_count="1")
    doc = _check(d)
    assert _rule(doc, "JRC-T9-GCP-VHR-RPC")["S02_SC1"]["verdict"] == "fail"
    assert doc["verdict"] == "rejected"


def test_without_an_image_id_column_the_footprint_decides(tmp_path: Path) -> None:
    """GCP rows naming no scene count for the scene whose delivered orthoimage contains them."""
    d = _copy(tmp_path)
    header, rows = read_table(d, "gcps")
    expected: dict[str, int] = {}
    for r in rows:
        expected[r["image_id"]] = expected.get(r["image_id"], 0) + 1
        del r["image_id"]
    write_table(d, "gcps", [h for h in header if h != "image_id"], rows)
    doc = _check(d)
    got = _rule(doc, "JRC-T9-GCP-COUNT-RECORDED")
    for scene, n in expected.items():
        assert got[scene]["verdict"] == "pass", got[scene]
        assert (
            f"{n} of the {len(rows)} rows naming no scene inside its orthoimage footprint"
            in got[scene]["message"]
        )
    assert doc["verdict"] == "accepted"


def test_a_gcp_table_removed_leaves_the_minimums_missing(tmp_path: Path) -> None:
    d = _copy(tmp_path)
    import yaml

    m = yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))
    del m["tables"]["gcps"]
    (d / "delivery.yaml").write_text(yaml.safe_dump(m, sort_keys=False), encoding="utf-8")
    doc = _check(d)
    got = _rule(doc, "JRC-T9-GCP-VHR-RPC")
    assert {got[s]["verdict"] for s in ("S02_SC1", "S02_SC2", "S02_SC3")} == {"missing"}
    block = _rule(doc, "JRC-T9-GCP-VHR-BLOCK")
    assert {block[s]["verdict"] for s in ("S01_SC1", "S01_SC2", "S01_SC3")} == {"missing"}
    assert doc["verdict"] == "rejected"


def test_a_strip_scene_needs_two_more_gcps_per_additional_100_km2(tmp_path: Path) -> None:
    """S02_SC1 re-georeferenced to a 16 x 16 km footprint (128 px of 125 m): 256 km², two started
    100 km² beyond the first, so 2 + 4 = 6 GCPs are recommended; it has 4."""
    d = _copy(tmp_path)
    with rasterio.open(d / "images" / "S02_SC1.tif", "r+") as ds:
        t = ds.transform
        ds.transform = Affine(125.0, 0.0, t.c, 0.0, -125.0, t.f)
        side_km = ds.width * 125.0 / 1000.0
    doc = _check(d)
    strip = _rule(doc, "JRC-T9-GCP-VHR-RPC-STRIP")
    assert strip["S02_SC1"]["verdict"] == "warn" and strip["S02_SC1"]["measured"]["value"] == 4
    assert strip["S02_SC1"]["requirement"]["value"] == 2 + strip_supplement(side_km**2) == 6
    assert {strip[s]["verdict"] for s in ("S02_SC2", "S02_SC3")} == {"not_applicable"}
