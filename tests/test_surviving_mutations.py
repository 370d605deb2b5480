"""Tests for the two planted bugs that survived the relevant tests in the issue 28 review.

1. A granted waiver that covers every item of its rule (``items: ["*"]``, or no ``items`` at all,
   which means the same) must waive every waivable item of that rule and nothing else; before, a
   ``_match`` that matched nothing for ``*`` passed every test (the only ``*`` waiver tested was on
   a rule in `error`, whose items are never waivable anyway).
2. JRC §12.8 rounds: a re-check of older content (content A, then B, then A again) belongs to A's
   round (1), not the latest round (2); before, only A, B, B was tested, whose re-check is round 2
   either way.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from tests.checking import check_with, write_checker
from tests.checking import records as all_records

from orthospec.ledger.history import DELIVERY, RECHECK, REDELIVERY, rounds_of

#: two images, both over the mini profile's 3 deg roll limit (mandatory R-ROLL), one within it
_TWO_BAD_ROLLS = ("image_id,file,block,roll,flying_height,std_dn\n"
                  "I1,a.tif,B1,0.5,1000,30\nI2,b.tif,B1,4.5,1000,30\nI3,c.tif,B2,4,1100,30\n")
_CHECKER = """\
orthospec_checker: 1
checker: {name: Eva External, role: external QC}
delivery: {id: D1}
parameters: {tolerance_xy: {value: 0.5, unit: m}}
manual_checks:
  - {check: R-VIS, item: "*", date: 2026-01-02, verdict: pass}
"""


def _verdicts(doc: dict[str, Any], rule: str) -> dict[str, str]:
    return {r["item"]: r["verdict"] for r in all_records(doc) if r["rule"] == rule}


@pytest.mark.parametrize("items", ['items: ["*"], ', "", "items: [I2, I3], "],
                         ids=["star", "items-omitted", "every-item-listed"])
def test_a_waiver_of_every_item_waives_every_failing_item(
    make_delivery, mini_profile, tmp_path: Path, items: str
) -> None:
    root = make_delivery(images=_TWO_BAD_ROLLS)
    plain = check_with(
        root, mini_profile, checker=write_checker(tmp_path, _CHECKER, "plain.yaml")
    ).document
    assert _verdicts(plain, "R-ROLL") == {"I1": "pass", "I2": "fail", "I3": "fail"}
    assert plain["verdict"] == "rejected"

    waiver = (
        f"waivers:\n  - {{rule: R-ROLL, {items}justification: ridge turbulence, approver: Eva}}\n"
    )
    doc = check_with(
        root, mini_profile, checker=write_checker(tmp_path, _CHECKER + waiver)
    ).document
    assert _verdicts(doc, "R-ROLL") == {"I1": "pass", "I2": "waived", "I3": "waived"}
    waived = [r for r in all_records(doc) if r["verdict"] == "waived"]
    assert {r["waived_verdict"] for r in waived} == {"fail"}
    assert {r["rule"] for r in waived} == {"R-ROLL"}  # no other rule's items
    assert doc["waivers_unused"] == []
    assert doc["verdict"] == "accepted"


def test_a_recheck_of_older_content_keeps_that_contents_round() -> None:
    runs = [("P", "A"), ("P", "B"), ("P", "A"), ("P", "B"), ("P", "C"), ("Q", "A")]
    assert rounds_of(runs) == [
        (DELIVERY, 1),
        (REDELIVERY, 2),
        (RECHECK, 1),
        (RECHECK, 2),
        (REDELIVERY, 3),
        (DELIVERY, 1),
    ]
