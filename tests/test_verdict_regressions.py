"""Regression tests for wrong verdicts an auditor found (issue 12, issue 17 "fail-open").

Each case copies ``examples/deliveries/aerial-pass`` into tmp_path, plants one defect by editing
its CSV/YAML, and runs the real ``orthospec.api.check``. Where the expected verdict depends on a
rule's level or consequence, the case uses a small profile written next to it, so the engine's
behaviour is asserted independently of the shipped profile's content; the shipped jrc-v3 is used
where the engine alone decides (fail-open cases, built-in rules).
"""

from __future__ import annotations

import csv
import math
import shutil
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tests.checking import DATE, manifest, read_table, write_manifest, write_table
from tests.checking import records as all_records

from orthospec.api import check as _check
from orthospec.engine.params import ParameterError
from orthospec.errors import OrthospecError

ROOT = Path(__file__).resolve().parents[1]
AERIAL_PASS = ROOT / "examples" / "deliveries" / "aerial-pass"


# --- helpers ---------------------------------------------------------------------------------

#: The ITT's tolerance for the aerial examples, stated by the checker (--param): the manifest's
#: tender.parameters only declares it (evidence, never a value in force; red team R1).
ITT_XY = ["tolerance_xy=0.5m"]


def check(d: Path, prof: Any, *, params: Any = None, **kw: Any) -> Any:
    """``api.check`` with the ITT tolerance given by the checker (--param) when the profile leaves
    tolerance_xy unset and the test gives no parameters of its own."""
    if params is None:
        from orthospec.profile.loader import ResolvedProfile, load_profile

        prof = prof if isinstance(prof, ResolvedProfile) else load_profile(prof)
        p = prof.parameters.get("tolerance_xy")
        params = ITT_XY if p is not None and p.value is None and p.default is None else []
        crs = prof.parameters.get("map_crs")
        if crs is not None and crs.value is None:
            params = [*params, "map_crs=EPSG:25832"]  # the ITT's map projection (red team R16)
    return _check(d, prof, params=params, **kw)

def copy_pass(tmp_path: Path, name: str = "d") -> Path:
    dst = tmp_path / name
    shutil.copytree(AERIAL_PASS, dst)
    return dst


TOLERANCE_FROM_ITT = (
    "tolerance_xy: {unit: m, required: true, description: tolerance from the ITT}\n"
)


def profile(
    tmp_path: Path, rules: str, *, parameters: str = TOLERANCE_FROM_ITT, name: str = "regress.yaml"
) -> Path:
    """A small profile (format of tests/data/profiles/mini.yaml) with the given rules."""
    text = (
        textwrap.dedent("""\
        orthospec_profile: 1
        id: regress
        version: 1.0.0
        title: Regression profile
        source: {title: JRC, seed: 002_7421c4ca450e31c6.txt}
        parameters:
        """)
        + textwrap.indent(textwrap.dedent(parameters), "  ")
        + "rules:\n"
        + textwrap.indent(textwrap.dedent(rules), "  ")
    )
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def records(doc: dict[str, Any], rule: str) -> dict[str, dict[str, Any]]:
    return {r["item"]: r for r in all_records(doc) if r["rule"] == rule}


def reasons(doc: dict[str, Any]) -> str:
    return "\n".join(doc["rollup"]["reasons"])


IMAGE_RULE = """\
- id: R-CLOUD
  title: cloud cover per image
  clause: {document: JRC EUR 23638 EN, section: "6.3"}
  quote: "The coefficient of variation"
  scope: image
  measure: images.cloud_cover
  requirement: {op: "<=", value: 5, unit: "%"}
  consequence: reject_item
"""


def image_rollup(level: str) -> str:
    return f"""\
- id: R-IMAGE-SHARE
  title: image share
  clause: {{document: JRC EUR 23638 EN, section: "12.3"}}
  quote: "more than 5% of the images tested fail on one or more of these specifications"
  scope: delivery
  measure: rollup.image_rejected_share
  requirement: {{op: "<=", value: 5, unit: "%"}}
  level: {level}
  consequence: return_delivery
"""


def cloudy(d: Path, n: int) -> list[str]:
    """Give the first n images 50 % cloud cover (the R-CLOUD rule rejects them)."""
    header, rows = read_table(d, "images")
    for r in rows[:n]:
        r["cloud_cover"] = "50.0"
    write_table(d, "images", header, rows)
    return [r["image_id"] for r in rows[:n]]


# --- never pass what was not measured ----------------------------------------------------------


def test_a_value_that_cannot_be_converted_is_missing_not_pass(tmp_path: Path) -> None:
    """Issue 12: a px requirement on an image without a GSD converted to NaN and passed."""
    d = copy_pass(tmp_path)
    m = manifest(d)
    del m["product"]["gsd"]
    write_manifest(d, m)
    header, rows = read_table(d, "images")
    rows[0]["gsd"] = ""
    write_table(d, "images", header, rows)
    prof = profile(
        tmp_path,
        """\
        - id: R-FH-PX
          title: flying height in pixels
          clause: {document: JRC EUR 23638 EN, section: "5.2.1"}
          quote: "Flying height"
          scope: image
          measure: images.flying_height
          requirement: {op: "<=", value: 1000000000, unit: px}
          consequence: reject_item
        """,
    )
    doc = check(d, prof, date=DATE).document
    recs = records(doc, "R-FH-PX")
    no_gsd, with_gsd = rows[0]["image_id"], rows[1]["image_id"]
    assert recs[no_gsd]["verdict"] == "missing"
    assert "no GSD" in recs[no_gsd]["message"]
    assert recs[with_gsd]["verdict"] == "pass"
    assert doc["verdict"] == "rejected" and no_gsd in doc["rollup"]["rejected"]["image"]


def test_a_when_over_an_absent_manifest_fact_is_missing_not_not_applicable(tmp_path: Path) -> None:
    d = copy_pass(tmp_path)
    m = manifest(d)
    m["product"].pop("mosaic", None)
    write_manifest(d, m)
    rules = """\
        - id: R-SEAMLINES
          title: seamlines for mosaics
          clause: {document: JRC EUR 23638 EN, section: "12.4", table: 12}
          quote: "Record of the location of seamlines for the mosaics (see 11)"
          scope: delivery
          when: "manifest.product.mosaic == true"
          measure: manifest.vectors.seamlines
          requirement: {op: present}
          consequence: return_delivery
        - id: R-SATELLITE-ONLY
          title: decided whatever the absent fact is
          clause: {document: JRC EUR 23638 EN, section: "9.1"}
          quote: "Satellite"
          scope: delivery
          when: "manifest.sensor.type == 'satellite' and manifest.product.mosaic == true"
          measure: manifest.vectors.seamlines
          requirement: {op: present}
          consequence: return_delivery
        - id: R-NULL-TESTED
          title: the when itself asks whether the fact is given
          clause: {document: JRC EUR 23638 EN, section: "11"}
          quote: "Mosaic"
          scope: delivery
          when: "manifest.product.mosaic != null and manifest.product.mosaic == true"
          measure: manifest.vectors.seamlines
          requirement: {op: present}
          consequence: return_delivery
        """
    doc = check(d, profile(tmp_path, rules), date=DATE).document
    rec = records(doc, "R-SEAMLINES")[doc["delivery"]["id"]]
    assert rec["verdict"] == "missing" and "product.mosaic" in rec["message"]
    assert records(doc, "R-SATELLITE-ONLY")[doc["delivery"]["id"]]["verdict"] == "not_applicable"
    assert records(doc, "R-NULL-TESTED")[doc["delivery"]["id"]]["verdict"] == "not_applicable"
    assert doc["verdict"] == "rejected" and "R-SEAMLINES" in reasons(doc)
    # declaring the fact decides the rule
    m["product"]["mosaic"] = False
    write_manifest(d, m)
    doc2 = check(d, profile(tmp_path, rules), date=DATE).document
    assert records(doc2, "R-SEAMLINES")[doc2["delivery"]["id"]]["verdict"] == "not_applicable"


def test_a_non_finite_threshold_is_an_error_never_a_pass(tmp_path: Path) -> None:
    """Issue 17: `tolerance_xy=1e999` passed everything. The parameter is refused at resolution;
    a threshold expression that overflows to inf is `error` per item in the evaluator."""
    d = copy_pass(tmp_path)
    prof = profile(
        tmp_path,
        """\
        - id: R-RMSEX
          title: block RMSEx
          clause: {document: JRC EUR 23638 EN, section: "12.7"}
          quote: "The planimetric threshold will be applied independently in X, and Y."
          scope: block
          measure: checkpoints.rmse_x
          requirement: {op: "<=", value: "tolerance_xy * 1e308 * 10", unit: m}
          consequence: reject_block
        """,
    )
    doc = check(d, prof, date=DATE).document
    verdicts = {r["verdict"] for r in records(doc, "R-RMSEX").values()}
    assert verdicts == {"error"} and doc["verdict"] == "rejected"
    with pytest.raises((ParameterError, OrthospecError)):
        check(d, prof, date=DATE, params=["tolerance_xy=1e999"])


# --- every mandatory rule can change the verdict -----------------------------------------------


def test_a_recommended_rollup_does_not_switch_off_the_default(tmp_path: Path) -> None:
    """Issue 12: §12.3 made `recommended` also disabled the default image roll-up -> ACCEPTED."""
    d = copy_pass(tmp_path)
    bad = cloudy(d, 1)
    doc = check(d, profile(tmp_path, IMAGE_RULE + image_rollup("recommended")), date=DATE).document
    assert doc["rollup"]["rejected"]["image"] == bad
    assert doc["verdict"] == "rejected"
    assert "any rejected image returns the delivery" in reasons(doc)
    # a MANDATORY roll-up rule does replace the default: 1 of 30 (3.3 %) is within §12.3
    doc2 = check(
        d, profile(tmp_path, IMAGE_RULE + image_rollup("mandatory"), name="m.yaml"), date=DATE
    ).document
    assert doc2["verdict"] == "accepted", reasons(doc2)
    assert records(doc2, "R-IMAGE-SHARE")[doc2["delivery"]["id"]]["measured"][
        "value"
    ] == pytest.approx(100 / 30)


def test_two_of_thirty_images_unusable_is_more_than_five_percent(tmp_path: Path) -> None:
    """§12.3: 2/30 = 6.7 % > 5 %: the mandatory image-share rule returns the delivery."""
    d = copy_pass(tmp_path)
    _, rows = read_table(d, "images")
    assert len(rows) == 30
    cloudy(d, 2)
    doc = check(d, profile(tmp_path, IMAGE_RULE + image_rollup("mandatory")), date=DATE).document
    rec = records(doc, "R-IMAGE-SHARE")[doc["delivery"]["id"]]
    assert rec["verdict"] == "fail" and rec["measured"]["value"] == pytest.approx(200 / 30)
    assert doc["verdict"] == "rejected" and "R-IMAGE-SHARE" in reasons(doc)


def test_two_truncated_images_reject_the_delivery_under_jrc_v3(tmp_path: Path) -> None:
    """Issue 12: 2 of 30 images truncated under jrc-v3 was ACCEPTED."""
    d = copy_pass(tmp_path)
    _, rows = read_table(d, "images")
    bad = sorted(r["image_id"] for r in rows[:2])
    for r in rows[:2]:
        p = d / r["file"]
        p.write_bytes(p.read_bytes()[:200])
    doc = check(d, "jrc-v3", date=DATE, options={"workers": 1}).document
    assert doc["verdict"] == "rejected"
    assert set(bad) <= set(doc["rollup"]["rejected"].get("image", []))
    assert "JRC-12.3-IMAGE-FAIL-SHARE" in reasons(doc) or "any rejected image" in reasons(doc)


DEM_RULE = """\
- id: R-DEM
  title: DEM height accuracy
  clause: {document: JRC EUR 23638 EN, section: "8.3", table: 5}
  quote: "2 x planimetric 1-D RMSE required"
  scope: dem
  measure: dem.rmse_z
  requirement: {op: "<=", value: "2 * tolerance_xy", unit: m}
  consequence: reject_block
- id: R-BLOCK-SHARE
  title: block share
  clause: {document: JRC EUR 23638 EN, section: "12.8"}
  quote: "Should more than 5% of the blocks that are subjected to external QC fail"
  scope: project
  measure: rollup.block_rejected_share
  requirement: {op: "<=", value: 50, unit: "%"}
  consequence: return_delivery
"""


def _with_dem(d: Path, text: str) -> None:
    (d / "tables" / "dem.csv").write_text(text, encoding="utf-8")
    m = manifest(d)
    m["tables"]["dem"] = "tables/dem.csv"
    write_manifest(d, m)


def test_a_failing_dem_rejects_only_the_blocks_it_serves(tmp_path: Path) -> None:
    """Issue 12: JRC-T5-DEM-HEIGHT-ACCURACY rejected every block for one failing DEM."""
    d = copy_pass(tmp_path)
    _with_dem(d, "dem_id,block,rmse_z\nDEM-A,B01,0.4\nDEM-B,B02;B03,3.0\n")
    doc = check(d, profile(tmp_path, DEM_RULE), date=DATE).document
    recs = records(doc, "R-DEM")
    assert (recs["DEM-A"]["verdict"], recs["DEM-B"]["verdict"]) == ("pass", "fail")
    assert doc["rollup"]["rejected"] == {"block": ["B02", "B03"]}
    # 2 of 3 blocks rejected is above the profile's 50 %: returned, for the stated reason
    assert (
        doc["verdict"] == "rejected"
        and "R-DEM" in reasons(doc)
        and "B01" not in reasons(doc).split("R-DEM")[1]
    )


def test_a_failing_dem_with_unknown_blocks_is_a_delivery_level_finding(tmp_path: Path) -> None:
    d = copy_pass(tmp_path)
    _with_dem(d, "dem_id,block,rmse_z\nDEM-A,B01,0.4\nDEM-X,,3.0\n")
    doc = check(d, profile(tmp_path, DEM_RULE), date=DATE).document
    assert doc["rollup"]["rejected"] == {}  # no block is blamed without evidence
    assert doc["verdict"] == "rejected"
    assert "DEM-X" in reasons(doc) and "blocks they serve are unknown" in reasons(doc)


def test_a_dem_without_a_block_is_placed_by_its_footprint(tmp_path: Path) -> None:
    """A DEM row with no `block` but a delivered file: its footprint decides the blocks it serves."""
    import rasterio
    from rasterio.transform import from_origin

    d = copy_pass(tmp_path)
    (d / "dem").mkdir()
    # 4 km x 6 km inside block B03 (x 512500-519500, y 5411000-5418200), away from B01 and B02
    with rasterio.open(
        d / "dem" / "b03.tif",
        "w",
        driver="GTiff",
        width=10,
        height=10,
        count=1,
        dtype="float32",
        crs="EPSG:25832",
        transform=from_origin(515000, 5418000, 400, 600),
    ) as ds:
        ds.write(np.full((1, 10, 10), 300.0, dtype="float32"))
    _with_dem(d, "dem_id,file,rmse_z\nDEM-F,dem/b03.tif,3.0\n")
    doc = check(d, profile(tmp_path, DEM_RULE), date=DATE).document
    assert records(doc, "R-DEM")["DEM-F"]["verdict"] == "fail"
    assert doc["rollup"]["rejected"] == {"block": ["B03"]}


# --- fail-open by the contractor (issue 17) ----------------------------------------------------


def test_a_nan_vertex_in_a_block_polygon_is_not_accepted(tmp_path: Path) -> None:
    d = copy_pass(tmp_path)
    text = (d / "delivery.yaml").read_text(encoding="utf-8")
    text = text.replace("  - [507000.0, 5400000.0]", "  - [.nan, 5400000.0]", 1)
    (d / "delivery.yaml").write_text(text, encoding="utf-8")
    try:
        doc = check(d, "jrc-v3", date=DATE, options={"workers": 1}).document
    except OrthospecError as exc:  # refusing the manifest (exit 2) is also a correct outcome
        assert "polygon" in str(exc) or "nan" in str(exc).lower()
        return
    assert doc["verdict"] == "rejected"
    rec = records(doc, "JRC-12.7-RMSEX")["B01"]
    assert rec["verdict"] == "error" and "not a finite number" in rec["message"]
    assert "B01" in doc["rollup"]["rejected"]["block"]


def test_an_error_for_the_whole_block_scope_returns_the_delivery(tmp_path: Path) -> None:
    """A block-scope finding on item `*` used to be intersected with the block ids and vanish."""
    d = copy_pass(tmp_path)
    m = manifest(d)
    m["blocks"] = []  # no blocks declared, none derivable from a table: a block rule has no items
    del m["tables"]["images"]
    write_manifest(d, m)
    header, _ = read_table(d, "checkpoints")
    write_table(d, "checkpoints", header, [])  # and the table gives none either
    prof = profile(
        tmp_path,
        """\
        - id: R-RMSEX
          title: block RMSEx
          clause: {document: JRC EUR 23638 EN, section: "12.7"}
          quote: "The planimetric threshold will be applied independently in X, and Y."
          scope: block
          measure: checkpoints.rmse_x
          requirement: {op: "<=", value: tolerance_xy, unit: m}
          consequence: reject_block
        - id: R-BLOCK-SHARE
          title: block share
          clause: {document: JRC EUR 23638 EN, section: "12.8"}
          quote: "Should more than 5% of the blocks that are subjected to external QC fail"
          scope: project
          measure: rollup.block_rejected_share
          requirement: {op: "<=", value: 5, unit: "%"}
          consequence: return_delivery
        """,
    )
    try:
        doc = check(d, prof, date=DATE).document
    except OrthospecError:
        return  # refusing a delivery without blocks (exit 2) is also not an acceptance
    assert records(doc, "R-RMSEX")["*"]["verdict"] in ("missing", "error")
    assert doc["verdict"] == "rejected" and "R-RMSEX" in reasons(doc)


def test_deleting_all_check_points_of_a_failing_block_is_not_accepted(tmp_path: Path) -> None:
    """Issue 17: the block share counted only blocks with check points -> ACCEPTED. Issue 26: a block
    without check points is a missing checker measurement - never accepted, the checker must measure
    B02 (it is not rejected for the checker's omission)."""
    d = copy_pass(tmp_path)
    header, rows = read_table(d, "checkpoints")
    write_table(d, "checkpoints", header, [r for r in rows if r["block"] != "B02"])
    doc = check(d, "jrc-v3", date=DATE, options={"workers": 1}).document
    assert records(doc, "JRC-12.7-RMSEX")["B02"]["verdict"] == "missing"
    assert doc["verdict"] == "incomplete"
    assert any(
        t.startswith("B02: not measured") and "JRC-12.7-RMSEX" in t
        for t in doc["rollup"]["incomplete"]
    )


# --- parameter authority (built-in rules) -------------------------------------------------------


def _scale_b02_dy(table: Path) -> None:
    """B02's northing residuals x2.2 in a check point table (the checker's, in its folder)."""
    with table.open(encoding="utf-8", newline="") as f:
        r = csv.DictReader(f)
        header, rows = list(r.fieldnames or []), list(r)
    for row in rows:
        if row["block"] == "B02":
            row["y"] = f"{float(row['y_ref']) + 2.2 * (float(row['y']) - float(row['y_ref'])):.3f}"
    with table.open("w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def _planted_rmsey(d: Path) -> None:
    """Red team R1's defect: B02's northing residuals x2.2 (RMSEy about 0.63 m > 0.5 m, JRC §12.7),
    the block's reported RMSEs set to what the edited table gives (so only §12.7 can catch it)."""
    header, rows = read_table(d, "checkpoints")
    for r in rows:
        if r["block"] == "B02":
            r["y"] = f"{float(r['y_ref']) + 2.2 * (float(r['y']) - float(r['y_ref'])):.3f}"
    write_table(d, "checkpoints", header, rows)
    used = [r for r in rows if r["block"] == "B02" and r["excluded"] != "true"]
    ex = [float(r["x"]) - float(r["x_ref"]) for r in used]
    ey = [float(r["y"]) - float(r["y_ref"]) for r in used]
    rmse = {
        "rmse_x": math.sqrt(sum(e * e for e in ex) / len(ex)),
        "rmse_y": math.sqrt(sum(e * e for e in ey) / len(ey)),
    }
    assert rmse["rmse_y"] > 0.5  # the planted defect: §12.7 fails at the ITT's 0.5 m
    m = manifest(d)
    m["tender"]["parameters"]["tolerance_xy"] = {
        "value": 1.0,
        "unit": "m",
    }  # the contractor's own "ITT"
    for b in m["blocks"]:
        if b["id"] == "B02":
            b["reported"] = {k: {"value": round(v, 3), "unit": "m"} for k, v in rmse.items()}
    write_manifest(d, m)


def test_r1_a_manifest_tolerance_never_decides_acceptance(tmp_path: Path) -> None:
    """Red team R1 (wrong ACCEPTED): the manifest's tender.parameters.tolerance_xy 1.0 m used to fill
    the ITT tolerance and accept a 0.63 m RMSEy. The brief: the manifest "is evidence, never
    authority: it cannot set or loosen a threshold"; JRC §2.5 "the tolerance stated in the ITT"."""
    from tests.checking import check_with, resigned

    d = copy_pass(tmp_path)
    _planted_rmsey(d)
    shipped = ROOT / "examples" / "checker" / "aerial-pass"
    # nobody on the checker's side states the tolerance: exit 2 with the advice, never a verdict
    silent = resigned(shipped, d, tmp_path / "silent.yaml", parameters={})
    with pytest.raises(ParameterError) as ei:
        check_with(d, "jrc-v3", checker=silent, date=DATE)
    msg = str(ei.value)
    assert (
        "tolerance_xy (m)" in msg
        and "--param" in msg
        and "checker file" in msg
        and "tender profile" in msg
    )
    # the checker's file states the ITT's 0.5 m: rejected on §12.7, and the contractor's 1.0 m is a finding;
    # the checker's own measurements (its folder's table) show the same B02 defect
    signed = resigned(shipped, d, tmp_path / "signed.yaml")
    _scale_b02_dy(signed.parent / "tables" / "checkpoints.csv")
    doc = check_with(d, "jrc-v3", checker=signed, date=DATE).document
    assert doc["profile"]["parameters"]["tolerance_xy"] == {
        "value": 0.5,
        "unit": "m",
        "source": "checker",
        "declared": 1.0,
    }
    assert records(doc, "JRC-12.7-RMSEY")["B02"]["verdict"] == "fail"
    declared = records(doc, "ORTHOSPEC-ITT-DECLARED")["tolerance_xy"]
    assert declared["verdict"] == "fail" and "declares tolerance_xy = 1 m" in declared["message"]
    assert "source: checker" in declared["message"]
    assert doc["verdict"] == "rejected"
    assert "JRC-12.7-RMSEY" in reasons(doc) and "ORTHOSPEC-ITT-DECLARED" in reasons(doc)
    assert not [
        r for r in all_records(doc) if r["rule"] == "ORTHOSPEC-ITT-SOURCE"
    ]  # nothing to warn about


def test_r5_check_points_edited_after_the_checker_signed_exit_2(tmp_path: Path) -> None:
    """Red team R5: the contractor deletes the worst check points after the checker signed their
    source (JRC §12.4): the example checker file pins tables/checkpoints.csv, so it no longer applies."""
    from tests.checking import check_with

    d = copy_pass(tmp_path)
    header, rows = read_table(d, "checkpoints")
    write_table(d, "checkpoints", header, rows[:-1])
    shipped = ROOT / "examples" / "checker" / "aerial-pass"
    with pytest.raises(OrthospecError) as ei:
        check_with(d, "jrc-v3", checker=shipped, date=DATE)
    assert "aerial-pass/checker.yaml:12 pins tables/checkpoints.csv sha256" in str(ei.value)
    assert "the checker's verdicts were given on other content" in str(ei.value)
    # the shipped example, unchanged, is what the checker signed
    assert (
        check_with(AERIAL_PASS, "jrc-v3", checker=shipped, date=DATE).document["verdict"]
        == "accepted"
    )


def test_a_manifest_value_different_from_the_tender_is_a_finding(tmp_path: Path) -> None:
    d = copy_pass(tmp_path)
    tender = profile(
        tmp_path,
        IMAGE_RULE,
        parameters="tolerance_xy: {unit: m, value: 0.5, description: ITT §4.1}\n",
    )
    m = manifest(d)
    m["tender"]["parameters"]["tolerance_xy"] = {"value": 1.0, "unit": "m"}  # the tender says 0.5 m
    write_manifest(d, m)
    doc = check(d, tender, date=DATE).document
    assert doc["profile"]["parameters"]["tolerance_xy"]["source"] == "tender"
    rec = records(doc, "ORTHOSPEC-ITT-DECLARED")["tolerance_xy"]
    assert rec["verdict"] == "fail" and rec["level"] == "mandatory"
    assert "declares tolerance_xy = 1 m" in rec["message"] and "0.5 m" in rec["message"]
    assert (
        doc["profile"]["parameters"]["tolerance_xy"]["value"] == 0.5
    )  # the tender's value is used
    assert doc["verdict"] == "rejected" and "ORTHOSPEC-ITT-DECLARED" in reasons(doc)


# --- systematic error (JRC §12.4; USGS bias, seed 000) -----------------------------------------


def test_a_uniform_shift_under_the_tolerance_shows_as_a_significant_bias(tmp_path: Path) -> None:
    """A block shifted by 0.45 m (tolerance 0.5 m) passes RMSE but its mean error is significant."""
    d = copy_pass(tmp_path)
    header, rows = read_table(d, "checkpoints")
    for r in rows:
        if r["block"] == "B01":
            r["x"] = f"{float(r['x']) + 0.45:.3f}"
    write_table(d, "checkpoints", header, rows)
    prof = profile(
        tmp_path,
        """\
        - id: R-BIAS-X
          title: no significant systematic error in X
          clause: {document: JRC EUR 23638 EN, section: "12.4"}
          quote: "check points"
          scope: block
          measure: checkpoints.bias_p_x
          requirement: {op: ">=", value: 0.05, unit: "1"}
          consequence: reject_block
        """,
    )
    doc = check(d, prof, date=DATE).document
    # expected t by hand from the table: |mean(dx)| / (s(dx) / sqrt(n)), s with n - 1
    b01 = [
        r
        for r in rows
        if r["block"] == "B01" and r.get("excluded", "").lower() not in ("true", "1")
    ]
    dx = np.array([float(r["x"]) - float(r["x_ref"]) for r in b01])
    t = abs(dx.mean()) / (dx.std(ddof=1) / math.sqrt(dx.size))
    assert t > 4  # far beyond any usual critical value (t_0.975,24 = 2.064)
    recs = records(doc, "R-BIAS-X")
    assert recs["B01"]["verdict"] == "fail" and recs["B01"]["measured"]["value"] < 1e-3
    assert {recs["B02"]["verdict"], recs["B03"]["verdict"]} == {"pass"}


def test_not_reporting_the_block_rmse_does_not_switch_the_cross_check_off(tmp_path: Path) -> None:
    """A block without `reported:` used to make the reported-vs-recomputed rule not applicable."""
    d = copy_pass(tmp_path)
    m = manifest(d)
    del m["blocks"][0]["reported"]
    write_manifest(d, m)
    prof = profile(
        tmp_path,
        """\
        - id: R-REPORTED-X
          title: reported RMSEx agrees
          clause: {document: JRC EUR 23638 EN, section: "9.5"}
          quote: "Number of checkpoints, Checkpoint RMSE, Maximum Checkpoint Discrepancy"
          scope: block
          measure: checkpoints.reported_diff_x
          requirement: {op: "<=", value: 0.01, unit: m}
          consequence: reject_block
        """,
    )
    doc = check(d, prof, date=DATE).document
    recs = records(doc, "R-REPORTED-X")
    assert (
        recs["B01"]["verdict"] == "missing" and "reported gives no rmse_x" in recs["B01"]["message"]
    )
    assert recs["B02"]["verdict"] == "pass"
    assert doc["verdict"] == "rejected" and "B01" in doc["rollup"]["rejected"]["block"]


def test_marking_only_good_images_as_sample_cannot_hide_failing_ones(tmp_path: Path) -> None:
    """The images table's `sample` column comes with the delivery: a failing image is tested anyway."""
    d = copy_pass(tmp_path)
    bad = cloudy(d, 2)
    header, rows = read_table(d, "images")
    for r in rows:
        r["sample"] = "true" if r["image_id"] not in bad and r is rows[5] else ""
    write_table(d, "images", [*header, "sample"] if "sample" not in header else header, rows)
    doc = check(d, profile(tmp_path, IMAGE_RULE + image_rollup("mandatory")), date=DATE).document
    rec = records(doc, "R-IMAGE-SHARE")[doc["delivery"]["id"]]
    assert rec["measured"]["value"] == pytest.approx(200 / 3)  # 2 failing of the 3 tested
    assert doc["verdict"] == "rejected"


def test_a_per_item_when_over_a_missing_value_is_missing_for_that_item(tmp_path: Path) -> None:
    d = copy_pass(tmp_path)
    header, rows = read_table(d, "images")
    rows[0]["sun_elevation"] = ""
    write_table(d, "images", header, rows)
    prof = profile(
        tmp_path,
        """\
        - id: R-LOW-SUN-ROLL
          title: roll limit when the sun is low
          clause: {document: JRC EUR 23638 EN, section: "5.2.5"}
          quote: "sun elevation"
          scope: image
          when: "images.sun_elevation < 35"
          measure: images.roll
          requirement: {op: "<=", value: 1, unit: deg}
          consequence: reject_item
        """,
    )
    doc = check(d, prof, date=DATE).document
    recs = records(doc, "R-LOW-SUN-ROLL")
    first, second = rows[0]["image_id"], rows[1]["image_id"]
    assert recs[first]["verdict"] == "missing" and "images.sun_elevation" in recs[first]["message"]
    assert recs[second]["verdict"] == "not_applicable"  # 43.1 deg: decided, the rule does not apply


def test_a_mandatory_rule_with_consequence_warn_still_changes_the_verdict(tmp_path: Path) -> None:
    """Issue 12: nine mandatory jrc-v3 rules had consequence `warn` and could never reject."""
    d = copy_pass(tmp_path)
    header, rows = read_table(d, "checkpoints")
    b01 = [r for r in rows if r["block"] == "B01"][:8]
    write_table(d, "checkpoints", header, [r for r in rows if r["block"] != "B01"] + b01)
    prof = profile(
        tmp_path,
        """\
        - id: R-MIN-CHECKPOINTS
          title: at least 20 check points per block
          clause: {document: JRC EUR 23638 EN, section: "12.4", table: 12}
          quote: "Generally a minimum number of 20 well-distributed Check Points per site is necessary"
          scope: block
          measure: checkpoints.n
          requirement: {op: ">=", value: 20, unit: "1"}
          level: mandatory
          consequence: warn
        """,
    )
    doc = check(d, prof, date=DATE).document
    assert records(doc, "R-MIN-CHECKPOINTS")["B01"]["verdict"] == "fail"
    assert doc["verdict"] == "rejected" and "R-MIN-CHECKPOINTS" in reasons(doc)


def _cut_block(d: Path, block: str, keep: int) -> None:
    header, rows = read_table(d, "checkpoints")
    mine = [r for r in rows if r["block"] == block][:keep]
    write_table(d, "checkpoints", header, [r for r in rows if r["block"] != block] + mine)


def test_eight_check_points_in_a_block_are_never_accepted_under_jrc_v3(tmp_path: Path) -> None:
    """Issue 12, first observation: B01 cut to 8 check points was ACCEPTED. Issue 26: the shortfall is
    the checker's (more points, §12.7), so the check is incomplete - not accepted, B01 not rejected."""
    d = copy_pass(tmp_path)
    _cut_block(d, "B01", 8)
    doc = check(d, "jrc-v3", date=DATE, options={"workers": 1}).document
    assert records(doc, "JRC-12.4-T12-MIN-CHECKPOINTS")["B01"]["verdict"] == "fail"
    assert doc["verdict"] == "incomplete" and "JRC-12.4-T12-MIN-CHECKPOINTS" not in reasons(doc)
    assert any(t.startswith("B01: 12 more check points") for t in doc["rollup"]["incomplete"])


def test_the_contractor_cannot_set_the_standards_numbers(tmp_path: Path) -> None:
    """Issue 12: `min_checkpoints: 5` and `fail_share_max: 50 %` in the manifest were used."""
    d = copy_pass(tmp_path)
    _cut_block(d, "B01", 8)
    m = manifest(d)
    m["tender"]["parameters"]["min_checkpoints"] = 5
    m["tender"]["parameters"]["fail_share_max"] = {"value": 50, "unit": "%"}
    write_manifest(d, m)
    doc = check(d, "jrc-v3", date=DATE, options={"workers": 1}).document
    params = doc["profile"]["parameters"]
    assert (
        params["min_checkpoints"]["value"] == 20
        and params["min_checkpoints"]["source"] == "standard"
    )
    declared = records(doc, "ORTHOSPEC-ITT-DECLARED")
    assert (
        declared["min_checkpoints"]["verdict"] == "fail"
        and declared["fail_share_max"]["verdict"] == "fail"
    )
    assert records(doc, "JRC-12.4-T12-MIN-CHECKPOINTS")["B01"]["verdict"] == "fail"
    assert doc["verdict"] == "rejected" and "ORTHOSPEC-ITT-DECLARED" in reasons(doc)


def test_a_check_point_on_a_gcp_and_imprecise_check_points_are_never_accepted_under_jrc_v3(
    tmp_path: Path,
) -> None:
    """Issue 12: one check point on a GCP and every check point at 1.0 m precision was ACCEPTED.
    Issue 26: both are the checker's to replace, so the check is incomplete, nothing rejected."""
    d = copy_pass(tmp_path)
    _, gcps = read_table(d, "gcps")
    g = next(r for r in gcps if r["block"] == "B01")
    header, rows = read_table(d, "checkpoints")
    first = next(r for r in rows if r["block"] == "B01")
    dx, dy = float(first["x"]) - float(first["x_ref"]), float(first["y"]) - float(first["y_ref"])
    first["x_ref"], first["y_ref"] = g["x"], g["y"]
    first["x"], first["y"] = f"{float(g['x']) + dx:.3f}", f"{float(g['y']) + dy:.3f}"
    for r in rows:
        r["precision_xy"] = "1.0"
    write_table(d, "checkpoints", header, rows)
    doc = check(d, "jrc-v3", date=DATE, options={"workers": 1}).document
    assert records(doc, "JRC-12.5-INDEPENDENT-CHECKPOINTS")["B01"]["verdict"] == "fail"
    assert records(doc, "JRC-DEF-CHECKPOINT-ACCURACY")[first["point_id"]]["verdict"] == "fail"
    assert doc["verdict"] == "incomplete" and doc["rollup"]["rejected"] == {}
    assert any("JRC-12.5-INDEPENDENT-CHECKPOINTS" in t for t in doc["rollup"]["incomplete"])


def test_space_resection_rule_applies_when_a_block_used_space_resection(tmp_path: Path) -> None:
    """Issue 12: JRC-12.8-SPACE-RESECTION never applied (it read a manifest key nobody wrote)."""
    d = copy_pass(tmp_path)
    m = manifest(d)
    m["product"].pop("orthorectification", None)
    for b in m["blocks"]:
        b["method"] = "space_resection"
    write_manifest(d, m)
    header, rows = read_table(d, "checkpoints")
    for r in rows:
        if r["block"] == "B02":
            r["x"] = f"{float(r['x']) + 1.0:.3f}"
    write_table(d, "checkpoints", header, rows)
    doc = check(d, "jrc-v3", date=DATE, options={"workers": 1}).document
    rec = next(iter(records(doc, "JRC-12.8-SPACE-RESECTION").values()))
    assert rec["verdict"] == "fail", rec["message"]
    assert doc["verdict"] == "rejected" and "JRC-12.8-SPACE-RESECTION" in reasons(doc)


def test_an_unreadable_declared_value_is_a_finding_not_silence(tmp_path: Path) -> None:
    """A declared contract value that cannot be read (decimal comma) is not quietly ignored."""
    d = copy_pass(tmp_path)
    m = manifest(d)
    m["tender"]["parameters"]["tolerance_xy"] = "0,5"
    write_manifest(d, m)
    doc = check(d, profile(tmp_path, IMAGE_RULE), date=DATE, params=["tolerance_xy=0.5m"]).document
    rec = records(doc, "ORTHOSPEC-ITT-DECLARED")["tolerance_xy"]
    assert rec["verdict"] == "fail" and "tender.parameters.tolerance_xy" in rec["message"]


def test_a_when_that_tests_an_unset_parameter_is_not_applicable_not_missing(tmp_path: Path) -> None:
    """usgs-insitu's CE90/CE95 rules apply `when: tolerance_ce90 != null and ...`: with the optional
    tolerance unset they are not applicable (the delivery was rejected for them before); with it set
    they judge every block. aerial-pass has RMSEx/y of about 0.3 m per block, so its CE90 (formula
    2.1460/2 (RMSEx + RMSEy), USGS seed) is far above 0.05 m."""
    d = copy_pass(tmp_path)
    unset = check(d, "usgs-insitu", date=DATE).document
    for rule in ("USGS-CE90", "USGS-CE95"):
        assert {r["verdict"] for r in records(unset, rule).values()} == {"not_applicable"}, rule
    assert unset["verdict"] == "accepted", reasons(unset)
    tight = check(d, "usgs-insitu", params={"tolerance_ce90": "0.05 m"}, date=DATE).document
    formula, empirical = records(tight, "USGS-CE90"), records(tight, "USGS-CE90-EMPIRICAL")
    for block in ("B01", "B02", "B03"):  # the bias test picks one of the two CE90s per block
        assert {formula[block]["verdict"], empirical[block]["verdict"]} == {
            "fail",
            "not_applicable",
        }, block
    assert tight["verdict"] == "rejected"


# --- the contractor's delivery is evidence, never authority (docs/CHECKER.md, JRC §2) ----------
# A waiver written in the contractor's delivery.yaml and a verdict in the delivery's own
# manual_checks table used to change the verdict: a contractor could waive a failing mandatory
# rule with an approver name it typed and be ACCEPTED. Now they are a request and a statement.

from tests.checking import check_with, write_checker  # noqa: E402

from orthospec.delivery.checker import load_checker  # noqa: E402

#: one failing image (I3, roll 4 deg > 3 deg) under the mini profile's mandatory R-ROLL
_ONE_BAD_ROLL = "image_id,file,block,roll,flying_height,std_dn\nI1,a.tif,B1,0.5,1000,30\nI3,c.tif,B2,4,1100,30\n"
_SIGN_ONLY = """\
orthospec_checker: 1
checker: {name: Eva External, role: external QC}
delivery: {id: D1}
parameters: {tolerance_xy: {value: 0.5, unit: m}}
manual_checks:
  - {check: R-VIS, item: "*", date: 2026-01-02, verdict: pass}
"""


def _rec(doc: dict[str, Any], rule: str, item: str) -> dict[str, Any]:
    return next(r for r in all_records(doc) if r["rule"] == rule and r["item"] == item)


def test_a_contractor_waiver_of_a_failing_mandatory_rule_is_only_a_request(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    # delivery.yaml (tests/conftest.py MANIFEST) waives R-ROLL for I3, "approver: Chief" typed by the contractor
    root = make_delivery(images=_ONE_BAD_ROLL)
    res = check_with(root, mini_profile, checker=write_checker(tmp_path, _SIGN_ONLY))
    doc = res.document
    rec = _rec(doc, "R-ROLL", "I3")
    assert rec["verdict"] == "fail" and rec["waiver"] is None
    assert (
        rec["waiver_requested"]["approver"] == "Chief"
        and rec["waiver_requested"]["declared_in"] == "delivery.yaml"
    )
    assert doc["waiver_requests"][0]["status"] == "requested by the contractor, not granted"
    assert doc["verdict"] == "rejected" and doc["rollup"]["rejected"] == {"image": ["I3"]}
    roll = next(r for r in res.evaluation.results if r.rule.id == "R-ROLL")
    assert (
        roll.requested["I3"]["approver"] == "Chief"
        and roll.requested["I3"]["requested_by"] == "ACME Mapping"
    )
    (req,) = res.evaluation.waiver_requests
    assert req["status"] == "requested by the contractor, not granted"
    assert req["matched"] == [{"item": "I3", "verdict": "fail"}]
    assert not doc["waivers_unused"]  # a request is not a waiver: nothing granted went unused


def test_a_contractor_waiver_of_a_failing_block_in_aerial_fail_stays_a_fail(tmp_path: Path) -> None:
    d = tmp_path / "aerial-fail"
    shutil.copytree(ROOT / "examples" / "deliveries" / "aerial-fail", d)
    text = (d / "delivery.yaml").read_text(encoding="utf-8")
    assert "\nwaivers: []\n" in text
    (d / "delivery.yaml").write_text(
        text.replace(
            "\nwaivers: []\n",
            (
                "\nwaivers:\n- {rule: JRC-12.7-RMSEY, items: [B02], justification: within our own QC, "
                "approver: 'Paying agency (typed by the contractor)'}\n"
            ),
        ),
        encoding="utf-8",
    )
    res = check_with(d, "jrc-v3", checker=ROOT / "examples" / "checker" / "aerial-fail", date=DATE)
    rec = _rec(res.document, "JRC-12.7-RMSEY", "B02")
    assert rec["verdict"] == "fail" and "B02" in res.document["rollup"]["rejected"]["block"]
    rmsey = next(r for r in res.evaluation.results if r.rule.id == "JRC-12.7-RMSEY")
    assert set(rmsey.requested) == {"B02"}


def test_the_contractors_own_manual_pass_alone_is_missing(make_delivery, mini_profile) -> None:
    # the delivery's manual_checks row "R-VIS,*,Joe Bloggs,2026-01-01,pass" is the contractor's statement
    root = make_delivery(images=_ONE_BAD_ROLL.replace(",4,", ",1,"))
    doc = check_with(
        root, mini_profile, params=ITT_XY
    ).document  # tolerance_xy stated by the checker (--param)
    vis = _rec(doc, "R-VIS", "D1")
    assert vis["verdict"] == "missing"
    assert "Joe Bloggs" in vis["message"] and "not a verdict" in vis["message"]
    assert vis["evidence"][0]["file"] == "tables/manual.csv" and vis["evidence"][0]["rows"] == [1]
    # never accepted: signing it is the checker's open work (issue 26: incomplete, not rejected)
    assert doc["verdict"] == "incomplete" and doc["rollup"]["reasons"] == []
    assert [t.split(":", 1)[0] for t in doc["rollup"]["incomplete"]] == ["R-VIS"]


def test_the_checkers_manual_verdict_decides_and_names_both_parties(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    root = make_delivery(images=_ONE_BAD_ROLL.replace(",4,", ",1,"))
    fail = _SIGN_ONLY.replace("verdict: pass", "verdict: fail, note: haze on I1")
    doc = check_with(root, mini_profile, checker=write_checker(tmp_path, fail)).document
    vis = _rec(doc, "R-VIS", "D1")
    assert vis["verdict"] == "fail" and doc["verdict"] == "rejected"
    assert vis["message"].startswith(
        "judged failing by Eva External, external QC on 2026-01-02: haze on I1"
    )
    assert "contractor's internal QC: 'pass' (tables/manual.csv row 1)" in vis["message"]
    assert {e["file"] for e in vis["evidence"]} == {"tables/manual.csv", "checker:checker.yaml"}
    ok = check_with(
        root, mini_profile, checker=write_checker(tmp_path, _SIGN_ONLY, "ok.yaml")
    ).document
    signed = _rec(ok, "R-VIS", "D1")
    assert signed["verdict"] == "pass" and ok["verdict"] == "accepted"
    assert signed["message"].startswith("signed by Eva External, external QC on 2026-01-02")


def test_the_same_waiver_in_the_checker_file_is_in_force(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    root = make_delivery(images=_ONE_BAD_ROLL)
    res = check_with(
        root, mini_profile, checker=write_checker(tmp_path)
    )  # tests/checking.py MINI_CHECKER
    rec = _rec(res.document, "R-ROLL", "I3")
    assert rec["verdict"] == "waived" and rec["waived_verdict"] == "fail"
    assert rec["waiver"]["approver"] == "Chief" and rec["waiver"]["declared_in"] == "checker"
    assert rec["waiver"]["granted_by"] == "Eva External (external QC, Paying Agency)"
    assert res.document["verdict"] == "accepted"
    (req,) = (
        res.evaluation.waiver_requests
    )  # the contractor asked for it too: granted by the checker
    assert (
        req["matched"] == [{"item": "I3", "verdict": "waived"}]
        and "not granted" not in req["status"]
    )


def test_a_checker_file_inside_the_delivery_is_refused(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    root = make_delivery()
    inside = write_checker(root / "tables", name="checker.yaml")
    with pytest.raises(OrthospecError, match="inside the delivery"):
        check_with(root, mini_profile, checker=inside)
    link = tmp_path / "looks-outside.yaml"  # a link outside that leads into the delivery
    link.symlink_to(inside)
    with pytest.raises(OrthospecError, match="inside the delivery"):
        load_checker(link, delivery_root=root)


def test_a_waiver_in_the_tender_profile_is_in_force(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    """The buyer's own tender profile may grant a waiver (the checker's side, like the checker's file)."""
    text = mini_profile.read_text(encoding="utf-8") + textwrap.dedent("""\
        waivers:
          - {rule: R-ROLL, items: [I3], justification: ridge turbulence accepted in the ITT, approver: Tender board}
        """)
    prof = tmp_path / "tender.yaml"
    prof.write_text(text, encoding="utf-8")
    res = check_with(
        make_delivery(images=_ONE_BAD_ROLL), prof, checker=write_checker(tmp_path, _SIGN_ONLY)
    )
    rec = _rec(res.document, "R-ROLL", "I3")
    assert rec["verdict"] == "waived" and rec["waived_verdict"] == "fail"
    assert (
        rec["waiver"]["declared_in"] == "profile"
        and rec["waiver"]["granted_by"] == "tender profile mini 1.0.0"
    )
    assert res.document["verdict"] == "accepted"
    # the contractor's own request for the same item is listed as matched by a granted waiver
    assert res.evaluation.waiver_requests[0]["matched"] == [{"item": "I3", "verdict": "waived"}]


def test_a_granted_waiver_never_turns_an_error_into_waived(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    """A broken check is not waivable: R-CV reading a text column is `error` whatever the checker waives."""
    prof = tmp_path / "p.yaml"
    prof.write_text(
        mini_profile.read_text(encoding="utf-8").replace(
            "measure: images.std_dn", "measure: images.bands"
        ),
        encoding="utf-8",
    )
    waive = _SIGN_ONLY + "waivers:\n  - {rule: R-CV, justification: all of them, approver: Eva}\n"
    res = check_with(
        make_delivery(images=_ONE_BAD_ROLL.replace(",4,", ",1,")),
        prof,
        checker=write_checker(tmp_path, waive, "w.yaml"),
    )
    assert {r["verdict"] for r in all_records(res.document) if r["rule"] == "R-CV"} == {"error"}
    assert res.document["waivers_unused"][0]["rule"] == "R-CV"
