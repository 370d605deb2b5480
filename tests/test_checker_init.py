"""`orthospec checker init` (issue 29 item 4): the checker folder's skeleton.

The shipped satellite-pass checker folder was written by examples/generate.py from its own list of
the manual checks that delivery owes (every applicable manual rule is signed there: see
tests/test_examples_jrc.py); the skeleton must list the same items, each image's bound to the
file's SHA-256 (hashlib), and, filled in, give the same verdict as the shipped folder.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from tests.checking import CHECKERS, DATE, EXAMPLES, check_with

from orthospec.cli.main import cli
from orthospec.delivery.checker import load_checker


def _init(delivery: Path, out: Path, *extra: str) -> object:
    return CliRunner().invoke(
        cli(), ["checker", "init", str(delivery), "-p", "jrc-v3", "--out", str(out), *extra]
    )


def _items(entries: list[dict], scope_of: dict[str, str]) -> set[tuple[str, str]]:
    # the shipped file judges a single DEM with "*"; the skeleton names it
    return {
        (e["check"], "*" if scope_of.get(e["check"]) == "dem" else str(e["item"])) for e in entries
    }


def test_the_skeleton_lists_every_manual_item_bound_to_the_images(tmp_path: Path) -> None:
    res = _init(EXAMPLES / "satellite-pass", tmp_path / "qc", "--name", "T. Tester")
    assert res.exit_code == 0, res.output
    sk = yaml.safe_load((tmp_path / "qc" / "checker.yaml").read_text(encoding="utf-8"))
    shipped = yaml.safe_load(
        (CHECKERS / "satellite-pass" / "checker.yaml").read_text(encoding="utf-8")
    )
    from orthospec.profile.loader import load_profile

    scope_of = {r.id: r.scope for r in load_profile("jrc-v3").rules}
    # the shipped file also signs JRC-T9-GCP-OVERLAP-ZONES on S02's scenes, which its `when` (RPC block
    # adjustment) leaves out: S02 is corrected scene by scene (scenes.csv correction_method)
    import csv

    with (EXAMPLES / "satellite-pass" / "tables" / "scenes.csv").open(
        encoding="utf-8", newline=""
    ) as f:
        single = {r["image_id"] for r in csv.DictReader(f) if r["correction_method"] != "rpc_block"}
    extra = {("JRC-T9-GCP-OVERLAP-ZONES", i) for i in single}
    assert (
        extra
        and _items(sk["manual_checks"], scope_of)
        == _items(shipped["manual_checks"], scope_of) - extra
    )
    images = [e for e in sk["manual_checks"] if scope_of[e["check"]] == "image"]
    assert images
    for e in images:
        item = e["item"]
        path = EXAMPLES / "satellite-pass" / e["file"]
        assert (
            e["file"] == f"images/{item}.tif"
            and e["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
        )
    assert all(e["verdict"] is None and e["date"] is None for e in sk["manual_checks"])
    # every table and document the delivery uses, pinned with its role
    manifest = yaml.safe_load(
        (EXAMPLES / "satellite-pass" / "delivery.yaml").read_text(encoding="utf-8")
    )
    used = {f"tables.{k}": v for k, v in manifest["tables"].items()}
    used |= {f"documents.{k}": v for k, v in manifest["documents"].items()}
    assert {p["role"]: rel for rel, p in sk["delivery"]["files"].items()} == used
    assert all(
        p["sha256"] == hashlib.sha256((EXAMPLES / "satellite-pass" / rel).read_bytes()).hexdigest()
        for rel, p in sk["delivery"]["files"].items()
    )
    # the ITT values are the checker's to state: listed, commented out, never filled from the delivery
    text = (tmp_path / "qc" / "checker.yaml").read_text(encoding="utf-8")
    assert (
        '# tolerance_xy: {value: , unit: "m"}   # required' in text
        and "the delivery declares 1 m" in text
    )
    assert "# map_crs:" in text and sk["parameters"] is None
    bound = sum(1 for e in sk["manual_checks"] if "sha256" in e)
    assert bound == sum(1 for e in sk["manual_checks"] if scope_of[e["check"]] == "image")
    assert f"{len(sk['manual_checks'])} manual check items to judge ({bound} bound" in res.output
    # it loads as the checker's file it is (every verdict still to give)
    assert load_checker(tmp_path / "qc").model.checker.name == "T. Tester"


def test_the_skeleton_filled_in_gives_the_shipped_verdict(tmp_path: Path) -> None:
    assert _init(EXAMPLES / "satellite-pass", tmp_path / "qc", "--name", "T. Tester").exit_code == 0
    path = tmp_path / "qc" / "checker.yaml"
    sk = yaml.safe_load(path.read_text(encoding="utf-8"))
    shipped = yaml.safe_load(
        (CHECKERS / "satellite-pass" / "checker.yaml").read_text(encoding="utf-8")
    )
    sk["parameters"] = shipped["parameters"]
    for e in sk["manual_checks"]:
        e.update(verdict="pass", date="2026-07-10")
    path.write_text(yaml.safe_dump(sk, sort_keys=False), encoding="utf-8")
    (tmp_path / "qc" / "tables").mkdir()
    shutil.copyfile(
        CHECKERS / "satellite-pass" / "tables" / "checkpoints.csv",
        tmp_path / "qc" / "tables" / "checkpoints.csv",
    )  # what `measure checkpoints` writes
    got = check_with(
        EXAMPLES / "satellite-pass", "jrc-v3", checker=tmp_path / "qc", date=DATE
    ).document
    want = check_with(
        EXAMPLES / "satellite-pass", "jrc-v3", checker=CHECKERS / "satellite-pass", date=DATE
    ).document
    assert got["verdict"] == want["verdict"] == "accepted"
    assert got["summary"] == want["summary"]


def test_checker_init_never_overwrites_and_never_writes_into_the_delivery(tmp_path: Path) -> None:
    assert _init(EXAMPLES / "aerial-pass", tmp_path / "qc").exit_code == 0
    before = (tmp_path / "qc" / "checker.yaml").read_bytes()
    again = _init(EXAMPLES / "aerial-pass", tmp_path / "qc")
    assert again.exit_code != 0 and "is never overwritten" in str(again.exception)
    assert (tmp_path / "qc" / "checker.yaml").read_bytes() == before
    d = tmp_path / "d"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    inside = _init(d, d / "qc")
    assert inside.exit_code != 0 and not (d / "qc").exists()
    # without --name the form loads only once the checker says who checks
    with pytest.raises(Exception, match="name"):
        load_checker(tmp_path / "qc")
