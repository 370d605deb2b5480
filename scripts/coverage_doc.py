"""Generate specs/COVERAGE.md: which rules encode each part of the JRC guidelines (and the others).

The profile is the product's knowledge, so an auditor needs to see, section by section and table
by table, which requirements became automatic rules, which were deliberately left to a human
(``manual: true``) and which statements were judged informational and not encoded (listed here
with the reason, so nothing in the standard silently disappears).

It also keeps the document true (issue 26): every checkable JRC item is counted as automatic,
manual or without a rule (:func:`item_counts`: the rules' distinct quotes plus :data:`UNCODED`, the
checkable statements no rule quotes, each with its reason), and a rule listed under a JRC table must
read some of that table's data (:data:`TABLE_DATA`; :func:`claim_problems` names any that does not,
and ``--check`` fails on them).

Usage::

    python scripts/coverage_doc.py            # write specs/COVERAGE.md
    python scripts/coverage_doc.py --check    # exit 1 if the committed file is out of date or over-claims
    python scripts/coverage_doc.py --counts [PROFILE.yaml]  # the JRC item counts of a jrc-v3 file (JSON)

Reads only the profile YAML files (no registry), so the output depends on nothing but the
profiles and this script: deterministic.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
SPECS = ROOT / "specs"
OUT = SPECS / "COVERAGE.md"

#: JRC EUR 23638 EN headings (section -> title), in document order.
JRC_SECTIONS: list[tuple[str, str]] = [
    ("2.3", "Quality audits"),
    ("2.4", "Quality control records"),
    ("2.5", "QA phases"),
    ("3.1", "GSD"),
    ("3.2", "Radiometric resolution"),
    ("3.3", "Spectral resolution"),
    ("3.4", "Temporal resolution"),
    ("4.2", "Calibration of film cameras"),
    ("4.3", "Calibration of digital airborne cameras"),
    ("5.2.1", "Flying height"),
    ("5.2.2", "Image overlaps"),
    ("5.2.3", "Scale variation"),
    ("5.2.4", "Roll and drift"),
    ("5.2.5", "Flying conditions"),
    ("5.2.6", "Auxiliary orientation equipment (GPS INS/IMU)"),
    ("5.2.7", "Sensor configuration and settings"),
    ("5.3", "Input data"),
    ("6.2", "Film scanning"),
    ("6.2.1", "Scanning resolution"),
    ("6.2.2", "Image scanning QA"),
    ("6.3", "Image radiometric quality assurance"),
    ("6.4", "Input data"),
    ("6.5", "Image compression"),
    ("7.1", "Accuracy requirements"),
    ("7.2", "Selection of GCPs and CPs"),
    ("7.3", "Documentation associated with ground reference data"),
    ("8.1", "Scope"),
    ("8.2", "Geo-reference"),
    ("8.3", "Orthorectification process"),
    ("8.4", "QCRs and quality audits for air-photo orthocorrection"),
    ("8.5", "Updating of zones covered by existing orthophotos"),
    ("9.1", "Introduction"),
    ("9.2", "Input data"),
    ("9.3", "Ground control requirements"),
    ("9.4", "Geometric correction process"),
    ("9.5", "QCRs and quality audits for satellite image rectification"),
    ("10.3", "Enhancement of spatial resolution"),
    ("10.4", "Preservation of spectral features"),
    ("10.5.1", "Geometric pre-processing"),
    ("10.5.2", "Radiometric pre-processing"),
    ("10.6", "Pan-sharpening algorithms"),
    ("11", "Mosaicking"),
    ("12.1", "Introduction"),
    ("12.2", "Thresholds and QC checks"),
    ("12.3", "Digital image delivery"),
    ("12.4", "Inputs to orthocorrection external quality check"),
    ("12.5", "Check point selection and distribution"),
    ("12.6", "External quality checking method for image accuracy"),
    ("12.7", "Result calculation - within block"),
    ("12.8", "Result calculation - project level"),
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
    (
        "2.3",
        '"Tightened" audit checks will follow an audit trail for suspect products or regions',
        "Audit regime, not a property of a delivery; carried as `audit:` metadata on the rules.",
    ),
    (
        "3.1",
        "generally halving the GSD size will increase the cost of a project 2-4 times",
        "Planning information.",
    ),
    (
        "3.3",
        "the final choice should be justified by the scope of the application",
        "Tender design decision, checked at tender evaluation, not on a delivery.",
    ),
    ("5.2.5", "(optimal 40-60)", "Advice on the optimum, the limit (30 deg) is encoded."),
    (
        "6.2.2",
        "Plot residuals for row and column on a control chart",
        "Form of the scanner QCR; the numeric results are encoded (Table 3 rules).",
    ),
    (
        "7.1",
        "GCPs should ideally be determined from field survey",
        "Preference among sources; the source is recorded (JRC-7.3-GCP-SOURCE) and map-derived "
        "control gets its stricter factor (JRC-7.1-MAP-CONTROL-5X).",
    ),
    (
        "8.1",
        "Tolerances are as stated in the relevant ITT",
        "Realised as the required parameter tolerance_xy.",
    ),
    (
        "8.5",
        "final acceptance will be made by applying the external quality control guidelines",
        "Chapter 12 rules apply to update projects unchanged.",
    ),
    (
        "7.3",
        "Other remarks",
        "Free text, no criterion; a `remarks` column would only be displayed.",
    ),
    (
        "9.2",
        "Figure 2. Influence of off-nadir angle and DEM accuracy",
        "The figure's relation dx = dh x tan(angle) is JRC-9.2-DEM-OFF-NADIR (view angle <= atan(tolerance / 3 "
        "/ DEM accuracy), from the scenes' Table 7 records).",
    ),
    (
        "9.3",
        "The requirements of the ground reference data described in Chapter 7 apply also",
        "The Chapter 7 rules have no sensor condition, so they apply to satellite deliveries.",
    ),
    (
        "9.4",
        "it is preferred to deliver separate RPC files for each standard image forming the strip",
        'Preference without a testable condition ("large" off-nadir angles undefined).',
    ),
    (
        "9.5",
        "It is strongly recommended that a paper *pro-forma* designed to record all the "
        "information listed above is devised by the contractor",
        "The scenes table is the electronic equivalent; the paper form itself is not checkable.",
    ),
    (
        "10.6",
        "There are many pan-sharpening algorithms available today in commercial packages.",
        "Descriptive list of algorithms.",
    ),
    (
        "12.1",
        "The radiometric quality check of the orthoimages will be similar to that applied "
        "for the images (see 6.3)",
        "The §6.3 rules are image-scope and run on the orthoimages.",
    ),
    (
        "12.2",
        "Additional indexes such as the mean error and the error standard deviation can be used",
        "Reported in the QCR details (checkpoints.mean_x/std_x ...), no pass/fail criterion.",
    ),
    (
        "12.3",
        "imagery failing the specification on one or more of the tests may be required to be "
        "re-processed",
        "This is the reject_item consequence of the image rules.",
    ),
    (
        "12.4",
        "Hardcopy and softcopy (ASCII, Tab delimited) or GIS layers.",
        "Table 12 GCP/check point file format: the convention's CSV tables are the softcopy (the reader "
        "refuses malformed files with file:row:column); the hardcopy is outside the delivery.",
    ),
    (
        "12.6",
        "The recommended output is a report showing an analysis of the results",
        "orthospec's QCR and report are that output.",
    ),
    (
        "12.7",
        "further investigations may be necessary to increase confidence in the result should "
        "the final result be marginal",
        'No definition of "marginal"; auditor\'s decision.',
    ),
    (
        "12.8",
        "that fail will be examined by the contractor, corrected, and redelivered",
        "This is the reject_block consequence.",
    ),
]

#: Checkable JRC statements that no rule quotes: (section, table, words (verbatim), level, rules that
#: now encode them (the item counts as theirs when any is in the profile), reason when none does).
#: Together with the rules' distinct quotes these are the checkable items :func:`item_counts` counts.
UNCODED: list[tuple[str, int | None, str, str, tuple[str, ...], str]] = [
    (
        "3.4",
        None,
        "Defining the window for the acquisition which can vary depending on the project's scope "
        "(e.g. leaf-on imagery)",
        "mandatory",
        ("JRC-3.4-ACQUISITION-WINDOW",),
        "",
    ),
    (
        "7.3",
        None,
        "point identifier (unique to project)",
        "mandatory",
        ("JRC-7.3-POINT-ID-UNIQUE",),
        "",
    ),
    (
        "7.1",
        None,
        "a digitization error (0.02mm at the map scale) must be allowed for",
        "mandatory",
        ("JRC-7.1-MAP-DIGITISATION",),
        "",
    ),
    (
        "12.7",
        None,
        "However, in the case of orthoimages created by space resection (either per image or per "
        "photogramme), each will be treated as a block.",
        "mandatory",
        ("JRC-12.7-SPACE-RESECTION-BLOCKS",),
        "",
    ),
    (
        "9.4",
        9,
        "linearity of the system (e.g. plus 2 per additional 100km ² of strip scene)",
        "recommended",
        ("JRC-T9-GCP-VHR-RPC-STRIP",),
        "",
    ),
    (
        "9.2",
        7,
        "Possibly use histograms/3D views to check for spikes/holes.",
        "recommended",
        ("JRC-9.2-T7-DEM-SPIKES", "JRC-9.2-T7-DEM-INTEGRITY"),
        "",
    ),
    (
        "9.4",
        9,
        "Distribution of GCPs should cover full AOI.",
        "recommended",
        ("JRC-T9-GCP-DISTRIBUTION",),
        "",
    ),
    (
        "5.2.7",
        None,
        "All bands (RGB,CIR or even PAN if pansharpening required) composite at same angle",
        "recommended",
        ("JRC-5.2.7-SENSOR-SETTINGS",),
        "",
    ),
    (
        "12.8",
        None,
        "Redelivery of products will be followed by a further independent check on a new sample",
        "mandatory",
        (),
        "Judged across checks, not on one: `orthospec sample --round R` draws the new sample of "
        "a redelivery and the ledger (`rounds_of`, keyed on content) records which round a check belongs to; "
        "a single check cannot know whether its sample is new. The auditor reads it in `orthospec history`.",
    ),
    (
        "2.5",
        None,
        "An auditor independent of the contractor will carry out external quality audits",
        "mandatory",
        (),
        "Who wrote the checker's file lies outside the delivery (the agency's contract names the auditor); the "
        "report names the checker and their role, and the contractor's manual_checks rows are never verdicts.",
    ),
    (
        "9.2",
        7,
        "Attention should be paid to datum references (mean sea level vs. ellipsoidal heights, for "
        "example)",
        "recommended",
        (),
        "The vertical datum of a DEM is not recorded by the convention and a "
        "GeoTIFF rarely carries it; the DEM QC record (scenes.dem_qc_result, §9.5) is where the contractor "
        "states it.",
    ),
    (
        "9.2",
        7,
        "The DEM should be of sufficient detail",
        "recommended",
        (),
        "No grid size is given for "
        "satellite work (Table 5's 5-20 x pixel is for air photos); the grid size is recorded "
        "(scenes.dem_grid_size, JRC-9.5 meta-database rules).",
    ),
    (
        "9.2",
        7,
        "Check corner and centre pixel values against heights on published maps.",
        "recommended",
        (),
        "Needs published map heights, which are outside the delivery (nothing outside it is read).",
    ),
    (
        "8.5",
        None,
        "the revision flight should be compatible with (although not necessarily identical to) the "
        "initial flight",
        "recommended",
        (),
        "The initial flight is not part of an update delivery; compatibility "
        "is a judgement without a criterion.",
    ),
    (
        "11",
        11,
        "Mosaic as much as possible only images acquired in a single collect (same conditions)",
        "recommended",
        (),
        '"as much as possible" gives no threshold; each image\'s acquisition date is '
        "measured (acquisition.date) and the result is judged by JRC-T11-RADIOMETRIC-BALANCE.",
    ),
    (
        "9.5",
        None,
        "corner co-ordinates and result of visual QC signed and dated by a supervisor",
        "recommended",
        (),
        "Corner co-ordinates are read from the rasters themselves (not a record to trust); the supervisor's "
        "signature is a ledger sign-off (`orthospec signoff`), recorded outside the delivery.",
    ),
    (
        "10.5.2",
        None,
        "The type of conversion to 8-bit format should be carefully considered.",
        "recommended",
        (),
        "A judgement with no criterion; the delivered bit depth is checked (§3.2, §6.3 rules).",
    ),
]

#: What each JRC table is about, as the names (tables, columns, measures; prefixes) a rule must read
#: for COVERAGE.md to list it under that table: a rule citing a table but reading none of its data
#: over-claims (issue 26: Table 2 "covered" by a rule that reads nothing of it). Manual rules read the
#: checker's verdict on the table's own item and are not held to this.
TABLE_DATA: dict[int, tuple[str, ...]] = {
    1: (
        "cameras.",
        "flights.",
        "images.exposure_",
        "images.flying_height",
        "derived.photo_coverage",
        "derived.area_of_interest_agrees",
        "derived.camera_agrees",
    ),
    2: ("images.scan_resolution", "tables.scanning_resolutions"),
    3: (
        "scanner_tests.",
        "scanner.",
        "interior_orientation.",
        "images.scan_resolution",
        "images.acquisition_gsd",
    ),
    4: ("gcps.", "gcp_pattern.", "aerotriangulation.configuration", "flights.gps_base_distance"),
    5: ("aerotriangulation.", "interior_orientation.", "dem.", "images.resampling"),
    6: (
        "qcr.",
        "manifest.documents.",
        "cameras.",
        "flights.",
        "scanner",
        "gcps.",
        "checkpoints.",
        "aerotriangulation.",
        "dem.",
        "images.",
    ),
    7: ("raster.", "scenes.", "dem.", "demfile."),
    8: ("scenes.", "derived.resolution_class"),
    9: (
        "scenes.",
        "scene.",
        "gcps.",
        "derived.master_images",
        "derived.is_master",
        "raster.pixel_size",
    ),
    10: ("qcr.", "scenes.", "gcps.", "manifest.documents."),
    11: ("mosaic.", "seamline.", "manifest.vectors.seamlines"),
    12: (
        "raster.",
        "derived.project_crs_agrees",
        "manifest.vectors.seamlines",
        "manifest.documents.gcp_report",
        "gcps.",
        "checkpoints.",
    ),
}

OTHER_PROFILES = ["usgs-insitu", "ceos-edge", "passini-jacobsen", "fgdc-nssda-1998", "asprs-2023"]
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)+")


def reads(rule: dict[str, Any]) -> set[str]:
    """The dotted names a rule reads: its measure and those of its requirement and `when`."""
    req = rule.get("requirement") or {}
    texts = [
        str(v) for v in (req.get("value"), req.get("min"), req.get("max")) if isinstance(v, str)
    ]
    texts.append(str(rule.get("when") or ""))
    out = {rule["measure"]}
    for t in texts:
        out |= {
            m
            for m in _NAME.findall(re.sub(r"'[^']*'|\"[^\"]*\"", "", t))
            if not m.startswith("manifest.sensor.")
        }
    return out


def claim_problems(rules: list[dict[str, Any]]) -> list[str]:
    """Rules listed under a JRC table that read none of that table's data."""
    out = []
    for r in rules:
        table = (r.get("clause") or {}).get("table")
        if table in (None, "") or r.get("manual"):
            continue
        want = TABLE_DATA.get(int(table), ())
        if not any(n.startswith(w) for n in reads(r) for w in want):
            out.append(
                f"{r['id']} cites Table {table} but reads none of its data ({', '.join(sorted(reads(r)))})"
            )
    return out


def _key(text: str) -> str:
    return " ".join(str(text).split()).lower()


def item_counts(rules: list[dict[str, Any]]) -> dict[str, Any]:
    """Checkable JRC items by kind: each distinct rule quote is an item (automatic when any of its rules
    is, else manual), and each :data:`UNCODED` statement no rule quotes is one too (its encoding rules'
    kind when the profile has them, else none)."""
    items: dict[str, dict[str, Any]] = {}
    for r in rules:
        it = items.setdefault(_key(r["quote"]), {"kinds": set(), "mandatory": False, "rules": []})
        it["kinds"].add(_kind(r))
        it["mandatory"] |= r["level"] == "mandatory"
        it["rules"].append(r["id"])
    by_id = {r["id"]: r for r in rules}
    none: list[tuple[str, str, bool]] = []
    for sec, _t, words, level, encoded, _why in UNCODED:
        if _key(words) in items:
            continue
        have = [by_id[i] for i in encoded if i in by_id]
        if have:
            items[_key(words)] = {
                "kinds": {_kind(r) for r in have},
                "mandatory": level == "mandatory",
                "rules": [r["id"] for r in have],
            }
        else:
            items[_key(words)] = {"kinds": set(), "mandatory": level == "mandatory", "rules": []}
            none.append((sec, words, level == "mandatory"))
    auto = sum(1 for it in items.values() if "auto" in it["kinds"])
    manual = sum(1 for it in items.values() if it["kinds"] == {"manual"})
    return {
        "items": len(items),
        "automatic": auto,
        "manual": manual,
        "none": len(none),
        "mandatory_none": sum(1 for n in none if n[2]),
        "mandatory_manual": sum(
            1 for it in items.values() if it["kinds"] == {"manual"} and it["mandatory"]
        ),
    }


def _verification(prof: dict[str, Any]) -> str:
    """How a profile's quotes were checked: the seed, else what its rules' notes say (verified: ...)."""
    src = prof["source"]
    if src.get("seed"):
        return "from seed " + src["seed"]
    said = [
        m.group(1)
        for r in prof["rules"]
        for m in [re.search(r"verified:\s*(true|partial|false)", str(r.get("note") or ""))]
        if m
    ]
    n = len(prof["rules"])
    true, part, false = (said.count(k) for k in ("true", "partial", "false"))
    unsaid = n - len(said)
    parts = [
        f"{true} verified against two public copies" if true else "",
        f"{part} against one copy only" if part else "",
        f"{false} unverified (the note says verified: false)" if false else "",
        f"{unsaid} without a verification note" if unsaid else "",
    ]
    return "not from a seed; " + ", ".join(p for p in parts if p) + " (see each rule's note)"


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
    return (
        f"| {rule['id']} | {_cell(rule['title'])} | {what} | {rule['level']} | "
        f"{rule['consequence']} |"
    )


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
    add(
        "Generated by `scripts/coverage_doc.py` from the profile YAML - do not edit by hand "
        "(`make coverage`; a test fails when this file is out of date)."
    )
    add("")
    add(f"## JRC Guidelines Issue 3.0 (EUR 23638 EN) - profile `jrc-v3` {jrc['version']}")
    add("")
    add(
        f"{len(rules)} rules: {len(rules) - n_manual} automatic, {n_manual} manual "
        f"(judged by the checker in the checker's file, `manual_checks:`, or a ledger sign-off; the "
        f"delivery's own manual_checks table is the contractor's statement, evidence only); {n_mand} "
        f"mandatory, {len(rules) - n_mand} recommended."
    )
    add("")
    c = item_counts(rules)
    add(
        f"Checkable items of the guidelines: {c['items']} - {c['automatic']} automatic, {c['manual']} "
        f"manual, {c['none']} without a rule ({c['mandatory_none']} of them mandatory; each with its reason "
        f'under "Checkable statements without a rule"). An item is a distinct requirement text: a rule\'s '
        "quote (several rules may test one) or a checkable statement no rule quotes."
    )
    add("")
    problems = claim_problems(rules)
    if problems:
        add("**Over-claims** (a rule cites a table but reads none of its data):")
        add("")
        for pr in problems:
            add(f"- {pr}")
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
                add(f'- Not encoded: "{_cell(words)}" - {why}')
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
        audit = [
            r
            for r in rules
            if str((r.get("audit") or {}).get("table")) == str(num) and r not in these
        ]
        auto = ", ".join(r["id"] for r in these if not r.get("manual")) or "-"
        manual = ", ".join(r["id"] for r in these if r.get("manual")) or "-"
        if num in (6, 10):
            auto += " (every row: JRC-2.4-QCR-MINIMUM-SET)"
        if num == 2:
            auto = "- (indicative values, no requirement; tables.scanning_resolutions keeps them)"
        if audit:
            auto += f" (and as `audit:` metadata on {len(audit)} more rules)"
        add(f"| {num} | {title} | {auto} | {manual} |")
    add("")
    add("### Requirements deliberately left manual")
    add("")
    add(
        "Visual or procedural requirements no program can judge. Each is a `manual: true` rule "
        "reading `manual.<rule-id>`; without the checker's entry (the checker's file or a ledger "
        "sign-off) its verdict is `missing` and the report lists it as still to be signed."
    )
    add("")
    add("| rule | section | requirement | level |")
    add("|---|---|---|---|")
    for r in rules:
        if r.get("manual"):
            add(f"| {r['id']} | §{_section_of(r)} | {_cell(r['title'])} | {r['level']} |")
    add("")
    add("### Checkable statements without a rule")
    add("")
    add("| section | words | level | why no rule |")
    add("|---|---|---|---|")
    by_id = {r["id"] for r in rules}
    quoted = {_key(r["quote"]) for r in rules}
    for sec, _t, words, level, encoded, why in UNCODED:
        if any(i in by_id for i in encoded) or _key(words) in quoted:
            continue
        add(f"| §{sec} | {_cell(words)} | {level} | {_cell(why)} |")
    add("")
    add("### Statements read and not encoded (not a checkable requirement)")
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
        add(
            f"Source: {_cell(src['title'])} ({src.get('identifier') or ''}); quotes {_verification(prof)}."
        )
        add("")
        add("| rule | title | measure / check | level | consequence |")
        add("|---|---|---|---|---|")
        for r in prof["rules"]:
            add(_rule_row(r))
        add("")
    return "\n".join(out).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--check",
        action="store_true",
        help="fail if specs/COVERAGE.md is out of date or a rule over-claims a table",
    )
    ap.add_argument(
        "--counts",
        nargs="?",
        const=str(SPECS / "jrc-v3.yaml"),
        metavar="PROFILE",
        help="print the JRC item counts of a jrc-v3 profile file (default the shipped one) as JSON",
    )
    args = ap.parse_args(argv)
    if args.counts:
        rules = yaml.safe_load(Path(args.counts).read_text(encoding="utf-8"))["rules"]
        print(json.dumps(item_counts(rules), sort_keys=True))
        return 0
    text = render()
    if args.check:
        problems = claim_problems(_load("jrc-v3")["rules"])
        if problems:
            print("rules over-claim a table:\n  " + "\n  ".join(problems), file=sys.stderr)
            return 1
        current = OUT.read_text(encoding="utf-8") if OUT.exists() else ""
        if current != text:
            print(
                f"{OUT.relative_to(ROOT)} is out of date: run python scripts/coverage_doc.py",
                file=sys.stderr,
            )
            return 1
        return 0
    OUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
