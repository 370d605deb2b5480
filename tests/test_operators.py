"""Requirement operators (orthospec.profile.operators): comparison, missing-value policy and wording in
one registered object per op; the annex and the QCR word a requirement with the same function.

Expected verdicts are worked by hand from the operator's definition (ARCHITECTURE.md "Spec profile
format" and "Verdict guarantees": nothing unmeasured passes, a non-finite threshold is an error).
"""

from __future__ import annotations

import math
import subprocess
import sys
import typing
from pathlib import Path

import numpy as np
import pytest

from orthospec import verdicts as V
from orthospec.profile.models import Op, Requirement
from orthospec.profile.operators import OPERATORS, Thresholds, operator
from orthospec.profile.wording import requirement_text

ROOT = Path(__file__).resolve().parents[1]
NAN, INF = math.nan, math.inf


def verdicts(op: str, measured: list, fail: str = V.FAIL, **thr: object) -> list[str]:
    return (
        operator(op)
        .decide(np.array(measured, dtype=object), Thresholds(**thr))
        .verdicts(fail)
        .tolist()
    )


def test_every_profile_op_is_registered_once() -> None:
    assert set(OPERATORS) == set(typing.get_args(Op))
    with pytest.raises(KeyError, match="unknown requirement operator"):
        operator("~=")


@pytest.mark.parametrize(
    ("op", "expected"),
    [
        # measured 0.3, 0.5 (the bound), 0.50001, NaN, None, "abc" against 0.5
        ("<", ["pass", "fail", "fail", "missing", "missing", "missing"]),
        ("<=", ["pass", "pass", "fail", "missing", "missing", "missing"]),
        (">", ["fail", "fail", "pass", "missing", "missing", "missing"]),
        (">=", ["fail", "pass", "pass", "missing", "missing", "missing"]),
    ],
)
def test_order_ops_bound_and_missing_values(op: str, expected: list[str]) -> None:
    assert verdicts(op, [0.3, 0.5, 0.50001, NAN, None, "abc"], value=0.5) == expected


def test_thresholds_per_item_nan_is_missing_inf_is_error() -> None:
    # item 2's threshold could not be computed (NaN), item 3's is not finite
    got = verdicts("<=", [1.0, 1.0, 1.0, 3.0], value=np.array([2.0, NAN, INF, 2.0]))
    assert got == ["pass", "missing", "error", "fail"]
    # a missing measured value wins over a broken threshold: the item was not measured at all
    assert verdicts("<=", [None], value=INF) == ["missing"]
    # a recommended rule's failure is a warning; undecided items stay undecided
    assert verdicts("<=", [3.0, NAN], fail=V.WARN, value=2.0) == ["warn", "missing"]


def test_codes_are_the_verdict_codes() -> None:
    d = operator("<").decide(np.array([1.0, 3.0, NAN]), Thresholds(value=2.0))
    assert d.codes().tolist() == [V.CODE["pass"], V.CODE["fail"], V.CODE["missing"]]
    assert d.codes().dtype == np.int8


def test_equality_numbers_within_isclose_and_text_exactly() -> None:
    # numpy.isclose: |a - b| <= 1e-8 + 1e-5 * |b|
    assert verdicts("==", [0.0, 1e-9, 0.1, NAN], value=0) == ["pass", "pass", "fail", "missing"]
    assert verdicts("!=", [0.0, 0.1], value=0) == ["fail", "pass"]
    assert verdicts("==", ["GTiff", "COG", "gtiff", None, ""], value="GTiff") == [
        "pass",
        "fail",
        "fail",
        "missing",
        "missing",
    ]
    assert verdicts("!=", ["GTiff", "COG", None], value="GTiff") == ["fail", "pass", "missing"]


def test_between_inclusive_exclusive_and_open_sides() -> None:
    m = [10.0, 20.0, 9.999, 20.001, 15.0, NAN]
    assert verdicts("between", m, min=10, max=20) == [
        "pass",
        "pass",
        "fail",
        "fail",
        "pass",
        "missing",
    ]
    assert verdicts("between", m, min=10, max=20, min_inclusive=False, max_inclusive=False) == [
        "fail",
        "fail",
        "fail",
        "fail",
        "pass",
        "missing",
    ]
    assert verdicts("between", m, min=10, max=20, min_inclusive=True, max_inclusive=False) == [
        "pass",
        "fail",
        "fail",
        "fail",
        "pass",
        "missing",
    ]
    # only a maximum: no lower bound at all (an open side is not an infinite threshold)
    assert verdicts("between", [-1e300, 3.0, 3.1], max=3) == ["pass", "pass", "fail"]
    assert verdicts("between", [1e300, 3.0, 2.9], min=3) == ["pass", "pass", "fail"]
    # a given bound that is NaN or infinite: missing / error
    assert verdicts("between", [1.0], min=NAN, max=2) == ["missing"]
    assert verdicts("between", [1.0], min=0, max=INF) == ["error"]


def test_in_with_strings_and_numbers() -> None:
    assert verdicts("in", ["aerial", "satellite", "Aerial", "", None], values=["aerial"]) == [
        "pass",
        "fail",
        "fail",
        "missing",
        "missing",
    ]
    assert verdicts("in", ["GTiff", "COG", "PNG"], values=["GTiff", "COG"]) == [
        "pass",
        "pass",
        "fail",
    ]
    assert verdicts("in", [8, 11, 16.0, NAN], values=[8, 16]) == ["pass", "fail", "pass", "missing"]


def test_present_missing_value_is_the_failure() -> None:
    assert operator("present").missing_value == V.FAIL
    assert verdicts("present", [None, "", "  ", "x", NAN, 0, False]) == [
        "fail",
        "fail",
        "fail",
        "pass",
        "fail",
        "pass",
        "pass",
    ]
    assert operator("present").decide(np.array([1.0, NAN])).verdicts().tolist() == ["pass", "fail"]


def test_true_false_only_booleans() -> None:
    m = [True, False, np.True_, None, 1, "true", NAN]
    assert verdicts("true", m) == ["pass", "fail", "pass", "missing", "fail", "fail", "missing"]
    assert verdicts("false", m) == ["fail", "pass", "fail", "missing", "fail", "fail", "missing"]
    assert operator("true").decide(np.array([True, False])).verdicts().tolist() == ["pass", "fail"]


def test_policy_is_declared_on_every_operator() -> None:
    for name, op in OPERATORS.items():
        assert op.missing_value in V.VERDICTS and op.missing_value != V.PASS, name
        assert op.missing_threshold == V.MISSING and op.nonfinite_threshold == V.ERROR, name
    # hand-checked: no operator lets an unmeasured item pass
    for name in OPERATORS:
        thr = {"between": {"min": 0, "max": 1}, "in": {"values": [1]}}.get(name, {"value": 1})
        assert V.PASS not in verdicts(name, [None, NAN], **thr), name


@pytest.mark.parametrize(
    ("req", "resolved", "expected"),
    [
        (Requirement(op="<=", value="tolerance_xy", unit="m"), {"value": 2.5}, "≤ 2.5 m"),
        (Requirement(op="<=", value="tolerance_xy", unit="m"), {}, "≤ tolerance_xy"),
        (Requirement(op=">=", value=20, unit="1"), {}, "≥ 20"),
        (Requirement(op="<", value=5, unit="µm"), {}, "< 5 µm"),
        (Requirement(op=">", value=4), {}, "> 4"),
        (Requirement(op="==", value=0, unit="%"), {}, "= 0 %"),
        (Requirement(op="!=", value="GTiff"), {}, "≠ GTiff"),
        (Requirement(op="<=", value="t / 3", unit="m"), {"value": 0.5 / 3}, "≤ 0.166667 m"),
        (
            Requirement(op="between", min="cv_min", max="cv_max", unit="%"),
            {"min": 10.0, "max": 20.0},
            "between 10 % (incl.) and 20 % (incl.)",
        ),
        (
            Requirement(op="between", max=3, min_inclusive=False, max_inclusive=False, unit="deg"),
            {"min": -INF, "max": 3.0},
            "between −∞ (excl.) and 3 deg (excl.)",
        ),
        (Requirement(op="in", values=["aerial", True, 1.5]), {}, "one of aerial, true, 1.5"),
        (Requirement(op="present"), {}, "present"),
        (Requirement(op="true"), {}, "is true"),
        (Requirement(op="false"), {}, "is false"),
    ],
)
def test_wording(req: Requirement, resolved: dict, expected: str) -> None:
    assert requirement_text(req, resolved) == expected


def test_annex_and_qcr_state_every_jrc_requirement_the_same_way() -> None:
    """The annex of jrc-v3 (with the parameters of a run) and that run's qcr.json give the same text
    for each rule whose thresholds the parameters fix (the QCR words per-item thresholds from the
    delivery, which the annex cannot know, so rules reading delivery facts are left out)."""
    from orthospec.api import check
    from orthospec.profile.expr import parse
    from orthospec.profile.loader import load_profile
    from orthospec.qcr import all_records
    from orthospec.reports.annex import requirement_text as annex_text

    prof = load_profile(ROOT / "specs" / "jrc-v3.yaml")
    res = check(
        ROOT / "examples" / "deliveries" / "aerial-pass",
        prof,
        date="2026-11-21",
        params={"tolerance_xy": "0.5m", "tolerance_z": "1m", "map_crs": "EPSG:25832"},
    )
    in_force = res.document["profile"]["parameters"]
    params = {
        n: p.model_copy(update={"value": in_force[n]["value"]})
        if in_force.get(n, {}).get("value") is not None
        else p
        for n, p in prof.parameters.items()
    }
    texts: dict[str, set[str]] = {}
    for r in all_records(res.document):
        req = r.get("requirement") or {}
        # records whose threshold was computed (not a not-applicable rule's threshold as written)
        if all(not isinstance(req.get(k), str) for k in ("value", "min", "max")) and req.get(
            "text"
        ):
            texts.setdefault(r["rule"], set()).add(req["text"])
    compared = 0
    for rule in prof.rules:
        specs = [
            v
            for v in (rule.requirement.value, rule.requirement.min, rule.requirement.max)
            if isinstance(v, str)
        ]
        if any(not set(parse(s).names) <= set(params) for s in specs) or rule.id not in texts:
            continue
        want = annex_text(rule.requirement, params)
        assert want in texts[rule.id], (rule.id, want, texts[rule.id])
        compared += 1
    assert compared >= 100, compared  # most of jrc-v3's ~230 rules apply to an aerial delivery


def test_wording_imports_no_numpy() -> None:
    """`explain` and `spec validate` word requirements; numpy loads only when a comparison runs."""
    code = (
        "import sys; import orthospec.profile.wording, orthospec.profile.operators; "
        "print('numpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
