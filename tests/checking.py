"""Shared test steps: run `check` with a checker file (``check --checker FILE``) as a library call,
copy and edit example deliveries, and compute figures by hand from the checker's tables.

Real components only: the checker file is a real YAML file on disk.
"""

from __future__ import annotations

import csv
import hashlib
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from orthospec import api
from orthospec.profile.loader import ResolvedProfile
from orthospec.qcr import all_records

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "deliveries"
CHECKERS = ROOT / "examples" / "checker"
#: the check date the example deliveries and checker folders are generated for
DATE = "2026-11-21"


def copy_example(example: str, tmp_path: Path) -> Path:
    """A copy of a shipped example delivery in ``tmp_path`` (tests edit the copy, never the original)."""
    d = tmp_path / example
    shutil.copytree(EXAMPLES / example, d)
    return d


#: a checker file for the tests' mini delivery (tests/conftest.py MANIFEST, tests/data/profiles/mini.yaml)
MINI_CHECKER = """\
orthospec_checker: 1
checker: {name: Eva External, role: external QC, organisation: Paying Agency}
delivery: {id: D1}
parameters: {tolerance_xy: {value: 0.5, unit: m}}
manual_checks:
  - {check: R-VIS, item: "*", date: 2026-01-02, verdict: pass, note: looked at every image}
waivers:
  - {rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}
"""


#: a checker's file template for the mini-profile deliveries of the ledger tests (``.format(id=...)``):
#: the ITT value in force and the verdict of the manual rule R-VIS
LEDGER_CHECKER = """\
orthospec_checker: 1
checker: {{name: Carla Checker (fictional), role: external QC}}
delivery: {{id: {id}}}
parameters: {{tolerance_xy: {{value: 0.5, unit: m}}}}
manual_checks:
  - {{check: R-VIS, item: "*", date: 2026-01-01, verdict: pass, note: visual check of every image}}
"""


def records(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """Every record of a QCR document (the one way to read records: qcr.all_records)."""
    return list(all_records(doc))


def write_checker(folder: Path, text: str = MINI_CHECKER, name: str = "checker.yaml") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def resigned(checker: str | Path, delivery: str | Path, out: str | Path, **top: Any) -> Path:
    """A copy of ``checker`` re-signed on ``delivery`` as it is now: each pinned file's SHA-256 and each manual
    verdict's image SHA-256 recomputed (``top`` replaces top-level keys of checker.yaml, e.g.
    ``parameters={}``): the checker's verdicts given on the planted content a test checks, written outside
    the delivery. The checker's measured check points keep their image_sha256: a point measured on an
    image that was changed since is measured again, never re-signed (JRC-12.6-POINTS-BOUND).

    A checker folder (or its checker.yaml) is copied whole to ``out`` without its ``.yaml`` suffix and the
    path of the copy's checker.yaml is returned (`--checker` reads DIR/checker.yaml as the folder DIR);
    a single checker file is written to ``out``."""
    src = Path(checker)
    if not src.exists() and src.suffix == ".yaml" and src.with_suffix("").is_dir():
        src = src.with_suffix(
            ""
        )  # examples/checker/<name>.yaml was the single file before the folders
    folder = src if src.is_dir() else (src.parent if src.name == "checker.yaml" else None)
    root = Path(delivery)
    if folder is not None:
        dst = Path(out).with_suffix("") if Path(out).suffix == ".yaml" else Path(out)
        if dst.resolve() != folder.resolve():
            shutil.rmtree(dst, ignore_errors=True)
            shutil.copytree(folder, dst)
        path = dst / "checker.yaml"
    else:
        path = Path(out)
    doc = yaml.safe_load(
        (folder / "checker.yaml" if folder is not None else src).read_text(encoding="utf-8")
    )
    m = yaml.safe_load((root / "delivery.yaml").read_text(encoding="utf-8")) or {}
    used = {v for k in ("tables", "vectors", "documents") for v in (m.get(k) or {}).values()}
    # the checker pins what it received: a table the planted delivery no longer has is not pinned
    pins = {}
    for rel, pin in (doc["delivery"].get("files") or {}).items():
        if rel in used and (root / rel).is_file():
            sha = hashlib.sha256((root / rel).read_bytes()).hexdigest()
            pins[rel] = {**pin, "sha256": sha} if isinstance(pin, dict) else sha
    doc["delivery"]["files"] = pins
    for entry in doc.get("manual_checks") or []:  # the checker judged the images as delivered now
        rel = entry.get("file")
        if rel and (root / rel).is_file():
            entry["sha256"] = hashlib.sha256((root / rel).read_bytes()).hexdigest()
    doc.update(top)
    path.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def remeasured(folder: str | Path, delivery: str | Path) -> None:
    """The checker measured its check points on the delivery as received: each point's image is the one
    delivered now (a point whose image is not delivered goes to the nearest delivered image of its
    block, by exposure position) and its image_sha256 that image's. For tests in which the contractor's
    edits come before the checker's work (tests/test_redteam.py)."""
    table = Path(folder) / "tables" / "checkpoints.csv"
    root = Path(delivery)
    with table.open(encoding="utf-8", newline="") as f:
        r = csv.DictReader(f)
        header, rows = list(r.fieldnames or []), list(r)
    _, images = read_table(root, "images")
    have = [i for i in images if i.get("file") and (root / i["file"]).is_file()]
    by_id = {i["image_id"]: i for i in have}
    for row in rows:
        img = by_id.get(row.get("image_id") or "")
        if img is None:
            near = [i for i in have if i.get("block") == row["block"]] or have
            x, y = float(row["x_ref"]), float(row["y_ref"])
            img = min(
                near,
                key=lambda i: (
                    (float(i.get("exposure_x") or 0) - x) ** 2
                    + (float(i.get("exposure_y") or 0) - y) ** 2
                ),
            )
        row["image_id"] = img["image_id"]
        row["image_sha256"] = hashlib.sha256((root / img["file"]).read_bytes()).hexdigest()
    with table.open("w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def check_with(
    delivery: str | Path,
    profile: str | Path | ResolvedProfile,
    *,
    checker: str | Path | None = None,
    date: str = "2026-01-01",
    params: list[str] | tuple[str, ...] | dict[str, str] = (),
    fail_on: str = "fail",
    options: dict[str, Any] | None = None,
) -> api.CheckResult:
    """`orthospec check DELIVERY --profile PROFILE [--checker FILE]` as a library call."""
    return api.check(
        delivery,
        profile,
        checker=checker,
        date=date,
        params=params,
        fail_on=fail_on,
        options=options,
    )


def nssda_accuracy_r(checkpoints_csv: Path) -> dict[str, float]:
    """NSSDA horizontal Accuracy_r per block, by hand from a checker's check point table
    (FGDC-STD-007.3-1998 Appendix 3-A: 1.7308 RMSE_r when RMSE_x = RMSE_y, else
    2.4477 x 0.5 (RMSE_x + RMSE_y)); rows marked ``excluded`` are left out."""
    t = pd.read_csv(checkpoints_csv)
    t = t[~t["excluded"].astype(str).str.lower().eq("true")]
    out = {}
    for block, g in t.groupby("block"):
        rx = float(np.sqrt(np.mean((g["x"] - g["x_ref"]) ** 2)))
        ry = float(np.sqrt(np.mean((g["y"] - g["y_ref"]) ** 2)))
        out[str(block)] = 1.7308 * float(np.hypot(rx, ry)) if rx == ry else 2.4477 * 0.5 * (rx + ry)
    return out


# --- editing a copied delivery (the red-team and regression tests plant defects with these) ---


def manifest(d: Path) -> dict[str, Any]:
    return yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))


def write_manifest(d: Path, m: dict[str, Any]) -> None:
    (d / "delivery.yaml").write_text(
        yaml.safe_dump(m, sort_keys=False, allow_unicode=True), encoding="utf-8"
    )


def read_table(d: Path, name: str) -> tuple[list[str], list[dict[str, str]]]:
    with (d / "tables" / f"{name}.csv").open(encoding="utf-8", newline="") as f:
        r = csv.DictReader(f)
        return list(r.fieldnames or []), list(r)


def write_table(d: Path, name: str, header: list[str], rows: list[dict[str, str]]) -> None:
    with (d / "tables" / f"{name}.csv").open("w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
