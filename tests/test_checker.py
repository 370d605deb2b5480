"""The checker's file (`check --checker FILE`, INTERFACES item 4): strict, located, outside the delivery.

Real YAML files on disk read by the real loader; the messages must name file:line:col (exit 2
through the CLI's OrthospecError mapping), and the published schema must be the model's.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest
from tests.checking import MINI_CHECKER, write_checker

from orthospec.delivery.checker import checker_schema, load_checker
from orthospec.errors import OrthospecError

ROOT = Path(__file__).resolve().parents[1]


def test_a_valid_checker_file_loads_with_its_lines_and_hash(tmp_path: Path) -> None:
    path = write_checker(tmp_path)
    chk = load_checker(path, delivery_root=tmp_path / "d")
    assert chk.who() == "Eva External (external QC, Paying Agency)"
    assert [m.check for m in chk.model.manual_checks] == ["R-VIS"]
    assert chk.lines[("manual_checks", 0)] == 4 and chk.lines[("waivers", 0)] == 6  # MINI_CHECKER's lines
    ev = chk.evidence("waivers", 0)
    assert ev.file == "checker:checker.yaml" and ev.path == "waivers[0] (line 6)"
    assert chk.sha256 == hashlib.sha256(MINI_CHECKER.encode()).hexdigest()


@pytest.mark.parametrize("text, where, what", [
    (MINI_CHECKER.replace("verdict: pass", "verdict: ok"), ":4:", "verdict"),
    (MINI_CHECKER.replace("approver: Chief", "approver: ''"), ":6:", "approver"),
    (MINI_CHECKER.replace("orthospec_checker: 1", "orthospec_checker: 2"), ":1:", "orthospec_checker"),
    (MINI_CHECKER.replace("checker: {name", "checkr: {name"), ":2:", "checkr"),
    (MINI_CHECKER.replace("date: 2026-01-02", "date: 2026-02-30"), ":4:", "invalid value|date"),
    ("[1, 2]\n", ":1:1:", "mapping"),
    ("a: [\n", ":", "invalid YAML"),
])
def test_a_bad_checker_file_names_file_line_and_column(tmp_path: Path, text: str, where: str, what: str) -> None:
    path = write_checker(tmp_path, text)
    with pytest.raises(OrthospecError, match=what) as exc:
        load_checker(path, delivery_root=tmp_path / "d")
    assert str(path) in str(exc.value) and where in str(exc.value)


def test_the_same_check_and_item_twice_is_refused(tmp_path: Path) -> None:
    text = MINI_CHECKER.replace("waivers:\n", "  - {check: R-VIS, item: '*', date: 2026-01-03, verdict: fail}\nwaivers:\n")
    with pytest.raises(OrthospecError, match=r"checker.yaml:5: manual_checks: R-VIS item '\*' is given twice"):
        load_checker(write_checker(tmp_path, text))


def test_a_missing_checker_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(OrthospecError, match="file not found"):
        load_checker(tmp_path / "nope.yaml")


def test_the_published_schema_is_the_models() -> None:
    committed = json.loads((ROOT / "specs" / "schema" / "checker.schema.json").read_text(encoding="utf-8"))
    assert committed == json.loads(json.dumps(checker_schema()))
    assert committed["properties"]["manual_checks"]["items"]["$ref"].endswith("CheckerManualCheck")


def test_check_with_a_checker_file_inside_the_delivery_exits_2(make_delivery, mini_profile, tmp_path: Path) -> None:
    """`orthospec check D --checker D/x.yaml`: exit 2, a one-line message, no traceback, nothing written."""
    root = make_delivery()
    inside = write_checker(root, name="my-own-verdicts.yaml")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "orthospec.cli.main", "check", str(root), "--profile",
                           str(mini_profile), "--checker", str(inside), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "inside the delivery" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()
    ok = subprocess.run([sys.executable, "-m", "orthospec.cli.main", "check", str(root), "--profile",
                         str(mini_profile), "--checker", str(write_checker(tmp_path)), "--out", str(out),
                         "--date", "2026-01-01", "--format", "json"], capture_output=True, text=True, timeout=120)
    assert ok.returncode in (0, 1), ok.stderr
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    assert doc["checker"]["name"] == "Eva External" and doc["checker"]["file"] == "checker.yaml"
