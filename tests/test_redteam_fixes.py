"""Fixes for red-team findings (tests/REDTEAM.md; the reproducers live in tests/test_redteam.py).

Each test edits a real copy of a shipped example delivery (never the shipped one) the way a contractor
could, runs the real check with the checker's real file (tests/checking.py), and asserts the finding
the standard asks for. Expected values come from the edit itself (which row was deleted, which file was
copied), never from pinned output.
"""

from __future__ import annotations

import csv
import hashlib
import shutil
from pathlib import Path
from typing import Any

import pytest
from tests.checking import CHECKERS, DATE, EXAMPLES, ROOT, check_with, records
from tests.checking import copy_example as _copy

from orthospec.delivery.checker import load_checker
from orthospec.delivery.reader import open_delivery
from orthospec.engine import manual
from orthospec.engine.evaluator import Evaluator
from orthospec.engine.params import resolve_parameters
from orthospec.profile.loader import load_profile


def _edit_images(d: Path, edit: Any) -> None:
    """Rewrite tables/images.csv through ``edit(rows) -> rows`` (the checker pins only checkpoints.csv)."""
    path = d / "tables" / "images.csv"
    with path.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        header, rows = list(reader.fieldnames or []), list(reader)
    rows = edit(rows)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def _drop(image_id: str) -> Any:
    return lambda rows: [r for r in rows if r["image_id"] != image_id]


def _rows(doc: dict[str, Any], item: str) -> dict[str, dict[str, Any]]:
    return {r["rule"]: r for r in records(doc) if r["item"] == item}


# --- R15: a checker verdict on an item the delivery no longer lists -----------------------------


def test_r15_checker_fail_on_deleted_image_stays_a_finding(tmp_path: Path) -> None:
    """aerial-fail: the checker judged F03_0202 `fail` (JRC-6.3-ARTEFACTS, JRC-T6-ORTHO-INSPECTION);
    the contractor deletes its row. The verdicts stay as records and page 1 names the item."""
    d = _copy("aerial-fail", tmp_path)
    _edit_images(d, _drop("F03_0202"))
    res = check_with(d, "jrc-v3", checker=CHECKERS / "aerial-fail", date=DATE)
    doc = res.document
    got = _rows(doc, "F03_0202")
    for rule in ("JRC-6.3-ARTEFACTS", "JRC-T6-ORTHO-INSPECTION"):
        # the checker's word is kept (a recommended rule's fail is a warn)
        assert got[rule]["measured"]["value"] == "fail" and got[rule]["verdict"] in (
            "fail",
            "warn",
        ), got.get(rule)
        assert "no longer lists" in got[rule]["message"]
    reasons = [r for r in doc["rollup"]["reasons"] if "F03_0202" in r]
    assert reasons and reasons[0].startswith(
        "the checker's verdict on F03_0202 refers to an item the delivery no longer lists"
    ), doc["rollup"]["reasons"]
    assert not res.accepted


def test_r15_shipped_aerial_fail_has_no_vanished_reason() -> None:
    """Control: with every row in place no checker verdict refers to a vanished item."""
    res = check_with(
        EXAMPLES / "aerial-fail", "jrc-v3", checker=CHECKERS / "aerial-fail", date=DATE
    )
    assert not [r for r in res.document["rollup"]["reasons"] if "no longer lists" in r]


def test_r15_deleted_image_alone_returns_an_accepted_delivery(tmp_path: Path) -> None:
    """aerial-pass is ACCEPTED; deleting one image row the checker inspected (overlap keeps coverage)
    returns it, with the reason naming the image - the delivery no longer is what the checker saw."""
    base = check_with(
        EXAMPLES / "aerial-pass", "jrc-v3", checker=CHECKERS / "aerial-pass", date=DATE
    )
    assert base.accepted, base.document["rollup"]["reasons"]
    d = _copy("aerial-pass", tmp_path)
    _edit_images(d, _drop("F02_0103"))
    res = check_with(d, "jrc-v3", checker=CHECKERS / "aerial-pass", date=DATE)
    assert not res.accepted
    assert any(
        r.startswith(
            "the checker's verdict on F02_0103 refers to an item the delivery no longer lists"
        )
        for r in res.document["rollup"]["reasons"]
    ), res.document["rollup"]["reasons"]
    assert _rows(res.document, "F02_0103")["JRC-6.3-ARTEFACTS"]["verdict"] == "pass"


def test_r15_unused_checker_entries_are_listed(tmp_path: Path) -> None:
    """`manual.unused` lists the checker entries that judged nothing delivered: the two F03_0202 entries."""
    d = _copy("aerial-fail", tmp_path)
    _edit_images(d, _drop("F03_0202"))
    ev = _evaluator(d, CHECKERS / "aerial-fail")
    out = manual.unused(ev.ctx, ev.run().results)
    assert sorted((u["check"], u["item"]) for u in out) == [
        ("JRC-6.3-ARTEFACTS", "F03_0202"),
        ("JRC-T6-ORTHO-INSPECTION", "F03_0202"),
    ]
    assert all("no longer lists" in u["reason"] for u in out)


# --- R12: two image rows, one content ----------------------------------------------------------


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _evaluator(d: Path, checker: Path) -> Evaluator:
    prof = load_profile("jrc-v3")
    dl = open_delivery(d)
    dl.load_all_tables()
    chk = load_checker(checker, delivery_root=dl.root, delivery=dl)
    return Evaluator(
        prof,
        dl,
        resolve_parameters(prof, {}, {}, manifest=dl.flat_manifest(), checker=chk),
        checker=chk,
    )


def _point_row(image_id: str, file: str) -> Any:
    def edit(rows: list[dict[str, str]]) -> list[dict[str, str]]:
        for r in rows:
            if r["image_id"] == image_id:
                r["file"] = file
        return rows

    return edit


@pytest.mark.parametrize("how", ["byte-copy", "same-file"])
def test_r12_duplicate_image_content_is_measured(how: str, tmp_path: Path) -> None:
    """F03_0202 (absent from aerial-fail) replaced by F03_0201's bytes, or its row naming F03_0201's file:
    raster.file_unique is False on both rows, each note naming the other image; the others stay True."""
    d = _copy("aerial-fail", tmp_path)
    if how == "byte-copy":
        shutil.copyfile(d / "images" / "F03_0201.tif", d / "images" / "F03_0202.tif")
        assert _sha(d / "images" / "F03_0201.tif") == _sha(d / "images" / "F03_0202.tif")
    else:
        _edit_images(d, _point_row("F03_0202", "images/F03_0201.tif"))
    m = _evaluator(d, CHECKERS / "aerial-fail").ctx.cache.get("raster.file_unique")
    vals = {str(k): v for k, v in m.values.items()}
    assert vals["F03_0201"] is False and vals["F03_0202"] is False
    assert "F03_0202" in m.notes["F03_0201"] and "F03_0201" in m.notes["F03_0202"]
    assert all(v is True for k, v in vals.items() if k not in ("F03_0201", "F03_0202")), vals
    assert len(vals) == 30


def test_r12_unique_files_and_absent_file(tmp_path: Path) -> None:
    """Control on the shipped aerial-fail: every present file is unique (True); F03_0202, whose file is
    absent, has nothing to compare (None: the rule reading it is missing, never pass)."""
    m = _evaluator(EXAMPLES / "aerial-fail", CHECKERS / "aerial-fail").ctx.cache.get(
        "raster.file_unique"
    )
    vals = {str(k): v for k, v in m.values.items()}
    assert vals.pop("F03_0202") is None
    assert set(vals.values()) == {True}


OWN_FILE_RULE = {
    "id": "JRC-12.4-T12-ORTHO-OWN-FILE",
    "title": "Each ortho-image is its own file, not a copy of another image",
    "clause": {
        "document": "JRC EUR 23638 EN",
        "section": "12.4",
        "table": 12,
        "row": "Ortho-image",
    },
    "quote": "Selected extracts from the final products, georeferenced to the (national) map projection.",
    "scope": "image",
    "measure": "raster.file_unique",
    "requirement": {"op": "true"},
    "level": "mandatory",
    "consequence": "reject_item",
    "tags": ["external-qc", "files"],
}


def _jrc_with_own_file_rule(tmp_path: Path) -> Path:
    """jrc-v3 with the rule requested from the profile owner (kept as is once the profile has it)."""
    import yaml

    doc = yaml.safe_load((ROOT / "specs" / "jrc-v3.yaml").read_text(encoding="utf-8"))
    if not any(r["id"] == OWN_FILE_RULE["id"] for r in doc["rules"]):
        doc["rules"].append(OWN_FILE_RULE)
    out = tmp_path / "jrc-v3.yaml"
    out.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return out


def test_r12_neighbour_copy_rejects_both_images(tmp_path: Path) -> None:
    """aerial-pass (ACCEPTED as shipped) with F02_0105.tif replaced by F02_0104.tif's bytes: both images
    are rejected by the mandatory rule, each record naming the other, and 2 of 30 images (6.7 % > 5 %,
    JRC §12.3) return the delivery."""
    d = _copy("aerial-pass", tmp_path)
    shutil.copyfile(d / "images" / "F02_0104.tif", d / "images" / "F02_0105.tif")
    res = check_with(
        d, _jrc_with_own_file_rule(tmp_path), checker=CHECKERS / "aerial-pass", date=DATE
    )
    got = {r["item"]: r for r in records(res.document) if r["rule"] == OWN_FILE_RULE["id"]}
    assert got["F02_0105"]["verdict"] == "fail" and "F02_0104" in got["F02_0105"]["message"]
    assert got["F02_0104"]["verdict"] == "fail" and "F02_0105" in got["F02_0104"]["message"]
    assert sorted(i for i, r in got.items() if r["verdict"] != "pass") == ["F02_0104", "F02_0105"]
    assert {"F02_0104", "F02_0105"} <= set(res.document["rollup"]["rejected"]["image"])
    assert not res.accepted


# --- R16: the map projection is the ITT's (map_crs), project.crs only the contractor's declaration ----


def _set_project_crs(d: Path, old: str, new: str) -> None:
    path = d / "delivery.yaml"
    text = path.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new, 1), encoding="utf-8")


def _checker_stating(example: str, d: Path, tmp_path: Path, **parameters: Any) -> Path:
    """The example's checker file with its ``parameters:`` entries replaced (re-signed on ``d``)."""
    import yaml
    from tests.checking import resigned

    base = yaml.safe_load((CHECKERS / example / "checker.yaml").read_text(encoding="utf-8"))[
        "parameters"
    ]
    return resigned(
        CHECKERS / example, d, tmp_path / "checker.yaml", parameters={**base, **parameters}
    )


def test_r16_project_crs_spelled_otherwise_is_the_same_projection(tmp_path: Path) -> None:
    # urn:ogc:def:crs:EPSG::25832 is EPSG:25832 (OGC URN for the EPSG code): the same CRS, no finding
    d = _copy("aerial-pass", tmp_path)
    _set_project_crs(d, "crs: 'EPSG:25832'", "crs: 'urn:ogc:def:crs:EPSG::25832'")
    res = check_with(d, "jrc-v3", checker=CHECKERS / "aerial-pass", date=DATE)
    got = _rows(res.document, res.document["delivery"]["id"])["JRC-12.4-T12-MAP-PROJECTION"]
    assert got["verdict"] == "pass", got
    assert res.accepted


def test_r16_images_are_compared_with_the_itt_projection_not_the_manifest(tmp_path: Path) -> None:
    """The ITT names EPSG:25833 while the delivery (images and project.crs) is in EPSG:25832 (written
    so by examples/generate.py): every image fails §12.4 Table 12 and the declaration is a finding."""
    d = _copy("aerial-pass", tmp_path)
    res = check_with(
        d,
        "jrc-v3",
        checker=_checker_stating("aerial-pass", d, tmp_path, map_crs="EPSG:25833"),
        date=DATE,
    )
    doc = res.document
    images = {
        r["item"]: r["verdict"]
        for r in records(doc)
        if r["rule"] == "JRC-12.4-T12-ORTHO-GEOREFERENCED"
    }
    assert len(images) == 30 and set(images.values()) == {"fail"}
    decl = _rows(doc, doc["delivery"]["id"])["JRC-12.4-T12-MAP-PROJECTION"]
    assert decl["verdict"] == "fail"
    assert "project.crs is EPSG:25832, the map projection in force is EPSG:25833" in decl["message"]
    assert doc["profile"]["parameters"]["map_crs"] == {
        "value": "EPSG:25833",
        "unit": "text",
        "source": "checker",
    }
    assert not res.accepted


def test_r16_a_delivery_without_project_crs_is_returned(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    _set_project_crs(d, ", crs: 'EPSG:25832'", "")
    res = check_with(d, "jrc-v3", checker=CHECKERS / "aerial-pass", date=DATE)
    decl = _rows(res.document, res.document["delivery"]["id"])["JRC-12.4-T12-MAP-PROJECTION"]
    assert decl["verdict"] == "fail" and "states no project.crs" in decl["message"], decl
    assert any(
        r.startswith("JRC-12.4-T12-MAP-PROJECTION") for r in res.document["rollup"]["reasons"]
    )
    assert not res.accepted


# --- R17: block outlines are valid and do not overlap (JRC §12.4, §12.8: blocks are the units) ---------


def _move_b02_west_edge(d: Path, x: str) -> None:
    """B02's west edge (x = 507,500 m in aerial-pass) moved to ``x``; B01's east edge is x = 507,000 m."""
    path = d / "delivery.yaml"
    text = path.read_text(encoding="utf-8")
    for y in ("5403000.0", "5410200.0"):
        assert text.count(f"[507500.0, {y}]") >= 1
        text = text.replace(f"[507500.0, {y}]", f"[{x}, {y}]")
    path.write_text(text, encoding="utf-8")


def _line_of_b02_polygon(d: Path) -> int:
    lines = (d / "delivery.yaml").read_text(encoding="utf-8").splitlines()
    start = lines.index("- id: B02")
    return next(i for i in range(start, len(lines)) if lines[i].startswith("  - [")) + 1


def test_r17_touching_block_outlines_are_fine(tmp_path: Path) -> None:
    d = _copy("aerial-pass", tmp_path)
    _move_b02_west_edge(
        d, "507000.0"
    )  # shares B01's east edge from y 5,403,000 to 5,406,000: no area
    assert [b.id for b in open_delivery(d).manifest.blocks] == ["B01", "B02", "B03"]


def test_r17_overlapping_block_outlines_are_refused_naming_both_and_the_line(
    tmp_path: Path,
) -> None:
    from orthospec.errors import DeliveryError

    d = _copy("aerial-pass", tmp_path)
    _move_b02_west_edge(d, "506999.0")  # 1 m over B01's east edge
    with pytest.raises(DeliveryError) as ei:
        open_delivery(d)
    msg = str(ei.value)
    assert msg.startswith(f"delivery.yaml:{_line_of_b02_polygon(d)}: blocks[1] (B02): ")
    assert "overlaps the outline of block B01 (blocks[0])" in msg
    # B01's east edge is x = 507,000 up to y = 5,406,000, then its cut corner runs to (506,000, 5,407,200)
    # (1 m west per 1.2 m north): the 1 m strip inside B01 is 1 x 3,000 m2 plus a 1 x 1.2 / 2 m2 triangle
    assert "over an area of 3000.6 (project.crs units squared)" in msg


# --- R8: which scene is the master image is the checker's knowledge (parameter master_images) ----------


def _master_rules(doc: dict[str, Any]) -> dict[str, dict[str, str]]:
    out: dict[str, dict[str, str]] = {}
    for r in records(doc):
        if r["rule"].startswith("JRC-T9-MASTER-"):
            out.setdefault(r["rule"], {})[r["item"]] = r["verdict"]
    return out


def test_r8_the_checkers_master_is_judged_and_the_flags_compared(tmp_path: Path) -> None:
    """satellite-pass flags S01_SC1 (20 check points); the checker names S02_SC1 (10 check points, written
    so by examples/generate.py) and S99 (no such scene): S02_SC1 is judged as a master, S01_SC1 is not."""
    d = _copy("satellite-pass", tmp_path)
    res = check_with(
        d,
        "jrc-v3",
        checker=_checker_stating("satellite-pass", d, tmp_path, master_images="S02_SC1; S99"),
        date=DATE,
    )
    rules = _master_rules(res.document)
    assert rules["JRC-T9-MASTER-CHECKPOINTS"]["S02_SC1"] == "fail"  # 10 < 20 (Table 9)
    assert rules["JRC-T9-MASTER-CHECKPOINTS"]["S01_SC1"] == "not_applicable"
    assert rules["JRC-T9-MASTER-IDENTIFIED"] == {"D-2026-031": "fail"}
    msg = _rows(res.document, "D-2026-031")["JRC-T9-MASTER-IDENTIFIED"]["message"]
    for part in (
        "no row of the scenes table: S99",
        "not flagged is_master: S02_SC1",
        "flagged is_master but not named by the checker: S01_SC1",
    ):
        assert part in msg, msg
    assert not res.accepted


def test_r8_without_the_checkers_master_the_flags_decide(tmp_path: Path) -> None:
    import yaml
    from tests.checking import resigned

    d = _copy("satellite-pass", tmp_path)
    params = yaml.safe_load(
        (CHECKERS / "satellite-pass" / "checker.yaml").read_text(encoding="utf-8")
    )["parameters"]
    assert params.pop("master_images") == "S01_SC1"
    res = check_with(
        d,
        "jrc-v3",
        checker=resigned(CHECKERS / "satellite-pass", d, tmp_path / "c.yaml", parameters=params),
        date=DATE,
    )
    rules = _master_rules(res.document)
    assert rules["JRC-T9-MASTER-IDENTIFIED"] == {"D-2026-031": "not_applicable"}
    assert rules["JRC-T9-MASTER-CHECKPOINTS"]["S01_SC1"] == "pass"  # flagged, 20 check points
    assert rules["JRC-T9-MASTER-CHECKPOINTS"]["S02_SC1"] == "not_applicable"
    assert res.accepted


def test_r8_the_shipped_satellite_checker_names_the_flagged_master() -> None:
    res = check_with(
        EXAMPLES / "satellite-pass", "jrc-v3", checker=CHECKERS / "satellite-pass", date=DATE
    )
    assert _master_rules(res.document)["JRC-T9-MASTER-IDENTIFIED"] == {"D-2026-031": "pass"}
    assert res.accepted


def test_r17_a_vertex_that_is_not_a_pair_is_refused_naming_it(tmp_path: Path) -> None:
    from orthospec.errors import DeliveryError

    d = _copy("aerial-pass", tmp_path)
    path = d / "delivery.yaml"
    text = path.read_text(encoding="utf-8")
    assert "  - [514500.0, 5403000.0]\n" in text
    path.write_text(
        text.replace("  - [514500.0, 5403000.0]\n", "  - [514500.0]\n", 1), encoding="utf-8"
    )
    with pytest.raises(
        DeliveryError,
        match=r"^delivery.yaml:\d+: blocks\[1\] \(B02\): polygon vertex 2 is \[514500.0\], "
        r"expected \[x, y\]",
    ):
        open_delivery(d)
