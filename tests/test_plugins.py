"""Extension points (issue 15 item 5): the example plugin in examples/plugins/ is installed for real
(``pip install --no-deps --target``, a wheel built by its own build backend) into a temporary
folder, and ``orthospec check`` run with that folder on ``PYTHONPATH`` finds its profile, its
measure and its output format through the entry points of the installed ``.dist-info``.

Nothing is installed into the project's virtualenv, so other tests never see the plugin.
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from tests.conftest import EXAMPLES

from orthospec.qcr import all_records

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "examples" / "plugins" / "orthospec-example-plugin"
CHECKER = ROOT / "examples" / "checker" / "aerial-pass"
RULE = "EXAMPLE-5.3-SELF-DOCUMENTING-NAME"
RENAMED = "F01_0103"


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example plugin installed into a fresh folder (a real wheel, built by hatchling)."""
    target = tmp_path_factory.mktemp("site")
    build = tmp_path_factory.mktemp("plugin-src") / "p"
    shutil.copytree(
        PLUGIN, build
    )  # pip may write build files next to the sources: not into the repo
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "--no-build-isolation",
            "--quiet",
            "--target",
            str(target),
            str(build),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, f"pip could not install the example plugin:\n{proc.stderr[-3000:]}"
    eps = next(target.glob("orthospec_example_plugin-*.dist-info")) / "entry_points.txt"
    assert "[orthospec.providers]" in eps.read_text(encoding="utf-8")
    return target


def orthospec(site: Path, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]),
        "ORTHOSPEC_CACHE_DIR": "off",
    }
    return subprocess.run(
        [sys.executable, "-m", "orthospec.cli.main", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        cwd=cwd,
    )


@pytest.fixture(scope="module")
def delivery(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """aerial-pass with one image file renamed (and its table row following it)."""
    root = tmp_path_factory.mktemp("deliv") / "aerial-pass"
    shutil.copytree(EXAMPLES / "aerial-pass", root)
    (root / "images" / f"{RENAMED}.tif").rename(root / "images" / "photo_3.tif")
    images = root / "tables" / "images.csv"
    text = images.read_text(encoding="utf-8")
    assert text.count(f"images/{RENAMED}.tif") == 1
    images.write_text(text.replace(f"images/{RENAMED}.tif", "images/photo_3.tif"), encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def checked(site: Path, delivery: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    out = tmp_path_factory.mktemp("out")
    res = orthospec(
        site,
        "check",
        str(delivery),
        "--profile",
        "example-agency",
        "--checker",
        str(CHECKER),
        "--format",
        "json",
        "--out",
        str(out),
        "--date",
        "2026-07-01",
    )
    assert res.returncode in (0, 1), res.stderr
    return json.loads((out / "qcr.json").read_text(encoding="utf-8"))


def test_plugin_profile_and_measure_are_found_and_judge(checked: dict, delivery: Path) -> None:
    """`--profile example-agency` is the plugin's profile (it extends the shipped jrc-v3) and its
    rule is measured by the plugin's provider: every image is judged, the renamed one fails."""
    assert checked["profile"]["id"] == "example-agency"
    assert any(r["rule"].startswith("JRC-") for r in checked["rules"])  # jrc-v3's rules, inherited
    recs = {r["item"]: r for r in all_records(checked) if r["rule"] == RULE}
    with (delivery / "tables" / "images.csv").open(encoding="utf-8") as fh:
        ids = [row["image_id"] for row in csv.DictReader(fh)]
    assert sorted(recs) == sorted(ids) and len(ids) == 30
    assert {i: r["verdict"] for i, r in recs.items() if r["verdict"] != "pass"} == {RENAMED: "fail"}
    assert recs[RENAMED]["measured"]["value"] is False
    assert recs[RENAMED]["evidence"][0]["file"] == "tables/images.csv"
    assert RENAMED in checked["rollup"]["rejected"]["image"]  # a mandatory reject_item rule


def test_plugin_format_renders_the_document(site: Path, checked: dict, tmp_path: Path) -> None:
    """The format entry point loads by name and renders the real QCR document."""
    doc = tmp_path / "qcr.json"
    doc.write_text(json.dumps(checked), encoding="utf-8")
    code = (
        "import json, sys; from orthospec import plugins; f = plugins.output_format('example-tiles'); "
        "print(f.suffix); print(f.origin); sys.stdout.write(f.render(json.load(open(sys.argv[1]))))"
    )
    env = {**os.environ, "PYTHONPATH": str(site)}
    res = subprocess.run(
        [sys.executable, "-c", code, str(doc)], capture_output=True, text=True, env=env, timeout=120
    )
    assert res.returncode == 0, res.stderr
    suffix, origin, *rows = res.stdout.splitlines()
    assert suffix == ".tiles.csv"
    assert "orthospec-example-plugin 0.1.0" in origin and "example-tiles" in origin
    table = {r["image"]: r for r in csv.DictReader(io.StringIO("\n".join(rows)))}
    assert len(table) == 30
    assert RULE in table[RENAMED]["failing_rules"].split(";")
    assert all(RULE not in r["failing_rules"] for i, r in table.items() if i != RENAMED)


def test_check_writes_the_plugin_format(site: Path, delivery: Path, tmp_path: Path) -> None:
    res = orthospec(
        site,
        "check",
        str(delivery),
        "--profile",
        "example-agency",
        "--checker",
        str(CHECKER),
        "--format",
        "example-tiles",
        "--out",
        str(tmp_path),
        "--date",
        "2026-07-01",
    )
    assert res.returncode in (0, 1), res.stderr
    rows = list(csv.DictReader((tmp_path / "qcr.tiles.csv").open(encoding="utf-8")))
    assert [r["image"] for r in rows if RULE in r["failing_rules"]] == [RENAMED]


def test_a_broken_plugin_is_named(tmp_path: Path) -> None:
    """A provider plugin whose module cannot be imported stops the run (exit 2) with a message
    naming its distribution and entry point, not a traceback."""
    dist = tmp_path / "broken_plugin-1.2.3.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: broken-plugin\nVersion: 1.2.3\n", encoding="utf-8"
    )
    (dist / "entry_points.txt").write_text(
        "[orthospec.providers]\nbroken = no_such_module_xyz\n", encoding="utf-8"
    )
    prof = tmp_path / "p.yaml"
    prof.write_text(
        (ROOT / "tests" / "data" / "profiles" / "mini.yaml")
        .read_text(encoding="utf-8")
        .replace("measure: images.roll", "measure: images.rol"),
        encoding="utf-8",
    )  # an unknown name makes plugins load
    res = orthospec(tmp_path, "spec", "validate", str(prof))
    assert res.returncode == 2, (res.stdout, res.stderr)
    msg = res.stderr + res.stdout
    assert "broken-plugin 1.2.3" in msg and "broken = no_such_module_xyz" in msg
    assert "Traceback" not in msg


def test_no_plugin_is_looked_for_by_help() -> None:
    code = (
        "import sys; from orthospec.cli.main import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in sys.modules if m in ('importlib.metadata', 'orthospec.plugins')))"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.stdout.strip().splitlines()[-1] == "[]"


def test_a_tender_extends_a_plugin_profile(site: Path, tmp_path: Path) -> None:
    """`extends` finds a profile a plugin ships (after the shipped ones and the tender's folder),
    and the plugin's measure validates in the extending file."""
    tender = tmp_path / "tender.yaml"
    tender.write_text(
        """\
orthospec_profile: 1
id: tender-on-plugin
version: 0.1.0
title: A tender adopting the example agency profile
source: {title: ITT (test)}
extends: {id: example-agency, version: 1.0.0}
parameters:
  tolerance_xy: {unit: m, value: 0.5, description: ITT 4.1}
""",
        encoding="utf-8",
    )
    res = orthospec(site, "spec", "show", str(tender))
    assert res.returncode == 0, res.stderr
    assert "EXAMPLE-5.3-SELF-DOCUMENTING-NAME" in res.stdout and "example-agency" in res.stdout
    bare = subprocess.run(
        [sys.executable, "-m", "orthospec.cli.main", "spec", "validate", str(tender)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "ORTHOSPEC_CACHE_DIR": "off"},
    )
    assert bare.returncode == 2 and "unknown profile 'example-agency'" in bare.stderr + bare.stdout


def test_a_file_cannot_claim_the_id_of_a_profile_a_plugin_installs(
    site: Path, tmp_path: Path
) -> None:
    """Issue 25 item 7: ids are reserved for the profiles shipped or installed by a plugin."""
    fake = tmp_path / "agency.yaml"
    fake.write_text(
        "orthospec_profile: 1\nid: example-agency\nversion: 1.0.0\ntitle: not the agency's\n"
        "source: {title: x}\nextends: {id: jrc-v3, version: 3.0.0}\n",
        encoding="utf-8",
    )
    res = orthospec(site, "spec", "validate", str(fake))
    assert res.returncode == 2, res.stdout + res.stderr
    assert "agency.yaml:2:5: id 'example-agency' is reserved" in res.stderr
    assert "installed by a plugin" in res.stderr
