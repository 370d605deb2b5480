"""Computed facts: the photo lay-down of JRC §5.2.2 (pure geometry, hand-checked areas)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from tests.conftest import EXAMPLES

from orthospec.api import check
from orthospec.errors import MeasureError
from orthospec.measures.mosaic import photo_footprints, strip_headings


def test_two_photos_of_one_strip_cover_their_hand_computed_union():
    # centres 800 m apart northwards; each photo 1200 m across track x 1000 m along track
    h = strip_headings([0.0, 0.0], [0.0, 800.0], ["F1", "F1"])
    assert np.allclose(np.abs(np.sin(h)), 1.0)  # flight direction is north-south
    feet = photo_footprints([0.0, 0.0], [0.0, 800.0], [1200.0] * 2, [1000.0] * 2, h)
    union = shapely.union_all(feet)
    assert union.area == pytest.approx(1200.0 * (1000.0 + 800.0))  # x in [-600, 600], y in [-500, 1300]
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
        d / "tables" / "cameras.csv", index=False)
    p = tmp_path / "p.yaml"
    p.write_text(COVERAGE_PROFILE)
    doc = check(d, p, date="2026-01-01").document
    rec = next(r for r in doc["records"] if r["rule"] == "COV")
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
    rec = next(r for r in doc["records"] if r["rule"] == "COV")
    assert rec["verdict"] == "pass" and rec["measured"]["value"] == pytest.approx(100.0)
    img = pd.read_csv(d / "tables" / "images.csv", dtype=str, keep_default_na=False)
    img = img[~img["image_id"].str.startswith("F01_01")]  # drop one strip of block B01
    img.to_csv(d / "tables" / "images.csv", index=False)
    doc2 = check(d, p, date="2026-01-01").document
    rec2 = next(r for r in doc2["records"] if r["rule"] == "COV")
    assert rec2["verdict"] == "fail" and rec2["measured"]["value"] < 100.0
