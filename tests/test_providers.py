"""Measure providers on real files: checkpoints, rasters, edges, mosaics, records, generic aggregates."""

import textwrap

import numpy as np
import pandas as pd
import pytest
import rasterio
from rasterio.transform import from_origin
from tests.conftest import EXAMPLES

from orthospec.api import check
from orthospec.measures.synthetic import slanted_edge
from orthospec.qcr import all_records, point_rows

CHECKERS = EXAMPLES.parent / "checker"

PROFILE_HEAD = """\
orthospec_profile: 1
id: t
version: 1.0.0
title: provider test
source: {title: JRC EUR 23638 EN}
parameters:
  tolerance_xy: {unit: m, default: 0.5}
rules:
"""


def profile(tmp_path, *rules: str):
    p = tmp_path / "p.yaml"
    body = "".join(textwrap.indent(textwrap.dedent(r), "  ") for r in rules)
    p.write_text(PROFILE_HEAD + body)
    return p


def rule(rid, scope, measure, req, consequence="reject_item", extra=""):
    return f"""\
- id: {rid}
  title: {rid}
  clause: {{document: JRC EUR 23638 EN, section: "12.7"}}
  quote: q
  scope: {scope}
  measure: {measure}
  requirement: {req}
  consequence: {consequence}
{extra}"""


def recs(doc, rid):
    return {r["item"]: r for r in all_records(doc) if r["rule"] == rid}


def test_block_rmse_equals_numpy_on_the_example(tmp_path):
    p = profile(
        tmp_path,
        rule(
            "RX",
            "block",
            "checkpoints.rmse_x",
            '{op: "<=", value: tolerance_xy, unit: m}',
            "reject_block",
        ),
        rule(
            "RD",
            "block",
            "checkpoints.reported_diff_x",
            '{op: "<=", value: 0.01, unit: m}',
            "reject_block",
        ),
    )
    doc = check(EXAMPLES / "aerial-pass", p, date="2026-01-01").document
    cp = pd.read_csv(EXAMPLES / "aerial-pass" / "tables" / "checkpoints.csv")
    for block, g in cp.groupby("block"):
        keep = g[~g.get("excluded", pd.Series(False, index=g.index)).fillna(False).astype(bool)]
        expected = float(np.sqrt(np.mean((keep["x"] - keep["x_ref"]) ** 2)))
        got = recs(doc, "RX")[block]
        assert got["measured"]["value"] == pytest.approx(expected, rel=1e-9)
        assert got["verdict"] == "pass"
        assert len(got["evidence"][0]["rows"]) == len(g)
        assert recs(doc, "RD")[block]["verdict"] == "pass"  # reported values agree within 1 cm
    table = doc["details"]["checkpoints"]
    assert set(table) == {"B01", "B02", "B03"} and point_rows(table["B01"]["points"])[0]["point_id"]


def test_reported_rmse_that_disagrees_is_a_finding(tmp_path):
    p = profile(
        tmp_path,
        rule(
            "RD",
            "block",
            "checkpoints.reported_diff_y",
            '{op: "<=", value: 0.01, unit: m}',
            "reject_block",
        ),
    )
    # the external statistics are the checker's measurements (its folder beside the examples)
    doc = check(
        EXAMPLES / "aerial-fail", p, date="2026-01-01", checker=CHECKERS / "aerial-fail"
    ).document
    assert recs(doc, "RD")["B02"]["verdict"] == "fail"
    assert "reported RMSE_y" in recs(doc, "RD")["B02"]["message"]


def write_tif(path, arr, *, gsd=0.25, x0=500000.0, y0=5400000.0, nodata=None, crs="EPSG:25832"):
    arr = np.atleast_3d(arr)
    if arr.ndim == 3 and arr.shape[0] not in (1, 3, 4):
        arr = arr.transpose(2, 0, 1)
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=arr.shape[1],
        width=arr.shape[2],
        count=arr.shape[0],
        dtype=arr.dtype,
        crs=crs,
        transform=from_origin(x0, y0, gsd, gsd),
        nodata=nodata,
    ) as ds:
        ds.write(arr)


def delivery_with_images(make_delivery, files: dict[str, np.ndarray | bytes], extra_manifest=""):
    rows = "\n".join(f"{Path_(f).stem},{f},B1" for f in files)
    root = make_delivery(
        images="image_id,file,block\n" + rows + "\n",
        manual=None,
        manifest=f"""\
orthospec_delivery: 1
id: D1
project: {{id: P1, crs: "EPSG:25832"}}
contractor: {{name: ACME}}
sensor: {{type: aerial, digital: true}}
product: {{gsd: {{value: 0.25, unit: m}}, bit_depth: 8}}
blocks: [{{id: B1, polygon: [[500000, 5399968], [500032, 5399968], [500032, 5400000], [500000, 5400000]]}}]
tables: {{images: tables/images.csv}}
{extra_manifest}""",
    )
    for f, data in files.items():
        (root / f).parent.mkdir(parents=True, exist_ok=True)
        if isinstance(data, bytes):
            (root / f).write_bytes(data)
        else:
            write_tif(root / f, data)
    return root


def Path_(f):
    from pathlib import Path

    return Path(f)


def test_raster_measures_and_a_corrupt_file(make_delivery, tmp_path):
    rng = np.random.default_rng(3)
    good = rng.integers(60, 200, (3, 128, 128), dtype=np.uint8)
    sat = good.copy()
    sat[:, :20, :] = 255  # 15.6 % saturated at the bright tail
    root = delivery_with_images(
        make_delivery,
        {"images/a.tif": good, "images/b.tif": sat, "images/c.tif": b"not a tiff at all"},
    )
    p = profile(
        tmp_path,
        rule("READ", "image", "raster.readable", '{op: "true"}'),
        rule("SAT", "image", "raster.saturation_high", '{op: "<=", value: 0.5, unit: "%"}'),
        rule("CRS", "image", "raster.crs_epsg", '{op: "==", value: 25832}'),
    )
    doc = check(root, p, date="2026-01-01").document
    assert {k: v["verdict"] for k, v in recs(doc, "READ").items()} == {
        "a": "pass",
        "b": "pass",
        "c": "fail",
    }
    sat_recs = recs(doc, "SAT")
    assert sat_recs["a"]["verdict"] == "pass" and sat_recs["b"]["verdict"] == "fail"
    assert sat_recs["b"]["measured"]["value"] == pytest.approx(100 * 20 / 128, rel=1e-6)
    assert sat_recs["c"]["verdict"] == "error" and "images/c.tif" in sat_recs["c"]["message"]
    assert recs(doc, "CRS")["a"]["verdict"] == "pass"
    assert any(e["file"] == "images/a.tif" for e in sat_recs["a"]["evidence"])


def test_edge_target_measured_through_a_rule(make_delivery, tmp_path):
    edge = slanted_edge(
        (100, 100),
        angle_deg=8.0,
        sigma_px=0.7,
        dark=40,
        bright=200,
        snr=200,
        bit_depth=8,
        rng=np.random.default_rng(5),
    )
    flat = np.full((100, 100), 120, dtype=np.uint8)
    root = delivery_with_images(
        make_delivery,
        {"images/e.tif": edge, "images/f.tif": flat},
        extra_manifest="edge_targets: [{id: E1, image: e, roi: [0, 0, 100, 100]}, "
        "{id: E2, image: f, roi: [0, 0, 100, 100]}]\n",
    )
    p = profile(
        tmp_path,
        rule("SNR", "edge", "edge.snr", '{op: ">", value: 50}'),
        rule("RER", "edge", "edge.rer", '{op: ">=", value: 0.3}'),
    )
    doc = check(root, p, date="2026-01-01").document
    rer = recs(doc, "RER")
    assert rer["E1"]["verdict"] == "pass" and 0.3 < rer["E1"]["measured"]["value"] < 0.9
    assert rer["E2"]["verdict"] == "error"  # no edge: health checks fail, no estimator reported
    assert "health checks failed" in rer["E2"]["message"]
    assert recs(doc, "SNR")["E2"]["verdict"] in ("fail", "missing")


def test_seamline_coverage_from_a_vector_file(make_delivery, tmp_path):
    import shapely

    root = delivery_with_images(
        make_delivery,
        {"images/a.tif": np.full((3, 128, 128), 100, np.uint8)},
        extra_manifest="vectors: {seamlines: vectors/seams.gpkg}\n",
    )
    (root / "vectors").mkdir()
    left = shapely.box(500000, 5399968, 500016, 5400000)
    right = shapely.box(500016, 5399968, 500030, 5400000)  # leaves a 2 m gap
    _write_gpkg(root / "vectors" / "seams.gpkg", [left, right])
    p = profile(
        tmp_path,
        rule(
            "SEAM",
            "delivery",
            "mosaic.seamline_coverage",
            '{op: ">=", value: 100, unit: "%"}',
            "return_delivery",
        ),
    )
    doc = check(root, p, date="2026-01-01").document
    r = recs(doc, "SEAM")["D1"]
    assert r["verdict"] == "fail"
    assert r["measured"]["value"] == pytest.approx(100 * 30 / 32)


def _write_gpkg(path, geoms):
    import pyogrio
    import shapely

    pyogrio.raw.write(
        str(path),
        geometry=shapely.to_wkb(np.array(geoms, dtype=object)),
        field_data=[np.arange(len(geoms))],
        fields=["id"],
        crs="EPSG:25832",
        geometry_type="Polygon",
        driver="GPKG",
    )


def test_records_providers(make_delivery, tmp_path):
    images = (
        "image_id,file,block,flight_id,roll,flying_height,cloud_cover\n"
        "I1,a.tif,B1,F1,0.5,3846,2\nI2,b.tif,B1,F1,-1.5,3846,4\nI3,c.tif,B1,F2,0.2,,9\n"
    )
    manifest_extra = (
        "dates: {acquired_from: 2026-04-01}\n"
        "tables: {images: tables/images.csv, flights: tables/flights.csv, cameras: tables/cameras.csv}\n"
    )
    from tests.conftest import MANIFEST

    m = MANIFEST.replace(
        "tables: {images: tables/images.csv, manual_checks: tables/manual.csv}\n", manifest_extra
    )
    root = make_delivery(
        manifest=m,
        images=images,
        extra={
            "tables/flights.csv": "flight_id,camera_id\nF1,C1\nF2,C1\n",
            "tables/cameras.csv": "camera_id,focal_length,pixel_size,calibration_date\nC1,80,5.2,2024-04-01\n",
        },
    )
    p = profile(
        tmp_path,
        rule("ROLL", "flight", "flight.roll_mean_abs", '{op: "<=", value: 1, unit: deg}'),
        rule("AGE", "camera", "camera.calibration_age", '{op: "<=", value: 2, unit: year}'),
        rule("GSD", "image", "geometry.gsd_from_flying_height", '{op: "<=", value: 0.25, unit: m}'),
        rule(
            "CLOUD",
            "delivery",
            "images.cloud_cover.mean",
            '{op: "<=", value: 5, unit: "%"}',
            "return_delivery",
        ),
    )
    doc = check(root, p, date="2026-01-01").document
    roll = recs(doc, "ROLL")
    assert roll["F1"]["measured"]["value"] == pytest.approx(1.0) and roll["F1"]["verdict"] == "pass"
    assert recs(doc, "AGE")["C1"]["measured"]["value"] == pytest.approx(730 / 365.25)
    gsd = recs(doc, "GSD")
    assert gsd["I1"]["measured"]["value"] == pytest.approx(3846 * 5.2e-6 / 0.080)
    assert gsd["I3"]["verdict"] == "missing"
    assert recs(doc, "CLOUD")["D1"]["measured"]["value"] == pytest.approx(5.0)


def test_weak_band_correlation_is_not_reported_as_misregistration(make_delivery, tmp_path):
    rng = np.random.default_rng(11)
    base = rng.integers(40, 220, (128, 128)).astype(np.uint8)
    noise = rng.integers(40, 220, (128, 128)).astype(
        np.uint8
    )  # a band sharing no texture (NIR-like)
    img = np.stack([base, base, base, noise])
    root = delivery_with_images(make_delivery, {"images/a.tif": img})
    p = profile(
        tmp_path, rule("MIS", "image", "raster.misregistration", '{op: "<=", value: 1, unit: px}')
    )
    doc = check(root, p, date="2026-01-01").document
    r = recs(doc, "MIS")["a"]
    assert r["verdict"] == "pass" and r["measured"]["value"] == pytest.approx(0.0, abs=0.05)


def test_manual_rule_applies_per_item(make_delivery, tmp_path):
    images = "image_id,file,block,roll\nI1,a.tif,B1,0.5\nI2,b.tif,B1,2.5\n"
    root = make_delivery(
        images=images, manual="check,item,inspector,date,verdict\nM,I2,Ann,2026-01-02,pass\n"
    )
    p = profile(
        tmp_path,
        rule(
            "M",
            "image",
            "manual.M",
            '{op: "==", value: pass}',
            extra="  manual: true\n  when: 'images.roll > 1'\n",
        ),
    )
    # the delivery's own table is the contractor's statement: without the checker's verdict, missing
    assert recs(check(root, p, date="2026-01-01").document, "M")["I2"]["verdict"] == "missing"
    checker = tmp_path / "checker.yaml"
    checker.write_text(
        "orthospec_checker: 1\nchecker: {name: Ann Checker, role: external QC}\ndelivery: {id: D1}\n"
        "manual_checks:\n"
        "  - {check: M, item: I2, date: 2026-01-02, verdict: pass, note: looked}\n",
        encoding="utf-8",
    )
    doc = check(root, p, date="2026-01-01", checker=checker).document
    m = recs(doc, "M")
    assert m["I1"]["verdict"] == "not_applicable"  # condition false for I1: no signature asked for
    assert m["I2"]["verdict"] == "pass" and "Ann" in m["I2"]["message"]


def test_bias_t_statistic_equals_the_formula_on_the_example(tmp_path):
    """checkpoints.bias_t_x = |mean dx| / (s(dx) / sqrt(n)), s with n - 1 (seed 000 sigma)."""
    p = profile(
        tmp_path,
        rule(
            "BT",
            "block",
            "checkpoints.bias_t_x",
            '{op: "<=", value: 1000, unit: "1"}',
            "reject_block",
        ),
    )
    doc = check(EXAMPLES / "aerial-pass", p, date="2026-01-01").document
    cp = pd.read_csv(EXAMPLES / "aerial-pass" / "tables" / "checkpoints.csv")
    for block, g in cp.groupby("block"):
        keep = g[~g.get("excluded", pd.Series(False, index=g.index)).fillna(False).astype(bool)]
        dx = (keep["x"] - keep["x_ref"]).to_numpy()
        expected = abs(dx.mean()) / (dx.std(ddof=1) / np.sqrt(dx.size))
        assert recs(doc, "BT")[block]["measured"]["value"] == pytest.approx(expected, rel=1e-9)


def _copy(tmp_path, name="aerial-pass"):
    import shutil

    dst = tmp_path / name
    shutil.copytree(EXAMPLES / name, dst)
    return dst


def test_space_resection_is_derived_from_the_blocks(tmp_path):
    """JRC §12.8 footnote 6 keys on space resection; a block's method decides it, not a product flag."""
    import yaml

    d = _copy(tmp_path)
    m = yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))
    m["product"].pop("orthorectification", None)
    m["blocks"][1]["method"] = "space_resection"
    (d / "delivery.yaml").write_text(yaml.safe_dump(m, sort_keys=False), encoding="utf-8")
    p = profile(
        tmp_path,
        rule(
            "SR",
            "delivery",
            "derived.orthorectification",
            '{op: "==", value: aerotriangulation}',
            "return_delivery",
        ),
    )
    doc = check(d, p, date="2026-01-01").document
    rec = recs(doc, "SR")[doc["delivery"]["id"]]
    assert rec["measured"]["value"] == "space_resection" and rec["verdict"] == "fail"
    assert "B02" in rec["message"]


def test_resolution_class_is_computed_from_the_pixel_size(tmp_path):
    """JRC §9.1 classes from the profile's `classes:`; a gap of the text gives no class (missing)."""
    d = _copy(tmp_path)
    img = pd.read_csv(d / "tables" / "images.csv", dtype=str, keep_default_na=False)
    # issue 25: the class is read from the delivered file's pixel (a declared GSD is only evidence)
    for k, pixel in ((0, 5.0), (1, 9.0)):  # HR: 3 <= 5 <= 8; 9 m lies in the 8-10 m gap of §9.1
        path = d / img.loc[k, "file"]
        with rasterio.open(path) as src:
            profile, data = src.profile, src.read()
        t = profile["transform"]
        profile["transform"] = from_origin(t.c, t.f, pixel, pixel)
        path.unlink()
        with rasterio.open(path, "w", **profile) as dst:
            dst.write(data)
    text = PROFILE_HEAD.replace(
        "rules:\n",
        textwrap.dedent("""\
        classes:
          resolution:
            unit: m
            items:
              - {id: VHR, max: 3, max_inclusive: false}
              - {id: HR, min: 3, max: 8}
              - {id: MR, min: 10, max: 20}
        rules:
        """),
    ) + textwrap.indent(
        textwrap.dedent(rule("RC", "image", "derived.resolution_class", "{op: in, values: [VHR]}")),
        "  ",
    )
    p = tmp_path / "classes.yaml"
    p.write_text(text)
    doc = check(d, p, date="2026-01-01").document
    got = recs(doc, "RC")
    ids = img["image_id"].tolist()
    assert got[ids[0]]["measured"]["value"] == "HR" and got[ids[0]]["verdict"] == "fail"
    assert got[ids[1]]["verdict"] == "missing" and "no class" in got[ids[1]]["message"]
    assert got[ids[2]]["measured"]["value"] == "VHR" and got[ids[2]]["verdict"] == "pass"


def test_per_point_decisions_values_and_rows_on_a_copied_example(tmp_path):
    """Per-point measures (built as arrays) equal pandas' deltas, name the CSV data row and give the
    §12.6 decision: a justified exclusion of a blunder, an exclusion of a point within tolerance."""
    import hashlib
    import shutil

    root = tmp_path / "d"
    shutil.copytree(EXAMPLES / "aerial-pass", root)
    folder = tmp_path / "checker"  # the checker's measurements are what the check point rules read
    shutil.copytree(CHECKERS / "aerial-pass", folder)
    csv = folder / "tables" / "checkpoints.csv"
    cp = pd.read_csv(csv, dtype={"exclusion_reason": object})
    cp.loc[cp["point_id"] == "B01-C05", "x"] += 5.0  # a 5 m blunder: 3 x RMSE_x of B01 is about 3 m
    cp.loc[cp["point_id"] == "B01-C05", ["excluded", "exclusion_reason"]] = [
        True,
        "target mis-identified",
    ]
    cp.loc[cp["point_id"] == "B01-C06", "excluded"] = True
    cp["excluded"] = cp["excluded"].map(lambda v: "true" if v is True or v == "True" else "false")
    cp.to_csv(csv, index=False)
    p = profile(
        tmp_path,
        rule("DX", "checkpoint", "checkpoint.dx", '{op: "<=", value: 100, unit: m}'),
        rule("OK", "checkpoint", "checkpoint.blunder_ok", '{op: "true"}'),
        rule("DEC", "checkpoint", "checkpoint.decision", '{op: "present"}'),
        rule(
            "RX",
            "block",
            "checkpoints.rmse_x",
            '{op: "<=", value: tolerance_xy, unit: m}',
            "reject_block",
        ),
    )
    doc = check(root, p, date="2026-01-01", checker=folder).document
    sha = hashlib.sha256(csv.read_bytes()).hexdigest()
    dx, ok, dec = recs(doc, "DX"), recs(doc, "OK"), recs(doc, "DEC")
    assert set(dx) == set(cp["point_id"]) == set(ok) == set(dec)
    for row, pt in enumerate(cp.itertuples(index=False), start=1):
        rec = dx[pt.point_id]
        assert rec["measured"]["value"] == pytest.approx(pt.x - pt.x_ref, rel=1e-9, abs=1e-12)
        assert rec["evidence"] == [
            {"file": "checker:tables/checkpoints.csv", "sha256": sha, "rows": [row]}
        ]
        assert ok[pt.point_id]["evidence"] == rec["evidence"]
    assert dec["B01-C05"]["measured"]["value"] == "excluded"
    assert ok["B01-C05"]["verdict"] == "pass"
    assert ok["B01-C05"]["message"] == (
        "exceeds the maximum tolerable discrepancy in x; excluded: target mis-identified"
    )
    assert dec["B01-C06"]["measured"]["value"] == "error_within_tolerance"
    assert ok["B01-C06"]["verdict"] == "fail"
    assert (
        "within the maximum tolerable discrepancy; it stays in the sample"
        in ok["B01-C06"]["message"]
    )
    assert (
        dec["B02-C13"]["measured"]["value"] == "excluded"
    )  # the example's own justified exclusion
    kept = [k for k in dec if k not in ("B01-C05", "B01-C06", "B02-C13")]
    assert {dec[k]["measured"]["value"] for k in kept} == {"kept"}
    assert {ok[k]["message"] for k in kept} == {"within the maximum tolerable discrepancy"}
    # the figure's per-point detail keeps its keys and the excluded blunder is drawn as failing
    pts = {q["point_id"]: q for q in point_rows(doc["details"]["checkpoints"]["B01"]["points"])}
    assert set(pts["B01-C05"]) == {
        "point_id",
        "dx",
        "dy",
        "dz",
        "dr",
        "x_ref",
        "y_ref",
        "status",
        "decision",
        "row",
    }
    b5 = cp[cp["point_id"] == "B01-C05"].iloc[0]
    assert pts["B01-C05"]["status"] == "fail" and pts["B01-C05"]["x_ref"] == pytest.approx(
        b5["x_ref"]
    )
    assert pts["B01-C05"]["dr"] == pytest.approx(
        np.hypot(b5["x"] - b5["x_ref"], b5["y"] - b5["y_ref"])
    )
    assert pts["B01-C06"]["status"] == "pass"
