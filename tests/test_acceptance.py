"""Acceptance (JRC §12.3 image share, §12.8 block share): the one implementation the evaluator calls.

§12.7 block verdicts are profile rules (JRC-12.7-RMSEX/-RMSEY); their end-to-end behaviour is in
tests/test_verdict_regressions.py.
"""

from __future__ import annotations

import pytest

from orthospec.errors import MeasureError
from orthospec.measures.acceptance import image_delivery_verdict, project_verdict


def test_project_verdict_thresholds():
    # 40 blocks, 4 checked (10%), 0 fail -> accepted, sample sufficient
    ok = project_verdict(40, [True] * 4)
    assert ok.sample_sufficient and not ok.return_all and ok.redeliver == ()
    # 20 checked, 1 fails = 5% -> not "more than 5%": only that block is redelivered
    v = project_verdict(100, [True] * 19 + [False], checked_ids=[f"B{i}" for i in range(20)])
    assert v.failed_fraction == pytest.approx(0.05) and not v.return_all
    assert v.redeliver == ("B19",) and "corrected and redelivered" in v.reason
    # 2 of 20 fail = 10% -> all products returned
    v2 = project_verdict(100, [True] * 18 + [False] * 2)
    assert v2.return_all and "all products returned" in v2.reason
    # 3 of 40 checked: 7.5% < 10% sample
    v3 = project_verdict(40, [True] * 3)
    assert not v3.sample_sufficient and "below the minimum" in v3.reason


def test_project_space_resection_any_failure_returns():
    v = project_verdict(100, [True] * 99 + [False], space_resection=True)
    assert v.failed_fraction < 0.05 and v.return_all and "space resection" in v.reason


def test_project_bad_input():
    with pytest.raises(MeasureError):
        project_verdict(2, [True, True, True])
    with pytest.raises(MeasureError, match="no block"):
        project_verdict(2, [])


def test_image_delivery_verdict():
    v = image_delivery_verdict(200, [False] * 19 + [True], sampled_ids=[f"I{i}" for i in range(20)])
    assert v.sample_sufficient and not v.return_delivery and v.reprocess == ("I19",)
    v2 = image_delivery_verdict(200, [False] * 18 + [True, True])
    assert v2.return_delivery and "entire delivery" in v2.reason
    v3 = image_delivery_verdict(200, [False] * 19)
    assert not v3.sample_sufficient and v3.sampled_fraction == pytest.approx(0.095)
    with pytest.raises(MeasureError):
        image_delivery_verdict(10, [])


@pytest.mark.parametrize(
    ("n", "failed", "returned"),
    [
        (30, 1, False),  # 1/30 = 3.3 % <= 5 %: the failing image is reprocessed
        (30, 2, True),  # 2/30 = 6.7 % > 5 % (§12.3 "more than 5%"): the delivery is returned
        (20, 1, False),  # exactly 5 % is not "more than 5%"
        (19, 1, True),  # 1/19 = 5.3 %: one image already returns a small delivery (the text, kept)
    ],
)
def test_image_share_follows_section_12_3(n, failed, returned):
    v = image_delivery_verdict(n, [True] * failed + [False] * (n - failed))
    assert v.failed_fraction == pytest.approx(failed / n)
    assert v.return_delivery is returned


def test_image_share_may_is_a_parameter_with_return_as_default():
    """§12.3 "may be returned": the default returns; the checker's discretion keeps the delivery."""
    fails = [True, True] + [False] * 28
    assert image_delivery_verdict(30, fails).return_delivery
    kept = image_delivery_verdict(30, fails, returns=False)
    assert not kept.return_delivery and "discretion" in kept.reason and kept.reprocess == ("0", "1")
