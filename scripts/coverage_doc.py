"""Generate specs/COVERAGE.md: which rules encode each part of the JRC guidelines (and the others).

The profile is the product's knowledge, so an auditor needs to see, section by section and table
by table, which requirements became automatic rules, which were deliberately left to a human
(``manual: true``) and which statements were judged informational and not encoded (listed here
with the reason, so nothing in the standard silently disappears).

Usage::

    python scripts/coverage_doc.py            # write specs/COVERAGE.md
    python scripts/coverage_doc.py --check    # exit 1 if the committed file is out of date

Reads only the profile YAML files (no registry), so the output depends on nothing but the
profiles and this script: deterministic.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs"
OUT = SPECS / "COVERAGE.md"

#: JRC EUR 23638 EN headings (section -> title), in document order.
JRC_SECTIONS: list[tuple[str, str]] = [
    ("2.3", "Quality audits"), ("2.4", "Quality control records"), ("2.5", "QA phases"),
    ("3.1", "GSD"), ("3.2", "Radiometric resolution"), ("3.3", "Spectral resolution"),
    ("3.4", "Temporal resolution"), ("4.2", "Calibration of film cameras"),
    ("4.3", "Calibration of digital airborne cameras"), ("5.2.1", "Flying height"),
    ("5.2.2", "Image overlaps"), ("5.2.3", "Scale variation"), ("5.2.4", "Roll and drift"),
    ("5.2.5", "Flying conditions"), ("5.2.6", "Auxiliary orientation equipment (GPS INS/IMU)"),
    ("5.2.7", "Sensor configuration and settings"), ("5.3", "Input data"),
    ("6.2", "Film scanning"), ("6.2.1", "Scanning resolution"), ("6.2.2", "Image scanning QA"),
    ("6.3", "Image radiometric quality assurance"), ("6.4", "Input data"),
    ("6.5", "Image compression"), ("7.1", "Accuracy requirements"),
    ("7.2", "Selection of GCPs and CPs"), ("7.3", "Documentation associated with ground reference data"),
    ("8.1", "Scope"), ("8.2", "Geo-reference"), ("8.3", "Orthorectification process"),
    ("8.4", "QCRs and quality audits for air-photo orthocorrection"),
    ("8.5", "Updating of zones covered by existing orthophotos"), ("9.1", "Introduction"),
    ("9.2", "Input data"), ("9.3", "Ground control requirements"),
    ("9.4", "Geometric correction process"),
    ("9.5", "QCRs and quality audits for satellite image rectification"),
    ("10.3", "Enhancement of spatial resolution"), ("10.4", "Preservation of spectral features"),
    ("10.5.1", "Geometric pre-processing"), ("10.5.2", "Radiometric pre-processing"),
    ("10.6", "Pan-sharpening algorithms"),
    ("11", "Mosaicking"), ("12.1", "Introduction"), ("12.2", "Thresholds and QC checks"),
    ("12.3", "Digital image delivery"), ("12.4", "Inputs to orthocorrection external quality check"),
    ("12.5", "Check point selection and distribution"),
    ("12.6", "External quality checking method for image accuracy"),
    ("12.7", "Result calculation - within block"), ("12.8", "Result calculation - project level"),
    ("Definitions", "Definitions"),
]

JRC_TABLES: dict[int, str] = {
    1: "Best practice for Input data quality assurance",
    2: "Indicative scanning resolutions for different photo scales",
    3: "Geometric QA for image scanning",
    4: "Flight configurations and recommended GCPs patterns",
    5: "Tolerances for ortho processing of airborne imagery",
    6: "QCR Production and Use for Aerial Ortho-images",
    7: "QCRs for Geometric Correction of Satellite Images",
    8: "Geometric Correction Procedure choice for HR,MR and LR images",
    9: "Specification for Satellite Image Rectification",
    10: "QCR Production and Auditing for Satellite Image Rectification",
    11: "Best practice and QC for the production of orthomosaics",
    12: "Inputs to External QC of orthoimages",
}

#: Statements read and deliberately NOT encoded as rules, with the reason (section, words, why).
NOT_ENCODED: list[tuple[str, str, str]] = [
    ("2.3", "\"Tightened\" audit checks will follow an audit trail for suspect products or regions",
     "Audit regime, not a property of a delivery; carried as `audit:` metadata on the rules."),
    ("3.1", "generally halving the GSD size will increase the cost of a project 2-4 times",
     "Planning information."),
    ("3.3", "the final choice should be justified by the scope of the application",
     "Tender design decision, checked at tender evaluation, not on a delivery."),
    ("3.4", "Defining the window for the acquisition",
     "Tender design decision; an acquisition window fixed by a tender is a tender rule."),
    ("5.2.5", "(optimal 40-60)", "Advice on the optimum, the limit (30 deg) is encoded."),
    ("6.2.2", "Plot residuals for row and column on a control chart",
     "Form of the scanner QCR; the numeric results are encoded (Table 3 rules)."),
    ("7.1", "GCPs should ideally be determined from field survey",
     "Preference among sources; the source is recorded (JRC-7.3-GCP-SOURCE) and map-derived "
     "control gets its stricter factor (JRC-7.1-MAP-CONTROL-5X)."),
    ("8.1", "Tolerances are as stated in the relevant ITT",
     "Realised as the required parameter tolerance_xy."),
    ("8.5", "final acceptance will be made by applying the external quality control guidelines",
     "Chapter 12 rules apply to update projects unchanged."),
    ("7.3", "point identifier (unique to project)",
     "Unique within each table by the delivery convention (a duplicate id is refused, exit 2); "
     "uniqueness across the GCP and check point tables is not checked (no cross-table measure yet)."),
    ("7.3", "Other remarks", "Free text, no criterion; a `remarks` column would only be displayed."),
    ("9.2", "Figure 2. Influence of off-nadir angle and DEM accuracy",
     "The figure's relation dx = dh x tan(angle) is JRC-9.2-DEM-OFF-NADIR (manual until a "
     "scenes.dem_displacement measure exists: the rule grammar has no tangent)."),
    ("9.3", "The requirements of the ground reference data described in Chapter 7 apply also",
     "The Chapter 7 rules have no sensor condition, so they apply to satellite deliveries."),
    ("9.4", "it is preferred to deliver separate RPC files for each standard image forming the strip",
     "Preference without a testable condition (\"large\" off-nadir angles undefined)."),
    ("9.5", "It is strongly recommended that a paper *pro-forma* designed to record all the "
     "information listed above is devised by the contractor",
     "The scenes table is the electronic equivalent; the paper form itself is not checkable."),
    ("10.6", "There are many pan-sharpening algorithms available today in commercial packages.",
     "Descriptive list of algorithms."),
    ("12.1", "The radiometric quality check of the orthoimages will be similar to that applied "
     "for the images (see 6.3)", "The §6.3 rules are image-scope and run on the orthoimages."),
    ("12.2", "Additional indexes such as the mean error and the error standard deviation can be used",
     "Reported in the QCR details (checkpoints.mean_x/std_x ...), no pass/fail criterion."),
    ("12.3", "imagery failing the specification on one or more of the tests may be required to be "
     "re-processed", "This is the reject_item consequence of the image rules."),
    ("12.4", "Hardcopy and softcopy (ASCII, Tab delimited) or GIS layers.",
     "Table 12 GCP/check point file format: the convention's CSV tables are the softcopy (the reader "
     "refuses malformed files with file:row:column); the hardcopy is outside the delivery."),
    ("12.6", "The recommended output is a report showing an analysis of the results",
     "orthospec's QCR and report are that output."),
    ("12.7", "further investigations may be necessary to increase confidence in the result should "
     "the final result be marginal", "No definition of \"marginal\"; auditor's decision."),
    ("12.8", "that fail will be examined by the contractor, corrected, and redelivered",
     "This is the reject_block consequence."),
]

OTHER_PROFILES = ["usgs-insitu", "ceos-edge", "passini-jacobsen", "fgdc-nssda-1998", "asprs-2023"]


def _load(name: str) -> dict[str, Any]:
    return yaml.safe_load((SPECS / f"{name}.yaml").read_text(encoding="utf-8"))


def _kind(rule: dict[str, Any]) -> str:
    return "manual" if rule.get("manual") else "auto"


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _rule_row(rule: dict[str, Any]) -> str:
    req = rule.get("requirement") or {}
    op = req.get("op", "")
    if op == "between":
        thr = f"between {req.get('min')} and {req.get('max')}"
    elif op == "in":
        thr = f"in {req.get('values')}"
    elif op in ("present", "true", "false"):
        thr = op
    else:
        thr = f"{op} {req.get('value')}"
    unit = req.get("unit")
    if unit and unit != "1" and op not in ("present", "true", "false", "in"):
        thr += f" {unit}"
    what = "manual check" if rule.get("manual") else f"`{rule['measure']}` {thr}"
    return (f"| {rule['id']} | {_cell(rule['title'])} | {what} | {rule['level']} | "
            f"{rule['consequence']} |")


def _section_of(rule: dict[str, Any]) -> str:
    return str((rule.get("clause") or {}).get("section"))


def render() -> str:
    """The full COVERAGE.md text."""
    jrc = _load("jrc-v3")
    rules: list[dict[str, Any]] = jrc["rules"]
    out: list[str] = []
    add = out.append
    n_manual = sum(1 for r in rules if r.get("manual"))
    n_mand = sum(1 for r in rules if r["level"] == "mandatory")
    add("# Coverage of the source documents by the shipped profiles")
    add("")
    add("Generated by `scripts/coverage_doc.py` from the profile YAML - do not edit by hand "
        "(`make coverage`; a test fails when this file is out of date).")
    add("")
    add(f"## JRC Guidelines Issue 3.0 (EUR 23638 EN) - profile `jrc-v3` {jrc['version']}")
    add("")
    add(f"{len(rules)} rules: {len(rules) - n_manual} automatic, {n_manual} manual "
        f"(signed in the delivery's manual_checks table); {n_mand} mandatory, "
        f"{len(rules) - n_mand} recommended.")
    add("")
    add("### By section")
    add("")
    known = {s for s, _ in JRC_SECTIONS}
    for sec, title in JRC_SECTIONS:
        these = [r for r in rules if _section_of(r) == sec]
        skipped = [n for n in NOT_ENCODED if n[0] == sec]
        add(f"#### §{sec} {title}")
        add("")
        if these:
            add("| rule | title | measure / check | level | consequence |")
            add("|---|---|---|---|---|")
            for r in these:
                add(_rule_row(r))
            add("")
        if skipped:
            for _, words, why in skipped:
                add(f"- Not encoded: \"{_cell(words)}\" - {why}")
            add("")
        if not these and not skipped:
            add("No checkable requirement (descriptive text).")
            add("")
    stray = sorted({_section_of(r) for r in rules} - known)
    if stray:
        add(f"Rules citing sections not in the heading list: {', '.join(stray)}")
        add("")
    add("### By table")
    add("")
    add("| table | title | rules (automatic) | rules (manual) |")
    add("|---|---|---|---|")
    for num, title in JRC_TABLES.items():
        these = [r for r in rules if str((r.get("clause") or {}).get("table")) == str(num)]
        audit = [r for r in rules if str((r.get("audit") or {}).get("table")) == str(num)
                 and r not in these]
        auto = ", ".join(r["id"] for r in these if not r.get("manual")) or "-"
        manual = ", ".join(r["id"] for r in these if r.get("manual")) or "-"
        if audit:
            auto += f" (and as `audit:` metadata on {len(audit)} more rules)"
        add(f"| {num} | {title} | {auto} | {manual} |")
    add("")
    add("### Requirements deliberately left manual")
    add("")
    add("Visual or procedural requirements no program can judge. Each is a `manual: true` rule "
        "reading `manual.<rule-id>`; without a signed row in manual_checks its verdict is "
        "`missing` and the report lists it as still to be signed.")
    add("")
    add("| rule | section | requirement | level |")
    add("|---|---|---|---|")
    for r in rules:
        if r.get("manual"):
            add(f"| {r['id']} | §{_section_of(r)} | {_cell(r['title'])} | {r['level']} |")
    add("")
    add("### Statements read and not encoded")
    add("")
    add("| section | words | why |")
    add("|---|---|---|")
    for sec, words, why in NOT_ENCODED:
        add(f"| §{sec} | {_cell(words)} | {_cell(why)} |")
    add("")
    add("## Other profiles")
    add("")
    for name in OTHER_PROFILES:
        prof = _load(name)
        src = prof["source"]
        add(f"### `{prof['id']}` {prof['version']} - {_cell(prof['title'])}")
        add("")
        add(f"Source: {_cell(src['title'])} ({src.get('identifier') or ''}); "
            f"quotes {'from seed ' + src['seed'] if src.get('seed') else 'verified against public copies (see notes)'}.")
        add("")
        add("| rule | title | measure / check | level | consequence |")
        add("|---|---|---|---|---|")
        for r in prof["rules"]:
            add(_rule_row(r))
        add("")
    return "\n".join(out).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="fail if specs/COVERAGE.md is out of date")
    args = ap.parse_args(argv)
    text = render()
    if args.check:
        current = OUT.read_text(encoding="utf-8") if OUT.exists() else ""
        if current != text:
            print(f"{OUT.relative_to(ROOT)} is out of date: run python scripts/coverage_doc.py",
                  file=sys.stderr)
            return 1
        return 0
    OUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
