"""specs/COVERAGE.md stays true (issue 26): the rules it lists under a JRC table read that table's data,
every checkable statement without a rule has its reason, the counts it states are those of the profile,
and its wording says where manual verdicts come from and how other profiles' quotes were verified."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "coverage_doc.py"
SEED = ROOT.parent / "shared" / "seeds" / "002_7421c4ca450e31c6.txt"
JRC = yaml.safe_load((ROOT / "specs" / "jrc-v3.yaml").read_text(encoding="utf-8"))


def _module() -> ModuleType:
    name = "orthospec_coverage_doc_t"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, SCRIPT)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]


def test_no_shipped_rule_over_claims_a_table() -> None:
    assert _module().claim_problems(JRC["rules"]) == []


def test_a_rule_citing_a_table_it_does_not_read_is_named() -> None:
    """The issue 26 over-claim: Table 2 "covered" by a rule reading the acquisition GSD and product GSD."""
    rule = {
        "id": "X-T2",
        "clause": {"table": 2},
        "measure": "images.acquisition_gsd",
        "level": "recommended",
        "requirement": {"op": "<=", "value": "manifest.product.gsd / 1.5"},
        "when": "manifest.sensor.type == 'aerial'",
    }
    got = _module().claim_problems([rule])
    assert got == [
        "X-T2 cites Table 2 but reads none of its data (images.acquisition_gsd, manifest.product.gsd)"
    ]
    reading = {**rule, "id": "X-T2b", "measure": "images.scan_resolution"}
    assert _module().claim_problems([reading]) == []
    assert _module().claim_problems([{**rule, "id": "X-M", "manual": True}]) == []


def test_check_fails_on_an_over_claim(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mod = _module()
    bad = [
        *JRC["rules"],
        {
            "id": "X-T2",
            "title": "t",
            "quote": "q",
            "clause": {"section": "6.2.1", "table": 2},
            "measure": "images.gsd",
            "level": "recommended",
            "consequence": "warn",
            "requirement": {"op": "<=", "value": 1},
        },
    ]
    monkeypatch.setattr(
        mod,
        "_load",
        lambda name: (
            {**JRC, "rules": bad}
            if name == "jrc-v3"
            else yaml.safe_load((ROOT / "specs" / f"{name}.yaml").read_text(encoding="utf-8"))
        ),
    )
    assert mod.main(["--check"]) == 1


def test_every_statement_without_a_rule_has_a_reason_and_every_encoding_rule_exists() -> None:
    ids = {r["id"] for r in JRC["rules"]}
    for sec, _table, words, level, encoded, why in _module().UNCODED:
        assert level in ("mandatory", "recommended"), words
        if encoded:
            assert set(encoded) & ids, (sec, words, encoded)
        else:
            assert len(why) > 40, (sec, words)


@pytest.mark.skipif(not SEED.is_file(), reason="the JRC seed is not beside the checkout")
def test_statements_without_a_rule_are_verbatim_in_the_guidelines() -> None:
    text = " ".join(SEED.read_text(encoding="utf-8").split())
    for sec, _t, words, *_ in _module().UNCODED:
        assert " ".join(words.split()) in text, (sec, words)


def test_counts_stated_are_the_profiles() -> None:
    mod = _module()
    c = mod.item_counts(JRC["rules"])
    text = (ROOT / "specs" / "COVERAGE.md").read_text(encoding="utf-8")
    assert (
        f"Checkable items of the guidelines: {c['items']} - {c['automatic']} automatic, {c['manual']} manual, "
        f"{c['none']} without a rule ({c['mandatory_none']} of them mandatory"
    ) in text
    assert c["automatic"] + c["manual"] + c["none"] == c["items"]
    listed = text.split("### Checkable statements without a rule")[1].split("###")[0]
    assert listed.count("\n| §") == c["none"]
    out = subprocess.run(
        [sys.executable, str(SCRIPT), "--counts"], capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout) == c


def test_counts_of_an_older_profile_put_items_now_encoded_in_none(tmp_path: Path) -> None:
    """The before/after comparison: without the rules that encode them, those statements count as none."""
    mod = _module()
    encoded = {i for *_, enc, why in mod.UNCODED if not why for i in enc[:1]}
    older = [r for r in JRC["rules"] if r["id"] not in encoded]
    now, before = mod.item_counts(JRC["rules"]), mod.item_counts(older)
    assert before["none"] > now["none"] and before["mandatory_none"] > now["mandatory_none"]


def test_wording_is_current() -> None:
    text = (ROOT / "specs" / "COVERAGE.md").read_text(encoding="utf-8")
    assert "signed in the delivery's manual_checks table" not in text
    assert "without a signed row in manual_checks" not in text
    asprs = text.split("### `asprs-2023`")[1].split("### ")[0]
    assert "verified against public copies" not in asprs and "unverified" in asprs
    for r in JRC["rules"]:
        if not r.get("manual"):
            assert not re.search(
                rf"\| {re.escape(r['id'])} \| [^|]*\| §",
                text.split("deliberately left manual")[1].split("###")[0],
            ), r["id"]
