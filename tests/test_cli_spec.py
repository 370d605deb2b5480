import json
from pathlib import Path

from click.testing import CliRunner

from checking import write_checker
from orthospec.cli.main import cli
from orthospec.delivery.reader import open_delivery


def run(*args):
    return CliRunner().invoke(cli(), list(map(str, args)))


def test_spec_validate_ok_and_bad(mini_profile, tmp_path):
    ok = run("spec", "validate", mini_profile)
    assert ok.exit_code == 0 and "valid (mini 1.0.0, 5 rules" in ok.output
    bad = tmp_path / "bad.yaml"
    bad.write_text(mini_profile.read_text().replace("scope: image\n    measure: images.roll",
                                                    "scope: image\n    measure: images.rol"))
    res = run("spec", "validate", bad)
    assert res.exit_code == 2
    assert "bad.yaml:" in res.output and "unknown measure 'images.rol'" in res.output


def test_spec_show_and_diff(mini_profile, tmp_path):
    shown = run("spec", "show", mini_profile, "--json")
    assert shown.exit_code == 0 and json.loads(shown.output)["id"] == "mini"
    tender = tmp_path / "tender.yaml"
    tender.write_text("""\
orthospec_profile: 1
id: tender
version: 1.0.0
title: A tender
source: {title: ITT 1}
extends: {id: mini, version: 1.0.0}
parameters:
  max_roll: {value: 2, justification: "ITT §4: stricter roll"}
remove_rules: [R-CV]
rules:
  - id: R-ROLL
    override: true
    level: recommended
    justification: "ITT §4: roll is advisory"
""")
    (tmp_path / "mini.yaml").write_text(mini_profile.read_text())
    res = run("spec", "diff", tmp_path / "mini.yaml", tender)
    assert res.exit_code == 0, res.output
    assert "- rule R-CV" in res.output
    assert "~ rule R-ROLL" in res.output and "level: mandatory -> recommended" in res.output
    assert (
        "~ parameter max_roll: effective 3 deg -> 2 deg" in res.output
        and "value: — -> 2" in res.output
    )


def test_explain(mini_profile):
    res = run("explain", "R-ROLL", "--profile", mini_profile)
    assert res.exit_code == 0
    assert (
        "§5.2.4" in res.output
        and "images.roll" in res.output
        and "≤ 3 deg" in res.output
        and "max_roll" in res.output
    )
    miss = run("explain", "R-RO", "--profile", mini_profile)
    assert miss.exit_code != 0 and "did you mean R-ROLL" in miss.output


def test_profiles_lists_given_files(mini_profile):
    res = run("profiles", mini_profile)
    assert res.exit_code == 0 and "mini" in res.output and "1.0.0" in res.output


def test_init_writes_a_valid_template(tmp_path):
    res = run("init", tmp_path / "new")
    assert res.exit_code == 0
    d = open_delivery(tmp_path / "new")
    d.load_all_tables()
    assert d.manifest.project.crs == "EPSG:25832"
    again = run("init", tmp_path / "new")
    assert again.exit_code != 0


def test_verify_runs_profile_tests(mini_profile, make_delivery, tmp_path):
    root = make_delivery()
    prof = tmp_path / "v.yaml"
    # the waiver in force and the manual verdict come from the checker's file (the delivery's own
    # waiver is only a request); the second entry is the planted mismatch: without the checker's file
    # the manual check R-VIS is unsigned (missing), so the delivery cannot be accepted
    write_checker(tmp_path)
    prof.write_text(
        mini_profile.read_text()
        + f"""
tests:
  - delivery: {root}
    checker: checker.yaml
    expect: {{verdict: rejected, rules: {{R-ROLL: waived, R-FH: fail}}}}
  - delivery: {root}
    params: {{max_roll: 10, tolerance_xy: 0.5}}
    expect: {{verdict: accepted}}
"""
    )
    res = run("verify", prof)
    assert "3 of 4 expectations met" in res.output, res.output
    assert res.exit_code == 1
    assert "tests[1] d: verdict      accepted  rejected  MISMATCH" in res.output, res.output


def test_spec_diff_shows_effective_values_with_units_and_warns_on_same_version(tmp_path):
    root = Path(__file__).resolve().parents[1]
    tender = root / "examples" / "specs" / "tender-example.yaml"
    res = run("spec", "diff", "jrc-v3", tender)
    assert res.exit_code == 0, res.output
    assert "~ parameter tolerance_xy: effective — -> 0.5 m" in res.output
    assert (
        "None" not in res.output and ": '" not in res.output
    )  # YAML-like values, not Python reprs
    # 0.5 m / gcp_accuracy_factor 3 (JRC §7.1) = 0.167 m
    assert "JRC-7.1-GCP-ACCURACY-3X: requirement" in res.output and "-> ≤ 0.166667 m" in res.output
    edited = tmp_path / "tender-edited.yaml"
    edited.write_text(
        tender.read_text(encoding="utf-8").replace("value: 0.5\n", "value: 0.4\n", 1),
        encoding="utf-8",
    )
    same = CliRunner().invoke(cli(), ["spec", "diff", str(tender), str(edited)])
    assert same.exit_code == 0
    assert "warning: both files say tender-example 1.0.0" in same.stderr
    assert "effective 0.5 m -> 0.4 m" in same.output


def test_init_for_a_profile_and_sensor_writes_what_it_reads(tmp_path):
    """The satellite template has the scenes table, the aerial one the flights and cameras tables
    (JRC §5.3 per-flight records); both validate as written and name a local schema."""
    for sensor in ("aerial", "satellite"):
        folder = tmp_path / sensor
        res = run("init", folder, "--profile", "jrc-v3", "--sensor", sensor)
        assert res.exit_code == 0, res.output
        manifest = (folder / "delivery.yaml").read_text(encoding="utf-8")
        assert (
            "$schema=./delivery.schema.json" in manifest
            and (folder / "delivery.schema.json").is_file()
        )
        assert "documents:" in manifest and "internal_qcr" in manifest
        d = open_delivery(folder)
        d.load_all_tables()
        tables = set(d.manifest.tables)
        assert "manual_checks" in tables and "checkpoints" in tables
        guide = (folder / "TEMPLATE.md").read_text(encoding="utf-8")
        assert "| point_id | required |" in guide and "optional" in guide
    assert "scenes" in set(open_delivery(tmp_path / "satellite").manifest.tables)
    aerial = set(open_delivery(tmp_path / "aerial").manifest.tables)
    assert "scenes" not in aerial and {"flights", "cameras"} <= aerial
