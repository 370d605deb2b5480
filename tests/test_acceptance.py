"""Acceptance: block verdicts (X, Y, Z independently, marginal), project and delivery rules."""

from __future__ import annotations

import numpy as np
import pytest

from orthospec.errors import MeasureError
from orthospec.measures.acceptance import (
    block_verdicts,
    image_delivery_verdict,
    project_verdict,
)


@pytest.mark.parametrize(
    ("rx", "ry", "passed", "marginal"),
    [
        (1.0, 1.0, True, False),
        (2.5, 1.0, True, True),      # exactly the tolerance passes ("exceed" fails)
        (2.6, 1.0, False, True),     # just above: fails, marginal
        (1.0, 3.0, False, False),    # Y alone rejects the block
        (2.3, 0.5, True, True),      # 0.2 below a 2.5 tolerance, margin 10% = 0.25
        (2.2, 0.5, True, False),
    ],
)
def test_block_verdict_table(rx, ry, passed, marginal):
    v = block_verdicts([rx], [ry], tolerance_xy=2.5, block_ids=["B1"])
    assert bool(v.passed[0]) is passed
    assert bool(v.marginal[0]) is marginal
    assert ("fail" in v.reasons[0]) is (not passed)
    assert ("marginal" in v.reasons[0]) is marginal


def test_block_verdicts_vectorised_with_dem_and_per_block_tolerance():
    rx = np.array([0.3, 0.3, 0.3, 0.9])
    ry = np.array([0.3, 0.3, 0.6, 0.3])
    rz = np.array([0.5, 1.2, 0.5, 0.5])
    v = block_verdicts(rx, ry, rz, tolerance_xy=[0.5, 0.5, 0.5, 1.0], tolerance_z=1.0,
                       block_ids=["A", "B", "C", "D"])
    assert v.passed.tolist() == [True, False, False, True]
    assert v.pass_z is not None and v.pass_z.tolist() == [True, False, True, True]
    assert v.failed_ids == ("B", "C")
    assert v.marginal_ids == ("D",)  # 0.9 within 10% of 1.0
    assert "RMSE_z 1.2 > 1" in v.reasons[1]


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        (([np.nan], [1.0]), {"tolerance_xy": 1.0, "block_ids": ["B7"]}, "rmse_x.*B7"),
        (([1.0], [1.0]), {"tolerance_xy": 0.0}, "positive"),
        (([1.0, 2.0], [1.0]), {"tolerance_xy": [1.0, 2.0, 3.0]}, "3 values for 2"),
        (([1.0], [1.0], [1.0]), {"tolerance_xy": 1.0}, "tolerance_z"),
        (([-1.0], [1.0]), {"tolerance_xy": 1.0}, "negative"),
    ],
)
def test_block_verdicts_bad_input(args, kwargs, match):
    with pytest.raises(MeasureError, match=match):
        block_verdicts(*args, **kwargs)


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
