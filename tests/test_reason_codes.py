"""Reason codes beside messages (issue 28 item 4): every record that is not a pass carries a
``reason`` from :class:`orthospec.verdicts.Reason`, each one produced here by a real case (a
delivery and profile on disk, the library's ``check``), and the writers carry it.

Expected values: the cause each case plants (an unset parameter, an empty cell, a missing GSD...)
is known from the input itself, not from orthospec's output."""

from __future__ import annotations

import csv
import dataclasses
import io
import textwrap

import pytest
from tests.checking import check_with, records, write_checker
from tests.conftest import MANIFEST

from orthospec import qcr
from orthospec import verdicts as V
from orthospec.reports.findings import not_applicable_summary
from orthospec.verdicts import Reason

#: the mini profile's rules plus one rule per cause (tests/data/profiles/mini.yaml)
PROFILE = """\
orthospec_profile: 1
id: reasons
version: 1.0.0
title: Reason codes
source: {title: JRC, seed: 002_7421c4ca450e31c6.txt}
parameters:
  tolerance_xy: {unit: m, required: true, description: tol}
  max_roll: {unit: deg, default: 3}
  max_pitch: {unit: deg, description: nobody sets it}
rules:
  - {id: R-ROLL, title: roll, clause: {document: JRC EUR 23638 EN, section: "5.2.4"}, quote: "Roll and drift",
     scope: image, measure: images.roll, requirement: {op: "<=", value: max_roll, unit: deg},
     consequence: reject_item}
  - {id: R-UNSET, title: unset, clause: {document: JRC EUR 23638 EN, section: "5.2.4"}, quote: "Roll and drift",
     scope: image, measure: images.roll, requirement: {op: "<=", value: max_pitch, unit: deg},
     consequence: reject_item}
  - {id: R-PX, title: px, clause: {document: JRC EUR 23638 EN, section: "5.3"}, quote: "Flying height",
     scope: image, measure: images.flying_height, requirement: {op: "<=", value: 100000, unit: px},
     consequence: reject_item}
  - {id: R-THR, title: thr, clause: {document: JRC EUR 23638 EN, section: "6.3"}, quote: "The coefficient",
     scope: image, measure: images.std_dn,
     requirement: {op: "<=", value: "images.gsd * 100 / images.gsd", unit: DN}, consequence: reject_item}
  - {id: R-WHEN, title: when, clause: {document: JRC EUR 23638 EN, section: "6.3"}, quote: "The coefficient",
     scope: image, when: "images.flying_height > 500", measure: images.std_dn,
     requirement: {op: "<=", value: 1000, unit: DN}, consequence: reject_item}
  - {id: R-SAT, title: sat, clause: {document: JRC EUR 23638 EN, section: "6.3"}, quote: "The coefficient",
     scope: image, when: "manifest.sensor.type == 'satellite'", measure: images.std_dn,
     requirement: {op: "<=", value: 1000, unit: DN}, consequence: reject_item}
  - {id: R-READ, title: read, clause: {document: JRC EUR 23638 EN, section: "6.3"}, quote: "The coefficient",
     scope: image, measure: raster.format, requirement: {op: "==", value: GTiff}, consequence: reject_item}
  - {id: R-WIN, title: window, clause: {document: JRC EUR 23638 EN, section: "6.3"}, quote: "The coefficient",
     scope: delivery, measure: acquisition.outside_declared_window,
     requirement: {op: "==", value: 0, unit: "1"}, consequence: reject_item}
  - {id: R-VIS, title: visual, clause: {document: JRC EUR 23638 EN, section: "6.3"},
     quote: "These checks are usually visual and qualitative", scope: delivery, measure: manual.R-VIS,
     manual: true, requirement: {op: "==", value: pass}, consequence: return_delivery}
"""

#: I1 roll empty (no value), I2 flying height empty (no threshold, unknown `when` fact), I3 roll 4 > 3
#: and no GSD
IMAGES = """\
image_id,file,block,roll,flying_height,std_dn,gsd
I1,images/i1.tif,B1,,1000,30,0.25
I2,images/i2.tif,B1,2.5,,40,0.25
I3,images/i3.tif,B2,4,1100,20,
"""
#: the delivery without a product GSD (so a value in px cannot be converted)
NO_GSD = MANIFEST.replace("product: {gsd: {value: 0.25, unit: m}}\n", "")


@pytest.fixture
def profile(tmp_path):
    p = tmp_path / "reasons.yaml"
    p.write_text(PROFILE, encoding="utf-8")
    return p


def by_rule(doc):
    out: dict[str, dict[str, dict]] = {}
    for r in records(doc):
        out.setdefault(r["rule"], {})[r["item"]] = r
    return out


@pytest.fixture
def doc(make_delivery, profile):
    assert NO_GSD != MANIFEST
    return check_with(
        make_delivery(manifest=NO_GSD, images=IMAGES),
        profile,
        params=["tolerance_xy=0.5m", "max_pitch=10deg"],
    ).document


def test_each_cause_has_its_reason(doc):
    got = {
        rule: {item: (r["verdict"], r["reason"]) for item, r in items.items()}
        for rule, items in by_rule(doc).items()
    }
    assert got["R-ROLL"] == {
        "I1": ("missing", "no_value"),
        "I2": ("pass", None),
        "I3": ("fail", "not_met"),
    }
    assert got["R-PX"] == {
        "I1": ("pass", None),
        "I2": ("missing", "no_value"),
        "I3": ("missing", "no_gsd"),
    }
    assert got["R-THR"] == {
        "I1": ("pass", None),
        "I2": ("pass", None),
        "I3": ("missing", "no_threshold"),
    }
    assert got["R-WHEN"]["I2"] == ("missing", "unknown_fact")
    assert got["R-WHEN"]["I1"] == ("pass", None)
    assert got["R-SAT"] == {i: ("not_applicable", "condition_false") for i in ("I1", "I2", "I3")}
    assert got["R-READ"] == {
        i: ("error", "provider_error") for i in ("I1", "I2", "I3")
    }  # no image on disk
    assert got["R-WIN"] == {
        "D1": ("not_applicable", "provider_not_applicable")
    }  # no acquisition window
    assert got["R-VIS"] == {"D1": ("missing", "unsigned")}  # no checker's file


def test_every_non_pass_record_has_a_reason_its_verdict_allows(doc):
    for r in records(doc):
        if r["verdict"] == V.PASS:
            assert r["reason"] is None
        else:
            assert r["reason"] in V.ALLOWED_REASONS[r["verdict"]], r


def test_unset_parameter(make_delivery, profile):
    # `check` refuses (exit 2) a profile whose rule reads a parameter nobody set, unless the rule
    # may not apply; the engine itself, given the parameter unset, records `missing` for that cause
    from orthospec.delivery.reader import open_delivery
    from orthospec.engine.evaluator import Evaluator
    from orthospec.engine.params import parse_cli_params, resolve_parameters
    from orthospec.profile.loader import load_profile

    prof = load_profile(profile)
    d = open_delivery(make_delivery(images=IMAGES))
    values = resolve_parameters(
        prof,
        {},
        parse_cli_params(["tolerance_xy=0.5m", "max_pitch=10deg"]),
        manifest=d.flat_manifest(),
    )
    values["max_pitch"] = dataclasses.replace(values["max_pitch"], value=None, source="unset")
    ev = Evaluator(prof, d, values).run()
    unset = next(r for r in ev.results if r.rule.id == "R-UNSET")
    assert [unset.reason(i) for i in range(len(unset.items))] == [
        "no_value",
        "unset_parameter",
        "unset_parameter",
    ]
    assert "max_pitch is not set" in str(unset.notes[1])


def test_requirement_error(make_delivery, profile):
    # no GSD at all (neither product.gsd nor images.gsd): metres cannot become pixels for any item
    d = check_with(
        make_delivery(manifest=NO_GSD, images=IMAGES.replace(",0.25", ",")),
        profile,
        params=["tolerance_xy=0.5m", "max_pitch=10deg"],
    ).document
    assert {(r["verdict"], r["reason"]) for r in records(d) if r["rule"] == "R-PX"} == {
        ("error", "requirement_error")
    }


def test_no_items_and_waived(make_delivery, profile, tmp_path):
    # a waiver in force (the checker's file) on I3's failing roll; an images table with no row
    d = check_with(
        make_delivery("w", images=IMAGES),
        profile,
        params=["max_pitch=10deg"],
        checker=write_checker(tmp_path),
    ).document
    assert by_rule(d)["R-ROLL"]["I3"]["verdict"] == "waived"
    assert by_rule(d)["R-ROLL"]["I3"]["reason"] == "waived"
    empty = check_with(
        make_delivery("e", images="image_id,file,block,roll,flying_height,std_dn\n"),
        profile,
        params=["tolerance_xy=0.5m", "max_pitch=10deg"],
    ).document
    assert {(r["verdict"], r["reason"]) for r in records(empty) if r["rule"] == "R-ROLL"} == {
        ("missing", "no_items")
    }


def test_outside_the_sample(make_delivery, profile):
    d = check_with(
        make_delivery(images=IMAGES),
        profile,
        params=["tolerance_xy=0.5m", "max_pitch=10deg"],
        options={"sample": ("image", ["I1", "I3"])},
    ).document
    roll = by_rule(d)["R-ROLL"]
    assert (roll["I2"]["verdict"], roll["I2"]["reason"]) == ("not_applicable", "outside_sample")
    assert roll["I3"]["reason"] == "not_met"
    # the compact block stores the column because the reason is not the verdict's default
    assert "reason" in d["compact"]["R-ROLL"]
    na = {g["condition"]: g for g in not_applicable_summary(records(d))}
    assert any("sample" in c for c in na)


def test_internal_error(make_delivery, profile, monkeypatch):
    from orthospec.engine import rules

    def crash(*a, **k):
        raise RuntimeError("planted")

    monkeypatch.setattr(rules, "_judge", crash)
    d = check_with(
        make_delivery(images=IMAGES), profile, params=["tolerance_xy=0.5m", "max_pitch=10deg"]
    ).document
    assert {r["reason"] for r in records(d) if r["rule"] == "R-ROLL"} == {"internal_error"}


def test_writers_carry_the_reason(doc):
    rows = list(csv.DictReader(io.StringIO(qcr.to_csv(doc))))
    assert [r["reason"] for r in rows] == [r["reason"] or "" for r in records(doc)]
    # the block writer and the record writer agree byte for byte
    assert qcr.to_csv(doc) == "".join(qcr._iter_csv_records(doc))
    junit = "".join(qcr.iter_junit(doc))
    assert '<property name="reason" value="no_gsd"/>' in junit
    assert '<property name="reason" value="provider_error"/>' in junit


def test_reason_enum_is_the_schema_vocabulary():
    schema = qcr.qcr_schema()
    text = str(schema)
    for r in Reason:
        assert r.value in text
    assert textwrap.dedent(V.reason_of(V.MISSING) or "") == "no_value"
