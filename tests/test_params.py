"""Who may set a threshold (issue 12 item 1) and the one number parser for --param (item 6).

Expected values come from the profiles' published numbers (jrc-v3: min_checkpoints 20 and
fail_share_max 5 %, JRC §12.4 Table 12 and §12.8) and from unit arithmetic (50 cm = 0.5 m), never
from a previous run of orthospec.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from orthospec.cli.main import cli, main
from orthospec.delivery.reader import open_delivery
from orthospec.engine.params import SOURCES, ParameterError, ParamValue, resolve_parameters
from orthospec.errors import SpecError
from orthospec.profile.loader import load_profile

ROOT = Path(__file__).resolve().parent.parent
AERIAL_PASS = ROOT / "examples" / "deliveries" / "aerial-pass"


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ORTHOSPEC_CACHE_DIR", str(tmp_path / "cache"))


def run(*args: object):
    return CliRunner().invoke(cli(), [str(a) for a in args])


def run_main(capsys, *args: object) -> tuple[int, str]:
    """The real entry point (it maps orthospec errors to exit 2); returns (code, stdout + stderr)."""
    with pytest.raises(SystemExit) as ei:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return int(ei.value.code or 0), out.out + out.err


def copy_pass(tmp_path: Path, parameters: str | None) -> Path:
    """aerial-pass with its `tender.parameters` block replaced (None: no parameters at all)."""
    dst = tmp_path / "delivery"
    shutil.copytree(AERIAL_PASS, dst)
    man = dst / "delivery.yaml"
    text = man.read_text(encoding="utf-8")
    block = re.search(r"^  parameters:\n(?:    .*\n)+", text, re.M)
    assert block, "aerial-pass declares tender.parameters"
    new = (
        ""
        if parameters is None
        else "  parameters:\n" + "".join(f"    {ln}\n" for ln in parameters.splitlines())
    )
    man.write_text(text[: block.start()] + new + text[block.end() :], encoding="utf-8")
    return dst


def declared(d: Path) -> dict:
    m = open_delivery(d).manifest
    return dict(m.tender.parameters) if m.tender else {}


JRC = None


def jrc():
    global JRC
    if JRC is None:
        JRC = load_profile("jrc-v3")
    return JRC


# --- the manifest never sets the standard's numbers -------------------------------------------

#: the ITT's tolerance as the checker states it (--param); the manifest's declaration is only evidence
ITT = {"tolerance_xy": "0.5 m", "map_crs": "EPSG:25832"}


def test_manifest_cannot_set_standard_thresholds(tmp_path):
    d = copy_pass(
        tmp_path, "tolerance_xy: {value: 0.5, unit: m}\nmin_checkpoints: 5\nfail_share_max: 50 %"
    )
    vals = resolve_parameters(jrc(), declared(d), ITT)
    # JRC §12.4 Table 12: at least 20 check points; §12.8: at most 5 % failing
    assert vals["min_checkpoints"].source == "standard" and vals["min_checkpoints"].value == 20
    assert vals["fail_share_max"].source == "standard" and vals["fail_share_max"].value == 5
    # what the contractor declared is kept as evidence, converted to the parameter's unit
    assert vals["min_checkpoints"].declared == 5
    assert vals["fail_share_max"].declared == 50
    assert vals["min_checkpoints"].to_dict() == {
        "value": 20.0,
        "unit": "1",
        "source": "standard",
        "declared": 5.0,
    }


def test_manifest_cannot_set_standard_thresholds_in_the_report(tmp_path):
    d = copy_pass(
        tmp_path, "tolerance_xy: {value: 0.5, unit: m}\nmin_checkpoints: 5\nfail_share_max: 50 %"
    )
    out = tmp_path / "out"
    res = run(
        "check",
        d,
        "--profile",
        "jrc-v3",
        "--out",
        out,
        "--date",
        "2026-01-01",
        "--param",
        "tolerance_xy=0.5m",
        "--param",
        "map_crs=EPSG:25832",
    )
    assert res.exit_code in (0, 1), res.output
    params = json.loads((out / "qcr.json").read_text())["profile"]["parameters"]
    assert (
        params["min_checkpoints"]["value"] == 20
        and params["min_checkpoints"]["source"] == "standard"
    )
    assert (
        params["fail_share_max"]["value"] == 5 and params["fail_share_max"]["source"] == "standard"
    )
    assert params["fail_share_max"]["declared"] == 50


def test_the_manifest_never_sets_an_itt_parameter(tmp_path):
    """Red team R1: the brief's "evidence, never authority: it cannot set or loosen a threshold".
    tolerance_xy is left to the ITT (JRC §2.5 "the tolerance stated in the ITT"); a manifest value
    alone stops the run with advice naming every checker-side place to state it."""
    d = copy_pass(tmp_path, "tolerance_xy: 50 cm")
    p = jrc().parameters["tolerance_xy"]
    assert p.default is None and p.value is None and p.authority() == "itt"
    with pytest.raises(ParameterError) as ei:
        resolve_parameters(jrc(), declared(d), {})
    msg = str(ei.value)
    assert "tolerance_xy (m): read by JRC-" in msg
    assert "--param" in msg and "checker file" in msg and "tender profile" in msg
    assert "manifest" not in SOURCES


def _checker(tmp_path, parameters: str, name: str = "checker.yaml"):
    from tests.checking import MINI_CHECKER, write_checker

    from orthospec.delivery.checker import load_checker

    text = MINI_CHECKER.replace(
        "parameters: {tolerance_xy: {value: 0.5, unit: m}}", f"parameters: {parameters}"
    )
    return load_checker(write_checker(tmp_path, text, name))


def test_the_checker_file_states_an_itt_parameter(tmp_path):
    d = copy_pass(tmp_path, "tolerance_xy: {value: 1.0, unit: m}")  # the contractor declares 1 m
    chk = _checker(tmp_path, "{tolerance_xy: {value: 50, unit: cm}, map_crs: 'EPSG:25832'}")
    v = resolve_parameters(jrc(), declared(d), {}, checker=chk)["tolerance_xy"]
    assert (v.value, v.source, v.declared, v.unit) == (0.5, "checker", 1.0, "m")  # 50 cm = 0.5 m
    # --param wins over the checker file, the checker file over a tender profile's value
    assert (
        resolve_parameters(jrc(), declared(d), {**ITT, "tolerance_xy": "0.4"}, checker=chk)[
            "tolerance_xy"
        ].source
        == "cli"
    )
    prof = load_profile(ROOT / "examples" / "specs" / "tender-example.yaml")  # ITT §4.1: 0.5 m
    assert (resolve_parameters(prof, {}, {})["tolerance_xy"].source) == "tender"
    # the tender's value is the contract (issue 26): the checker's file cannot replace it ...
    with pytest.raises(
        ParameterError, match=r"c2.yaml:4: parameters.tolerance_xy: 0.4 m differs from 0.5 m"
    ):
        resolve_parameters(
            prof, {}, {}, checker=_checker(tmp_path, "{tolerance_xy: 40 cm}", "c2.yaml")
        )
    # ... but states it again freely (50 cm is the tender's 0.5 m)
    same = resolve_parameters(
        prof, {}, {}, checker=_checker(tmp_path, "{tolerance_xy: 50 cm}", "c3.yaml")
    )
    assert (same["tolerance_xy"].value, same["tolerance_xy"].source) == (0.5, "checker")


@pytest.mark.parametrize(
    "parameters, match",
    [
        ("{tolerance_xy: {value: 0.5, unit: s}}", r"checker.yaml:4: parameters.tolerance_xy: "),
        ("{tolerance_xy: '0,5'}", r"checker.yaml:4: parameters.tolerance_xy: .*decimal comma"),
        ("{tolerance_xy: {value: .nan, unit: m}}", r"checker.yaml:4: parameters.tolerance_xy: "),
        (
            "{tolerance_xyz: {value: 0.5, unit: m}}",
            r"checker.yaml:4: parameters.tolerance_xyz: profile jrc-v3 has no "
            r"such parameter; did you mean 'tolerance_xy'\?",
        ),
        (
            "{systematic_error_level: sometimes}",
            r"checker file .*checker.yaml:4: parameter systematic_error_level=",
        ),
    ],
)
def test_a_bad_checker_parameter_names_file_and_line(tmp_path, parameters, match):
    with pytest.raises(ParameterError, match=match):
        resolve_parameters(jrc(), {}, ITT, checker=_checker(tmp_path, parameters))


def test_a_checker_parameter_another_profile_reads_is_ignored(tmp_path):
    """One checker file may serve several profiles: jrc-v3's tolerance_xy is nothing to asprs-2023."""
    vals = resolve_parameters(
        load_profile("asprs-2023"),
        {},
        {},
        checker=_checker(tmp_path, "{tolerance_xy: {value: 0.5, unit: m}}"),
    )
    assert "tolerance_xy" not in vals and all(v.source != "checker" for v in vals.values())


def test_cli_wins_and_keeps_the_declared_value_for_the_cross_check(tmp_path):
    d = copy_pass(tmp_path, "tolerance_xy: {value: 0.5, unit: m}")
    v = resolve_parameters(jrc(), declared(d), {**ITT, "tolerance_xy": "0.4"})["tolerance_xy"]
    assert (v.value, v.source, v.declared) == (0.4, "cli", 0.5)
    assert all(pv.source in SOURCES for pv in resolve_parameters(jrc(), declared(d), ITT).values())


def test_unreadable_declared_value_is_noted_not_fatal(tmp_path):
    d = copy_pass(
        tmp_path,
        "tolerance_xy: {value: 0.5, unit: m}\nmin_checkpoints: '0,5'\ncloud_cover_max: lots",
    )
    vals = resolve_parameters(jrc(), declared(d), ITT)
    assert (
        vals["min_checkpoints"].declared is None and "decimal comma" in vals["min_checkpoints"].note
    )
    assert vals["cloud_cover_max"].declared is None and vals["cloud_cover_max"].note
    assert "declared" not in vals["min_checkpoints"].to_dict()
    assert (
        "decimal comma" in vals["min_checkpoints"].to_dict()["note"]
    )  # evidence the report can show
    assert vals["min_checkpoints"].value == 20


def test_unknown_manifest_parameter_is_ignored_here(tmp_path):
    d = copy_pass(tmp_path, "tolerance_xy: {value: 0.5, unit: m}\nno_such_thing: 3")
    assert "no_such_thing" not in resolve_parameters(jrc(), declared(d), ITT)


# --- one number parser for --param ---------------------------------------------------------------


@pytest.mark.parametrize("text", ["0.5", "0.5m", "0.5 m", "50 cm", "500 mm", ".5"])
def test_cli_param_numbers_with_units(text):
    v = resolve_parameters(jrc(), {}, {**ITT, "tolerance_xy": text})["tolerance_xy"]
    assert v.value == pytest.approx(0.5) and v.source == "cli"


@pytest.mark.parametrize(
    "text, hint",
    [
        ("0,5", "write 0.5"),
        ("1,0 m", "write 1.0 m"),
        ("inf", "not a number"),
        ("nan", "not a number"),
        ("1e999", "not a finite number"),
        ("one metre", "not a number"),
        ("0.5 %", "does not convert"),
        ("", "not a number"),
    ],
)
def test_cli_param_refuses_what_pint_would_misread(text, hint):
    with pytest.raises(ParameterError, match=re.escape(hint)):
        resolve_parameters(jrc(), {}, {"tolerance_xy": text})


def test_cli_decimal_comma_exits_2_with_a_hint(tmp_path, capsys):
    code, out = run_main(
        capsys,
        "check",
        AERIAL_PASS,
        "--profile",
        "jrc-v3",
        "--param",
        "tolerance_xy=0,5",
        "--out",
        tmp_path / "o",
    )
    assert code == 2
    assert "decimal comma" in out and "write 0.5" in out and "Traceback" not in out
    assert not (tmp_path / "o" / "qcr.json").exists()


def test_unknown_cli_parameter_suggests_the_right_name():
    with pytest.raises(ParameterError, match="did you mean 'cloud_cover_max'"):
        resolve_parameters(jrc(), {}, {"cloud_cover_maximum": "5"})


# --- unset parameters a rule needs stop the run -----------------------------------------------


def test_usgs_insitu_without_any_tolerance_exits_2_with_advice(tmp_path, capsys):
    d = copy_pass(tmp_path, None)
    code, out = run_main(capsys, "check", d, "--profile", "usgs-insitu", "--out", tmp_path / "o")
    assert code == 2, out
    for name in ("tolerance_xy", "tolerance_ce90", "tolerance_ce95", "tolerance_net"):
        assert name in out
    assert "--param" in out and "USGS-RMSE-X" in out
    assert "expected a number, got None" not in out
    assert not (tmp_path / "o" / "qcr.json").exists()


TENDER_UNSET = """\
orthospec_profile: 1
id: t-unset
version: 1.0.0
title: tender reading an unset tolerance
source: {{title: ITT}}
extends: {{id: jrc-v3, version: 3.0.0}}
parameters:
  tolerance_xy: {{value: 0.5}}
  map_crs: {{value: "EPSG:25832"}}
rules:
  - id: ITT-DEM
    title: DEM accuracy
    clause: {{document: ITT, section: "4.2"}}
    quote: "The DEM RMSEz shall not exceed the tender value."
    scope: block
{when}    measure: checkpoints.rmse_z
    requirement: {{op: "<=", value: "tolerance_z", unit: m}}
    consequence: reject_block
"""


def test_unset_parameter_read_by_a_rule_stops_the_run(tmp_path):
    f = tmp_path / "t.yaml"
    f.write_text(TENDER_UNSET.format(when=""))
    prof = load_profile(f)
    with pytest.raises(ParameterError) as ei:
        resolve_parameters(prof, {}, {})
    msg = str(ei.value)
    assert "tolerance_z (m): read by" in msg and "ITT-DEM" in msg and "--param" in msg
    # set on the command line, it resolves
    assert resolve_parameters(prof, {}, {"tolerance_z": "1"})["tolerance_z"].value == 1.0


def test_rule_that_tests_the_parameter_is_optional(tmp_path):
    f = tmp_path / "t.yaml"
    f.write_text(TENDER_UNSET.format(when='    when: "tolerance_z != null"\n'))
    vals = resolve_parameters(load_profile(f), {}, {})
    assert vals["tolerance_z"].source == "unset" and vals["tolerance_z"].value is None


def test_manifest_gated_rule_needs_its_parameter_only_when_it_applies():
    # JRC-12.7-RMSEZ: "Where the DEM is also a deliverable ... checked using the Z threshold"
    base = {"manifest.sensor.type": "aerial"}
    ok = resolve_parameters(
        jrc(), {}, ITT, manifest={**base, "manifest.product.dem_delivered": False}
    )
    assert ok["tolerance_z"].source == "unset"
    with pytest.raises(ParameterError, match="JRC-12.7-RMSEZ"):
        resolve_parameters(
            jrc(), {}, ITT, manifest={**base, "manifest.product.dem_delivered": True}
        )


def test_param_value_quantity_and_dict():
    v = ParamValue("t", 0.5, "m", "tender", justification="ITT 4.1")
    assert str(v.quantity().units) == "meter" and v.quantity().magnitude == 0.5
    assert v.to_dict() == {
        "value": 0.5,
        "unit": "m",
        "source": "tender",
        "justification": "ITT 4.1",
    }


# --- map_crs: the ITT's map projection (red team R16) ---------------------------------------------
# JRC §12.4 Table 12 "Ortho-image: ... georeferenced to the (national) map projection": the projection
# is the ITT's, stated on the checker's side; the manifest's project.crs only declares it.


def test_map_crs_is_an_itt_parameter_the_run_cannot_do_without():
    p = jrc().parameters["map_crs"]
    assert p.default is None and p.required and p.authority() == "itt" and p.unit == "text"
    with pytest.raises(ParameterError) as ei:
        resolve_parameters(jrc(), {}, {"tolerance_xy": "0.5"})
    msg = str(ei.value)
    assert (
        "map_crs (text): required by the profile (a coordinate reference system: EPSG:<code>)"
        in msg
    )
    assert "--param map_crs=EPSG:<code>" in msg and "parameters: {map_crs: EPSG:<code>}" in msg


@pytest.mark.parametrize(
    "text",
    [
        "EPSG:25832",
        "epsg:25832",
        "urn:ogc:def:crs:EPSG::25832",
        "+proj=utm +zone=32 +ellps=GRS80 +units=m +no_defs",
    ],
)
def test_map_crs_is_read_with_pyproj_and_held_as_its_epsg_code(text):
    # EPSG:25832 = ETRS89 / UTM zone 32N = UTM zone 32 on GRS80 (the EPSG registry's definition)
    v = resolve_parameters(jrc(), {}, {**ITT, "map_crs": text})["map_crs"]
    assert (v.value, v.source, v.unit) == ("EPSG:25832", "cli", "text")


def test_map_crs_from_the_checker_file_and_a_tender_profile(tmp_path):
    chk = _checker(tmp_path, "{tolerance_xy: 0.5 m, map_crs: 'urn:ogc:def:crs:EPSG::25833'}")
    v = resolve_parameters(jrc(), {}, {}, checker=chk)["map_crs"]
    assert (v.value, v.source) == ("EPSG:25833", "checker")
    prof = load_profile(ROOT / "examples" / "specs" / "tender-example.yaml")
    assert (
        resolve_parameters(prof, {}, {})["map_crs"].source,
        resolve_parameters(prof, {}, {})["map_crs"].value,
    ) == ("tender", "EPSG:25832")
    # the tender's map projection is the contract: another one from the checker's side stops the run,
    # the same CRS however written passes
    with pytest.raises(
        ParameterError, match=r"parameters.map_crs: EPSG:25833 differs from EPSG:25832"
    ):
        resolve_parameters(prof, {}, {}, checker=chk)
    with pytest.raises(
        ParameterError, match=r"--param map_crs=EPSG:3035: EPSG:3035 differs from EPSG:25832"
    ):
        resolve_parameters(prof, {}, {"map_crs": "EPSG:3035"})
    assert resolve_parameters(prof, {}, {"map_crs": "epsg:25832"})["map_crs"].value == "EPSG:25832"


@pytest.mark.parametrize(
    "text, why",
    [
        ("garbage", "is not a coordinate reference system pyproj can read"),
        ("EPSG:99999999", "is not a coordinate reference system pyproj can read"),
        ("+proj=tmerc +lat_0=0 +lon_0=10.3 +k=1 +x_0=0 +y_0=0 +ellps=GRS80", "has no EPSG code"),
    ],
)
def test_a_map_crs_pyproj_cannot_name_stops_the_run_naming_its_source(tmp_path, text, why):
    with pytest.raises(
        ParameterError, match=re.escape(f"--param map_crs={text}: ") + ".*" + re.escape(why)
    ):
        resolve_parameters(jrc(), {}, {**ITT, "map_crs": text})
    chk = _checker(tmp_path, f"{{tolerance_xy: 0.5 m, map_crs: '{text}'}}")
    with pytest.raises(
        ParameterError, match=r"checker.yaml:4: parameters.map_crs: .*" + re.escape(why)
    ):
        resolve_parameters(jrc(), {}, {}, checker=chk)
    f = tmp_path / "t.yaml"
    f.write_text(
        TENDER_UNSET.format(when="").replace(
            'map_crs: {value: "EPSG:25832"}', f"map_crs: {{value: '{text}'}}"
        )
    )
    # a tender profile's map projection is read when the profile is validated (issue 26)
    with pytest.raises(SpecError, match=r"t.yaml:9:\d+: parameter map_crs: .*" + re.escape(why)):
        load_profile(f)


def test_a_declared_map_crs_is_compared_as_a_crs(tmp_path):
    d = copy_pass(tmp_path, "tolerance_xy: {value: 0.5, unit: m}\nmap_crs: 'epsg:25832'")
    v = resolve_parameters(jrc(), declared(d), ITT)["map_crs"]
    assert (v.value, v.declared) == (
        "EPSG:25832",
        "EPSG:25832",
    )  # same CRS, other spelling: no finding
    d2 = copy_pass(tmp_path / "2", "tolerance_xy: {value: 0.5, unit: m}\nmap_crs: 'UTM 32'")
    v2 = resolve_parameters(jrc(), declared(d2), ITT)["map_crs"]
    assert v2.declared is None and "cannot be read" in v2.note
