"""Computed facts: the photo lay-down of JRC §5.2.2 (pure geometry, hand-checked areas)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from tests.checking import records
from tests.conftest import EXAMPLES

from orthospec.api import check
from orthospec.errors import MeasureError
from orthospec.measures.mosaic import photo_footprints, strip_headings

CHECKERS = EXAMPLES.parent / "checker"


def test_two_photos_of_one_strip_cover_their_hand_computed_union():
    # centres 800 m apart northwards; each photo 1200 m across track x 1000 m along track
    h = strip_headings([0.0, 0.0], [0.0, 800.0], ["F1", "F1"])
    assert np.allclose(np.abs(np.sin(h)), 1.0)  # flight direction is north-south
    feet = photo_footprints([0.0, 0.0], [0.0, 800.0], [1200.0] * 2, [1000.0] * 2, h)
    union = shapely.union_all(feet)
    assert union.area == pytest.approx(
        1200.0 * (1000.0 + 800.0)
    )  # x in [-600, 600], y in [-500, 1300]
    assert union.bounds == pytest.approx((-600.0, -500.0, 600.0, 1300.0))


def test_the_strip_direction_comes_from_the_nearest_photo_of_the_same_flight():
    # two east-west strips 1500 m apart; along-track spacing 700 m
    x = [0.0, 700.0, 1400.0, 0.0, 700.0, 1400.0]
    y = [0.0, 0.0, 0.0, 1500.0, 1500.0, 1500.0]
    h = strip_headings(x, y, ["F1"] * 6)
    assert np.allclose(np.abs(np.cos(h)), 1.0)
    alone = strip_headings([5.0], [5.0], ["F9"])
    assert alone[0] == 0.0
    rot = photo_footprints([0.0], [0.0], [100.0], [50.0], [math.pi / 4])[0]
    assert rot.area == pytest.approx(5000.0)


def test_bad_lay_down_input_is_refused():
    with pytest.raises(MeasureError):
        photo_footprints([0.0], [np.nan], [100.0], [100.0], [0.0])
    with pytest.raises(MeasureError):
        photo_footprints([0.0], [0.0], [-1.0], [100.0], [0.0])


def test_photo_coverage_without_a_camera_format_is_missing_with_the_reason(tmp_path):
    import shutil

    import pandas as pd

    d = tmp_path / "d"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    cams = pd.read_csv(d / "tables" / "cameras.csv", dtype=str, keep_default_na=False)
    cams.drop(columns=["format_across_px", "format_along_px"], errors="ignore").to_csv(
        d / "tables" / "cameras.csv", index=False
    )
    p = tmp_path / "p.yaml"
    p.write_text(COVERAGE_PROFILE)
    doc = check(d, p, date="2026-01-01").document
    rec = next(r for r in records(doc) if r["rule"] == "COV")
    assert rec["verdict"] == "missing" and "format_across_px" in rec["message"]
    assert doc["verdict"] == "rejected"


COVERAGE_PROFILE = """\
orthospec_profile: 1
id: t
version: 1.0.0
title: coverage
source: {title: JRC EUR 23638 EN}
parameters:
  tolerance_xy: {unit: m, default: 0.5}
rules:
  - id: COV
    title: coverage
    clause: {document: JRC EUR 23638 EN, section: "5.2.2"}
    quote: "Side overlap must ensure that all the surveyed area will be covered with imagery"
    scope: delivery
    measure: derived.photo_coverage
    requirement: {op: ">=", value: 100, unit: "%"}
    consequence: return_delivery
"""


def test_photo_coverage_of_the_example_lay_down(tmp_path):
    """With the camera format (UltraCam Eagle: 20010 x 13080 px, 5.2 µm, f = 80 mm) the photo
    lay-down of aerial-pass covers its blocks; removing one strip leaves a gap."""
    import shutil

    import pandas as pd

    d = tmp_path / "d"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    cams = pd.read_csv(d / "tables" / "cameras.csv", dtype=str, keep_default_na=False)
    cams["format_across_px"], cams["format_along_px"] = "20010", "13080"
    cams.to_csv(d / "tables" / "cameras.csv", index=False)
    p = tmp_path / "p.yaml"
    p.write_text(COVERAGE_PROFILE)
    doc = check(d, p, date="2026-01-01").document
    rec = next(r for r in records(doc) if r["rule"] == "COV")
    assert rec["verdict"] == "pass" and rec["measured"]["value"] == pytest.approx(100.0)
    img = pd.read_csv(d / "tables" / "images.csv", dtype=str, keep_default_na=False)
    img = img[~img["image_id"].str.startswith("F01_01")]  # drop one strip of block B01
    img.to_csv(d / "tables" / "images.csv", index=False)
    doc2 = check(d, p, date="2026-01-01").document
    rec2 = next(r for r in records(doc2) if r["rule"] == "COV")
    assert rec2["verdict"] == "fail" and rec2["measured"]["value"] < 100.0


# ---------------------------------------------------------------- derived.pansharpened (JRC §10.5)
PANSHARPENED_PROFILE = """\
orthospec_profile: 1
id: t
version: 1.0.0
title: pan-sharpening
source: {title: JRC EUR 23638 EN}
parameters:
  tolerance_xy: {unit: m, default: 0.5}
rules:
  - id: PS
    title: pan-sharpened
    clause: {document: JRC EUR 23638 EN, section: "10.5"}
    quote: "Pan-sharpening of satellite data"
    scope: delivery
    measure: derived.pansharpened
    requirement: {op: "true"}
    consequence: warn
  - id: AG
    title: declared as computed
    clause: {document: JRC EUR 23638 EN, section: "10.5"}
    quote: "Pan-sharpening of satellite data"
    scope: delivery
    measure: derived.pansharpened_agrees
    requirement: {op: "true"}
    consequence: warn
"""
SAT_ID = "D-2026-031"


def _sat_copy(tmp_path, *, scenes=None, images=None, product=None):
    """A copy of satellite-pass with columns of scenes/images set (None drops the column) and
    product keys of delivery.yaml set (None deletes the key)."""
    import shutil

    import pandas as pd
    import yaml

    d = tmp_path / "d"
    shutil.copytree(EXAMPLES / "satellite-pass", d)
    for name, cols in (("scenes", scenes), ("images", images)):
        f = d / "tables" / f"{name}.csv"
        df = pd.read_csv(f, dtype=str, keep_default_na=False)
        for col, v in (cols or {}).items():
            if v is None:
                df = df.drop(columns=[col])
            else:
                df[col] = v
        df.to_csv(f, index=False)
    if product:
        man = yaml.safe_load((d / "delivery.yaml").read_text())
        for k, v in product.items():
            if v is None:
                man["product"].pop(k, None)
            else:
                man["product"][k] = v
        (d / "delivery.yaml").write_text(yaml.safe_dump(man, sort_keys=False))
    return d


def _ps(tmp_path, d):
    p = tmp_path / "p.yaml"
    p.write_text(PANSHARPENED_PROFILE)
    doc = check(d, p, date="2026-08-01").document
    return {r["rule"]: r for r in records(doc) if r["item"] == SAT_ID}


def test_pansharpened_from_bands_and_pixel_sizes_of_satellite_pass(tmp_path):
    # WorldView-3: 4 bands (R;G;B;NIR) at 0.5 m; MS native 1.24 m; 0.5 <= 1.24 / 1.5 = 0.827 -> true
    rec = _ps(tmp_path, _sat_copy(tmp_path))
    assert rec["PS"]["verdict"] == "pass" and rec["PS"]["measured"]["value"] is True
    assert rec["AG"]["verdict"] == "pass"  # declared true


def test_pansharpened_false_for_a_single_band_or_a_product_not_finer_than_the_ms_pixel(tmp_path):
    # one band (PAN only) at 0.5 m: not multispectral -> false. The files decide: each image is
    # rewritten with its first band only (same grid), as a PAN-only product would be delivered.
    import rasterio

    d = _sat_copy(tmp_path / "a", images={"bands": "PAN"}, product={"bands": ["PAN"]})
    for f in sorted((d / "images").glob("*.tif")):
        with rasterio.open(f) as src:
            band, profile = src.read(1), {**src.profile, "count": 1}
        profile.pop("photometric", None)
        with rasterio.open(f, "w", **profile) as dst:
            dst.write(band, 1)
    rec = _ps(tmp_path / "a", d)
    assert rec["PS"]["verdict"] == "fail" and rec["PS"]["measured"]["value"] is False
    assert any(
        e["file"] == "images/S01_SC1.tif" for e in rec["PS"]["evidence"]
    )  # the file was read
    assert rec["AG"]["verdict"] == "fail"  # the manifest still declares pansharpened: true
    # 4 bands at 1.24 m, the MS pixel itself: 1.24 >= 1.24 -> false
    rec = _ps(tmp_path / "b", _sat_copy(tmp_path / "b", images={"gsd": "1.24"}))
    assert rec["PS"]["verdict"] == "fail" and rec["PS"]["measured"]["value"] is False


def test_declaring_a_single_band_does_not_hide_the_four_bands_of_the_files(tmp_path):
    # images.bands and product.bands say PAN only; the delivered GeoTIFFs carry 4 colour bands
    rec = _ps(tmp_path, _sat_copy(tmp_path, images={"bands": "PAN"}, product={"bands": ["PAN"]}))
    assert rec["PS"]["verdict"] == "pass" and rec["PS"]["measured"]["value"] is True


def test_pansharpened_is_missing_without_the_ms_pixel_size(tmp_path):
    rec = _ps(tmp_path, _sat_copy(tmp_path, scenes={"ms_pixel_size": None}))
    assert rec["PS"]["verdict"] == "missing" and "ms_pixel_size" in rec["PS"]["message"]


def test_between_the_ms_pixel_and_the_margin_the_declaration_decides(tmp_path):
    # 1.0 m: finer than 1.24 m but coarser than 1.24 / 1.5 = 0.827 m (plain resampling possible)
    rec = _ps(tmp_path / "a", _sat_copy(tmp_path / "a", images={"gsd": "1.0"}))
    assert rec["PS"]["measured"]["value"] is True and "declared" in rec["PS"]["message"]
    rec = _ps(
        tmp_path / "b",
        _sat_copy(tmp_path / "b", images={"gsd": "1.0"}, product={"pansharpened": None}),
    )
    assert rec["PS"]["verdict"] == "missing"
    assert rec["AG"]["verdict"] == "not_applicable"


def test_a_declared_false_does_not_switch_off_the_pan_sharpening_rules(tmp_path):
    """MS bands at 0.5 m from 1.24 m scenes declared `pansharpened: false`: jrc-v3 §10.5 still applies,
    and without the inspector's record of JRC-10.5.1-SAME-MODEL-GCPS the delivery is not accepted."""
    import shutil

    import pandas as pd
    import yaml

    d = _sat_copy(tmp_path, product={"pansharpened": False})
    rec = _ps(tmp_path, d)
    assert rec["PS"]["measured"]["value"] is True and rec["AG"]["verdict"] == "fail"
    assert "contradict" in rec["PS"]["message"]
    f = d / "tables" / "manual_checks.csv"
    mc = pd.read_csv(f, dtype=str, keep_default_na=False)
    mc[mc["check"] != "JRC-10.5.1-SAME-MODEL-GCPS"].to_csv(f, index=False)
    # the external QC's folder (docs/CHECKER.md, its measurements with it) without its §10.5.1 verdict
    folder = tmp_path / "checker"
    shutil.copytree(CHECKERS / "satellite-pass", folder)
    checker = yaml.safe_load((folder / "checker.yaml").read_text(encoding="utf-8"))
    checker["manual_checks"] = [
        e for e in checker["manual_checks"] if e["check"] != "JRC-10.5.1-SAME-MODEL-GCPS"
    ]
    (folder / "checker.yaml").write_text(yaml.safe_dump(checker, sort_keys=False), encoding="utf-8")
    doc = check(d, "jrc-v3", date="2026-08-01", checker=folder).document
    recs = {r["rule"]: r for r in records(doc) if r["rule"].startswith("JRC-10.")}
    assert recs["JRC-10.5.1-SAME-MODEL-GCPS"]["verdict"] == "missing"
    assert (
        recs["JRC-10.5.2-EXCLUDE-ZERO"]["verdict"] == "pass"
    )  # applies: the inspector's record is there
    # never accepted: the unsigned §10.5.1 check is the checker's open work (issue 26: incomplete)
    assert doc["verdict"] == "incomplete"
    assert [t.split(":", 1)[0] for t in doc["rollup"]["incomplete"]] == [
        "JRC-10.5.1-SAME-MODEL-GCPS"
    ]


def test_pan_sharpening_rules_do_not_apply_to_an_aerial_delivery():
    doc = check(
        EXAMPLES / "aerial-pass", "jrc-v3", date="2026-08-01", checker=CHECKERS / "aerial-pass"
    ).document
    recs = [r for r in records(doc) if r["rule"].startswith(("JRC-10.5", "JRC-10.3"))]
    assert len(recs) == 4 and all(r["verdict"] == "not_applicable" for r in recs)


# ---------------------------------------------------------------- red team R7: inflated flying heights
def _aerial_copy_without_strip_f02_02(tmp_path, height_factor, columns=("flying_height",)):
    """aerial-pass without strip F02_02 (rows and image files), F02_01 ``columns`` (flying heights)
    x height_factor (the reproducer of tests/REDTEAM.md R7, R18)."""
    import shutil

    import pandas as pd

    d = tmp_path / "d"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    f = d / "tables" / "images.csv"
    img = pd.read_csv(f, dtype=str, keep_default_na=False)
    for rel in img.loc[img["image_id"].str.startswith("F02_02"), "file"]:
        (d / rel).unlink()
    img = img[~img["image_id"].str.startswith("F02_02")].copy()
    strip = img["image_id"].str.startswith("F02_01")
    for col in columns:
        img.loc[strip, col] = [f"{float(h) * height_factor:.4f}" for h in img.loc[strip, col]]
    img.to_csv(f, index=False)
    return d


def _cov(tmp_path, d):
    p = tmp_path / "p.yaml"
    p.write_text(COVERAGE_PROFILE)
    doc = check(d, p, date="2026-01-01").document
    return doc, next(r for r in records(doc) if r["rule"] == "COV")


def test_inflated_flying_heights_cannot_hide_a_missing_strip(tmp_path):
    """Red team R7: F02_01 heights x2.5 give H/f x pixel = 3688 m x 2.5 x 5.2 µm / 80 mm = 0.60 m
    against the rows' own acquisition_gsd 0.24 m (JRC §3.1 GSD = H/f x CCD): those footprints are
    not evidence, and without them the strip gap stays open, so coverage is missing, never 100 %."""
    d = _aerial_copy_without_strip_f02_02(tmp_path, 2.5)
    doc, rec = _cov(tmp_path, d)
    assert rec["verdict"] == "missing", rec
    assert "F02_0101" in rec["message"] and "acquisition_gsd" in rec["message"]
    assert doc["verdict"] == "rejected"


def test_inflating_the_declared_gsds_too_does_not_help_the_rasters_keep_their_pixel(tmp_path):
    """Red team R18: heights, acquisition_gsd and gsd of F02_01 all x2.5 (0.60 m) agree with each
    other, but the delivered rasters still have 0.25 m pixels (read from the GeoTIFFs): the
    footprints are still not evidence and coverage stays missing."""
    import rasterio

    d = _aerial_copy_without_strip_f02_02(
        tmp_path, 2.5, ("flying_height", "acquisition_gsd", "gsd")
    )
    with rasterio.open(d / "images" / "F02_0101.tif") as ds:
        assert ds.res[0] == pytest.approx(0.25)
    doc, rec = _cov(tmp_path, d)
    assert rec["verdict"] == "missing", rec
    assert "F02_0101" in rec["message"] and doc["verdict"] == "rejected"


def test_heights_within_the_gsd_tolerance_still_count(tmp_path):
    """Control: heights x1.1 (GSD 0.264 m, 10 % over the 0.24 m acquisition GSD, within 20 %) are
    counted, and the strip gap is then a plain coverage failure measured below 100 %."""
    d = _aerial_copy_without_strip_f02_02(tmp_path, 1.1)
    _, rec = _cov(tmp_path, d)
    assert rec["verdict"] == "fail" and rec["measured"]["value"] < 100.0
    assert "acquisition_gsd" not in rec["message"]


def test_inflated_heights_not_needed_for_full_coverage_are_named_but_do_not_block(tmp_path):
    """With every strip delivered, one photo's inflated height (x2.5) is left out and the rest still
    cover 100 %: pass, with the photo named in the note."""
    import shutil

    import pandas as pd

    d = tmp_path / "d"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    f = d / "tables" / "images.csv"
    img = pd.read_csv(f, dtype=str, keep_default_na=False)
    row = img["image_id"] == "F01_0103"
    img.loc[row, "flying_height"] = f"{float(img.loc[row, 'flying_height'].iloc[0]) * 2.5:.1f}"
    img.to_csv(f, index=False)
    _, rec = _cov(tmp_path, d)
    assert rec["verdict"] == "pass" and rec["measured"]["value"] == pytest.approx(100.0)


# ---------------------------------------------------------------- red team R8: derived.master_images
MASTER_PROFILE = """\
orthospec_profile: 1
id: t
version: 1.0.0
title: master
source: {title: JRC EUR 23638 EN}
parameters:
  tolerance_xy: {unit: m, default: 1.0}
rules:
  - id: MASTER
    title: master declared
    clause: {document: JRC EUR 23638 EN, section: "9.4", table: "9"}
    quote: "Record result in metadata and identify as master image."
    scope: delivery
    measure: derived.master_images
    requirement: {op: ">=", value: 1, unit: "1"}
    consequence: return_delivery
"""


@pytest.mark.parametrize(
    ("scenes", "expected", "verdict"),
    [
        (None, 1.0, "pass"),
        # R8: the master un-declared, but S01_SC1 still records its master check date (Table 9 dated record)
        ({"is_master": "false"}, 0.0, "fail"),
        # no trace of a master-image workflow: absolute correction (JRC §9.4 "only in rare cases")
        ({"is_master": "false", "master_check_date": ""}, None, "not_applicable"),
        ({"is_master": "true"}, 6.0, "pass"),
    ],
)
def test_master_images_counts_the_scenes_flagged_master(tmp_path, scenes, expected, verdict):
    """satellite-pass flags one master (S01_SC1, with its master_check_date)."""
    d = _sat_copy(tmp_path, scenes=scenes)
    p = tmp_path / "p.yaml"
    p.write_text(MASTER_PROFILE)
    doc = check(d, p, date="2026-08-01").document
    rec = next(r for r in records(doc) if r["rule"] == "MASTER")
    assert rec["verdict"] == verdict, rec
    if expected is not None:
        assert rec["measured"]["value"] == expected
