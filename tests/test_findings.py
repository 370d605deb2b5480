"""Findings: measured against required, in consequence order, one root cause one finding."""

from __future__ import annotations

from typing import Any

from orthospec.reports.findings import (
    clean_text,
    condition_prose,
    findings,
    not_applicable_summary,
    stated,
)


def rec(
    rule: str,
    item: str,
    verdict: str,
    value: Any = None,
    *,
    op: str = "<=",
    req: Any = 0.5,
    unit: str = "m",
    consequence: str = "warn",
    message: str = "",
    title: str = "T",
) -> dict[str, Any]:
    return {
        "rule": rule,
        "item": item,
        "verdict": verdict,
        "title": title,
        "consequence": consequence,
        "clause": {"document": "JRC", "section": "12.7"},
        "measured": {"value": value, "unit": unit},
        "requirement": {"op": op, "value": req, "unit": unit},
        "message": message,
        "level": "mandatory",
    }


def test_stated_never_reads_equal_to_the_requirement() -> None:
    assert stated(rec("R", "B02", "fail", 0.640523)) == "0.641 m > 0.5 m"
    assert stated(rec("R", "B02", "fail", 1.0004, req=1.0)) == "1.0004 m > 1 m"
    assert (
        stated(
            rec("R", "I1", "warn", 3.72, op="between", req=None)
            | {
                "requirement": {"op": "between", "min": -3.0, "max": 3.0, "unit": "deg"},
                "measured": {"value": 3.72, "unit": "deg"},
            }
        )
        == "3.72 deg outside [-3, 3] deg"
    )


def test_order_by_consequence_then_missing_errors_warnings() -> None:
    recs = [
        rec("W", "I1", "warn", 0.6),
        rec("E", "I2", "error", message="boom"),
        rec("M", "I3", "missing", message="no value"),
        rec("RI", "I4", "fail", 0.7, consequence="reject_item"),
        rec("RB", "B1", "fail", 0.8, consequence="reject_block"),
        rec("RD", "D1", "fail", 0.9, consequence="return_delivery"),
    ]
    assert [f.rule for f in findings(recs)] == ["RD", "RB", "RI", "M", "E", "W"]


def test_one_missing_file_is_one_finding_naming_every_check() -> None:
    msg = "images/F03.tif: listed in tables/images.csv but not found in the delivery"
    recs = [rec(f"R{i}", "F03", "error", message=msg) for i in range(9)]
    recs.append(
        rec("READ", "F03", "fail", False, op="true", consequence="reject_item", message=msg)
    )
    found = findings(recs)
    assert len(found) == 1
    f = found[0]
    assert (
        f.rule == "READ"
        and f.label == "rejects an item"
        and len(f.rules) == 10
        and f.n_records == 10
    )


def test_not_applicable_is_summarised_per_condition_in_words() -> None:
    recs = [
        rec(
            f"S{i}",
            f"I{j}",
            "not_applicable",
            message="not applicable: manifest.sensor.type == 'satellite' is false for this delivery",
        )
        for i in range(3)
        for j in range(4)
    ]
    [g] = not_applicable_summary(recs)
    assert g["records"] == 12 and g["rules"] == ["S0", "S1", "S2"]
    assert g["prose"] == "applies only when the sensor type is 'satellite'"
    assert condition_prose("manifest.tables.dem != null") == "a dem table is given"


def test_terminal_escapes_are_stripped() -> None:
    assert clean_text("a\x1b[31mb\x1b]8;;http://x\x07c\x07d") == "abcd"
