"""Evaluation without hidden state (issue 26 "What to build" 5).

The checker's data (its outlines, its tables, its grid) lives on the evaluation context, never on
the ``Delivery``: a second ``check()`` of the same opened delivery without a checker must judge
exactly as a fresh check without one. Before the fix, ``delivery/checker.bind`` wrote the checker's
outlines onto the ``Delivery`` and the second check judged JRC-12.4-BLOCK-OUTLINES-AGREE and
JRC-5.2.2-AOI-AGREES against them (``pass`` instead of ``not_applicable``) while reporting
``checker: null``.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import yaml
from tests.checking import DATE, check_with, records

from orthospec.delivery.checker import load_checker
from orthospec.delivery.reader import open_delivery

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deliveries" / "aerial-pass"
CHECKER = ROOT / "examples" / "checker" / "aerial-pass"
PARAMS = ["tolerance_xy=0.5", "map_crs=EPSG:25832"]
OUTLINE_RULES = ("JRC-12.4-BLOCK-OUTLINES-AGREE", "JRC-5.2.2-AOI-AGREES")


def _verdicts(doc: dict[str, Any]) -> dict[tuple[str, str], str]:
    return {(r["rule"], r["item"]): r["verdict"] for r in records(doc)}


def _with_aoi(tmp_path: Path) -> Path:
    """The example checker folder with an area of interest stated (the union of its blocks' bounds)."""
    if CHECKER.is_dir():
        folder = tmp_path / "checker"
        shutil.copytree(CHECKER, folder)
        path = folder / "checker.yaml"
    else:  # before the checker folders (the single-file form)
        folder = path = tmp_path / "checker.yaml"
        shutil.copy(CHECKER.with_suffix(".yaml"), path)
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    doc["area_of_interest"] = [
        [500000, 5400000],
        [519500, 5400000],
        [519500, 5418200],
        [500000, 5418200],
    ]
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return folder


def test_two_checks_of_one_delivery_object_equal_two_fresh_checks(tmp_path: Path) -> None:
    checker = _with_aoi(tmp_path)
    d = open_delivery(EXAMPLE)
    with_checker = check_with(d, "jrc-v3", checker=checker, date=DATE)
    again = check_with(d, "jrc-v3", params=PARAMS, date=DATE)  # the same object, no checker now
    fresh_with = check_with(open_delivery(EXAMPLE), "jrc-v3", checker=checker, date=DATE)
    fresh = check_with(open_delivery(EXAMPLE), "jrc-v3", params=PARAMS, date=DATE)
    assert again.document["checker"] is None
    got, want = _verdicts(again.document), _verdicts(fresh.document)
    # the two rules that read the checker's outlines: not applicable without a checker (no outline stated)
    for rule in OUTLINE_RULES:
        assert want[(rule, "D-2026-014")] == "not_applicable", rule
        assert got[(rule, "D-2026-014")] == "not_applicable", rule
    assert got == want
    assert _verdicts(with_checker.document) == _verdicts(fresh_with.document)
    assert again.document["verdict"] == fresh.document["verdict"]


def test_loading_and_binding_a_checker_leaves_the_delivery_untouched(tmp_path: Path) -> None:
    d = open_delivery(EXAMPLE)
    before = dict(vars(d))
    load_checker(_with_aoi(tmp_path), delivery=d)
    assert set(vars(d)) == set(before)
    assert all(vars(d)[k] is v for k, v in before.items() if k not in ("_tables", "_sha"))
    assert not hasattr(d, "stated_outlines")
