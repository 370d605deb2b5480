"""`orthospec spec diff` computed by the library (issue 28 item 1): `--json` carries the rules whose
effective requirement changed only through a parameter, the same list the text output prints."""

from __future__ import annotations

import json
from pathlib import Path

import yaml
from click.testing import CliRunner

from orthospec import api
from orthospec.cli.main import cli
from orthospec.profile.loader import load_profile

ROOT = Path(__file__).resolve().parents[1]
TENDER = ROOT / "examples" / "specs" / "tender-example.yaml"


def test_json_lists_the_rules_changed_through_parameters_as_the_text_does() -> None:
    lib = api.diff("jrc-v3", TENDER)["through_parameters"]
    res = CliRunner().invoke(cli(), ["spec", "diff", "jrc-v3", str(TENDER), "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["through_parameters"] == lib
    text = CliRunner().invoke(cli(), ["spec", "diff", "jrc-v3", str(TENDER)])
    got = [x for x in text.output.splitlines() if x.endswith("(through its parameters)")]
    assert got == [f"~ rule {t['id']}: requirement {t['before']} -> {t['after']} (through its parameters)"
                   for t in lib]
    assert len(lib) >= 5


def test_a_threshold_through_parameters_is_the_tender_value_over_the_standard_factor() -> None:
    """JRC §7.1: GCPs 3x more accurate than the tolerance: the tender's tolerance_xy over jrc-v3's
    gcp_accuracy_factor, computed here from the two YAML files."""
    tol = yaml.safe_load(TENDER.read_text(encoding="utf-8"))["parameters"]["tolerance_xy"]["value"]
    factor = load_profile("jrc-v3").parameters["gcp_accuracy_factor"].default
    got = {t["id"]: t for t in api.diff("jrc-v3", TENDER)["through_parameters"]}
    assert got["JRC-7.1-GCP-ACCURACY-3X"]["after"] == f"≤ {float(tol) / float(factor):.6g} m"
    assert "tolerance_xy" in got["JRC-7.1-GCP-ACCURACY-3X"]["before"]


def test_no_parameter_change_no_entry() -> None:
    assert api.diff("jrc-v3", "jrc-v3")["through_parameters"] == []
