import json

import numpy as np
import pytest
from tests.checking import check_with, records, write_checker
from tests.conftest import MANIFEST

from orthospec.api import check
from orthospec.engine.params import ParameterError


def recs(doc, rule):
    return {r["item"]: r for r in records(doc) if r["rule"] == rule}


def test_verdicts_per_item(make_delivery, mini_profile, tmp_path):
    # the waiver of I3 and the R-VIS verdict come from the checker's file (the same waiver in the
    # delivery.yaml is only the contractor's request: tests/test_verdict_regressions.py)
    doc = check_with(make_delivery(), mini_profile, checker=write_checker(tmp_path)).document
    roll = recs(doc, "R-ROLL")
    assert {k: v["verdict"] for k, v in roll.items()} == {
        "I1": "pass",
        "I2": "pass",
        "I3": "waived",
    }
    assert roll["I3"]["waived_verdict"] == "fail"
    assert roll["I3"]["waiver"]["approver"] == "Chief"
    assert roll["I3"]["waiver"]["declared_in"] == "checker"
    assert roll["I3"]["waiver"]["granted_by"] == "Eva External (external QC, Paying Agency)"
    assert roll["I1"]["requirement"]["value"] == 3.0 and roll["I1"]["requirement"]["unit"] == "deg"
    assert roll["I1"]["evidence"][0]["rows"] == [1]
    fh = recs(doc, "R-FH")
    assert fh["I2"]["verdict"] == "fail"  # flying height absent on row 2
    cv = recs(doc, "R-CV")
    assert cv["I3"]["verdict"] == "warn"  # recommended level => warn, not fail
    assert cv["I1"]["requirement"]["min"] == pytest.approx(25.6)
    assert recs(doc, "R-VIS")["D1"]["verdict"] == "pass"


def test_rollup_counts_rejected_images(make_delivery, mini_profile, tmp_path):
    doc = check_with(make_delivery(), mini_profile, checker=write_checker(tmp_path)).document
    assert doc["rollup"]["rejected"] == {"image": ["I2"]}  # I3 is waived, not rejected
    share = recs(doc, "R-ROLLUP")["D1"]
    assert share["measured"]["value"] == pytest.approx(100 / 3)
    assert share["verdict"] == "fail"
    assert doc["verdict"] == "rejected"


def test_fixing_the_data_accepts(make_delivery, mini_profile, tmp_path):
    images = "image_id,file,block,roll,flying_height,std_dn\nI1,a.tif,B1,0.5,1000,30\nI2,b.tif,B1,1,900,40\n"
    doc = check_with(
        make_delivery(images=images), mini_profile, checker=write_checker(tmp_path)
    ).document
    assert doc["verdict"] == "accepted"
    assert doc["summary"]["fail"] == 0
    assert doc["waivers_unused"] and doc["waivers_unused"][0]["rule"] == "R-ROLL"
    assert doc["waivers_unused"][0]["declared_in"] == "checker"


def test_fail_on_warn_makes_recommended_blocking(make_delivery, mini_profile, tmp_path):
    images = "image_id,file,block,roll,flying_height,std_dn\nI1,a.tif,B1,0.5,1000,5\n"
    # tolerance_xy given by the checker, so the only warning is R-CV's (not the ITT-source one)
    chk = write_checker(tmp_path)
    soft = check_with(
        make_delivery("a", images=images), mini_profile, checker=chk, params=["tolerance_xy=0.5m"]
    ).document
    hard = check_with(
        make_delivery("b", images=images),
        mini_profile,
        fail_on="warn",
        checker=chk,
        params=["tolerance_xy=0.5m"],
    ).document
    assert soft["verdict"] == "accepted" and soft["summary"]["warn"] == 1
    assert hard["verdict"] == "rejected"


def test_manual_check_without_record_is_missing(make_delivery, mini_profile):
    doc = check(
        make_delivery(manual="check,item,inspector,date,verdict\n"),
        mini_profile,
        date="2026-01-01",
        params=["tolerance_xy=0.5m"],
    ).document
    vis = recs(doc, "R-VIS")["D1"]
    assert vis["verdict"] == "missing" and "no recorded verdict" in vis["message"]
    assert doc["verdict"] == "rejected"


def test_cli_param_overrides_and_unit_conversion(make_delivery, mini_profile):
    # 100 cm = 1 deg? no: max_roll is in degrees; 0.6 deg makes I2 (2.5 deg) fail
    doc = check(
        make_delivery(),
        mini_profile,
        date="2026-01-01",
        params=["max_roll=0.6deg", "tolerance_xy=0.5m"],
    ).document
    assert recs(doc, "R-ROLL")["I2"]["verdict"] == "fail"
    # the profile's own value is recorded beside the one in force (issue 26: page 1 prints both)
    assert doc["profile"]["parameters"]["max_roll"] == {
        "value": 0.6,
        "unit": "deg",
        "source": "cli",
        "profile_value": 3.0,
    }
    # the manifest's declared 0.5 m is evidence only: the value in force is the checker's --param
    assert doc["profile"]["parameters"]["tolerance_xy"]["source"] == "cli"


@pytest.mark.parametrize(
    "param, message",
    [
        ("max_roll=3m", "does not convert"),
        ("nope=1", "has no such parameter"),
        ("max_roll", "expected NAME=VALUE"),
        ("max_roll=abc", "not a number"),
    ],
)
def test_bad_params(make_delivery, mini_profile, param, message):
    with pytest.raises(ParameterError, match=message):
        check(make_delivery(), mini_profile, params=[param])


def test_required_parameter_unset(make_delivery, mini_profile):
    manifest = MANIFEST.replace(
        "tender: {reference: ITT-1, parameters: {tolerance_xy: {value: 0.5, unit: m}}}\n", ""
    )
    with pytest.raises(ParameterError, match="needs parameter"):
        check(make_delivery(manifest=manifest), mini_profile)


def test_a_crashing_rule_is_error_and_others_still_run(make_delivery, tmp_path, mini_profile):
    text = mini_profile.read_text().replace("measure: images.std_dn", "measure: images.bands")
    p = tmp_path / "p.yaml"
    p.write_text(text)
    doc = check(make_delivery(), p, date="2026-01-01", params=["tolerance_xy=0.5m"]).document
    cv = recs(doc, "R-CV")
    assert {r["verdict"] for r in cv.values()} == {"error"}
    assert "text" in next(iter(cv.values()))["message"]
    assert recs(doc, "R-ROLL")["I1"]["verdict"] == "pass"


def _overflowing_checkpoints(tmp_path):
    """A copy of aerial-pass whose first two check points lie at x = 1e308 and -1e308 (a corrupt
    table: finite numbers the CSV reader accepts, whose squares overflow in the checkpoints provider)."""
    import shutil

    from tests.conftest import EXAMPLES

    d = tmp_path / "aerial-pass"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    lines = (d / "tables" / "checkpoints.csv").read_text(encoding="utf-8").splitlines()
    col = lines[0].split(",").index("x")
    for i, v in ((1, "1e308"), (2, "-1e308")):
        cells = lines[i].split(",")
        cells[col] = v
        lines[i] = ",".join(cells)
    (d / "tables" / "checkpoints.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return d


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_a_crashing_rule_keeps_its_traceback_under_debug(tmp_path, monkeypatch):
    """Issue 15 item 6: a rule whose provider crashes on a real input is `error` (so the delivery is
    never accepted) and, with `orthospec --debug`, the record detail keeps the traceback."""
    import subprocess
    import sys

    d = _overflowing_checkpoints(tmp_path)
    monkeypatch.delenv("ORTHOSPEC_DEBUG", raising=False)
    plain = check(
        d,
        "jrc-v3",
        date="2026-11-21",
        options={"workers": 1},
        params=["tolerance_xy=0.5m", "map_crs=EPSG:25832"],
    ).document
    rec = recs(plain, "JRC-12.7-RMSEX")["B01"]
    assert rec["verdict"] == "error" and plain["verdict"] == "rejected"
    assert (
        rec["message"].startswith("internal error in rule: OverflowError")
        and "--debug" in rec["message"]
    )
    assert "tracebacks" not in plain["details"]
    out = tmp_path / "out"
    proc = subprocess.run(
        [
            sys.executable,
            "-W",
            "ignore",
            "-m",
            "orthospec.cli.main",
            "--debug",
            "check",
            str(d),
            "--profile",
            "jrc-v3",
            "--out",
            str(out),
            "--date",
            "2026-11-21",
            "--format",
            "json",
            "--workers",
            "1",
            "--param",
            "tolerance_xy=0.5m",
            "--param",
            "map_crs=EPSG:25832",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 1, proc.stderr
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    tb = doc["details"]["tracebacks"]["JRC-12.7-RMSEX"]
    assert tb.startswith("Traceback (most recent call last)") and "OverflowError" in tb
    assert "providers/checkpoints.py" in tb  # the provider's own frame, not just the evaluator's
    assert "internal error in rule: OverflowError" in recs(doc, "JRC-12.7-RMSEX")["B01"]["message"]


def test_deterministic_json(make_delivery, mini_profile):
    from orthospec.qcr import dumps

    root = make_delivery()
    a = dumps(check(root, mini_profile, date="2026-01-01", params=["tolerance_xy=0.5m"]).document)
    b = dumps(check(root, mini_profile, date="2026-01-01", params=["tolerance_xy=0.5m"]).document)
    assert a == b
    json.loads(a)


def test_records_are_schema_valid(make_delivery, mini_profile):
    import jsonschema

    from orthospec.qcr import qcr_schema

    doc = check(
        make_delivery(), mini_profile, date="2026-01-01", params=["tolerance_xy=0.5m"]
    ).document
    jsonschema.validate(doc, qcr_schema())


def test_vectorised_over_many_items(make_delivery, mini_profile):
    n = 5000
    rng = np.random.default_rng(1)
    rolls = rng.uniform(0, 4, n)
    rows = "\n".join(f"I{i},f{i}.tif,B1,{r:.3f},1000,30" for i, r in enumerate(rolls))
    doc = check(
        make_delivery(images="image_id,file,block,roll,flying_height,std_dn\n" + rows + "\n"),
        mini_profile,
        date="2026-01-01",
        params=["tolerance_xy=0.5m"],
    ).document
    roll = recs(doc, "R-ROLL")
    failing = {k for k, v in roll.items() if v["verdict"] in ("fail", "waived")}
    expected = {f"I{i}" for i, r in enumerate(np.round(rolls, 3)) if r > 3}
    assert failing == expected


def test_rejected_items_of_a_scope_without_rollup_return_the_delivery(make_delivery, tmp_path):
    images = "image_id,file,block,flight_id,roll\nI1,a.tif,B1,F1,2.5\nI2,b.tif,B1,F2,0.1\n"
    m = MANIFEST.replace(
        "tables: {images: tables/images.csv, manual_checks: tables/manual.csv}",
        "tables: {images: tables/images.csv, flights: tables/flights.csv}",
    )
    root = make_delivery(
        manifest=m,
        images=images,
        manual=None,
        extra={"tables/flights.csv": "flight_id,camera_id\nF1,C1\nF2,C1\n"},
    )
    p = tmp_path / "p.yaml"
    p.write_text("""\
orthospec_profile: 1
id: f
version: 1.0.0
title: flights
source: {title: JRC EUR 23638 EN}
rules:
  - id: ROLL-MEAN
    title: mean roll per flight
    clause: {document: JRC EUR 23638 EN, section: "5.2.4"}
    quote: Roll and drift
    scope: flight
    measure: flight.roll_mean_abs
    requirement: {op: "<=", value: 1, unit: deg}
    consequence: reject_item
""")
    doc = check(root, p, date="2026-01-01").document
    assert doc["rollup"]["rejected"] == {"flight": ["F1"]}
    assert doc["verdict"] == "rejected"
    assert any("no roll-up rule covers the flight scope" in r for r in doc["rollup"]["reasons"])


@pytest.mark.parametrize(
    "value, expected", [("GeoTIFF", "pass"), ("pass", "fail"), ("Geo TIFF", "fail")]
)
def test_text_requirements_are_literals_even_when_not_identifiers(
    make_delivery, tmp_path, value, expected
):
    images = "image_id,file,block,bands\nI1,a.tif,B1,GeoTIFF\n"
    p = tmp_path / "p.yaml"
    p.write_text(f"""\
orthospec_profile: 1
id: t
version: 1.0.0
title: text
source: {{title: JRC EUR 23638 EN}}
rules:
  - id: FMT
    title: format
    clause: {{document: JRC EUR 23638 EN, section: "6.4"}}
    quote: TIFF 6
    scope: image
    measure: images.bands
    requirement: {{op: "==", value: "{value}"}}
    consequence: reject_item
""")
    doc = check(make_delivery(images=images), p, date="2026-01-01").document
    assert recs(doc, "FMT")["I1"]["verdict"] == expected
