"""Report render time for a large synthetic QCR document (1,000 images, 5,000 QCRs).

The document is qcr.json-shaped (validated against ``orthospec.qcr.qcr_schema()``): 5 image
rules x 1,000 images, block rules over 20 blocks with 25 check points each, ~2 % failing items.
Prints seconds for HTML (every record, passing ones folded) and PDF (bounded tables), and sizes.

    .venv/bin/python benchmarks/report.py [--images 1000] [--rules 5] [--blocks 20] [--no-figures]
                                          [--points N]

``--points N`` spreads N check points over the blocks (default 25 per block): the figures draw
at most ``figures.accuracy.MAX_MARKS`` of a block's points and the HTML table lists at most
``ReportOptions.max_table_points``, so the cost should level off as N grows (issue 14). Peak RSS
of the whole run is printed too.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import math
import resource
import time
from typing import Any

import jsonschema
import numpy as np

from orthospec.qcr import qcr_schema, stable
from orthospec.reports import document
from orthospec.reports.html import ReportOptions


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def _record(rule: str, scope: str, item: str, value: float, limit: float, unit: str, row: int,
            verdict: str, file: str) -> dict[str, Any]:
    return {
        "rule": rule,
        "title": f"{rule} within limit",
        "clause": {"document": "JRC EUR 23638 EN", "section": "6.3"},
        "quote": "Synthetic quote.",
        "scope": scope,
        "item": item,
        "level": "mandatory",
        "consequence": "reject_item",
        "manual": False,
        "verdict": verdict,
        "measure": f"images.{rule.lower()}",
        "measured": {"value": value, "unit": unit},
        "requirement": {"op": "<=", "value": limit, "unit": unit, "text": f"<= {limit} {unit}"},
        "evidence": [{"file": file, "rows": [row], "sha256": _sha(file)}],
        "message": f"{rule} = {value:.6g} {unit}; required <= {limit} {unit}",
        "waiver": None,
    }


def synthetic_document(
    n_images: int = 1000,
    n_rules: int = 5,
    n_blocks: int = 20,
    points_per_block: int = 25,
    seed: int = 1,
) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    images = [f"IMG_{i:05d}" for i in range(1, n_images + 1)]
    records: list[dict[str, Any]] = []
    rules: list[dict[str, Any]] = []
    rejected: set[str] = set()
    blocks = [f"B{b:02d}" for b in range(1, n_blocks + 1)]
    details: dict[str, Any] = {}
    for b in blocks:
        x0, y0 = 500000.0 + 8000 * (int(b[1:]) % 5), 5400000.0 + 8000 * (int(b[1:]) // 5)
        sigma = 0.9 if b in ("B03", "B11") else 0.15
        pts = []
        dx, dy = rng.normal(0, sigma, points_per_block), rng.normal(0, sigma, points_per_block)
        for k in range(points_per_block):
            pts.append(
                {
                    "point_id": f"{b}-C{k + 1:02d}",
                    "dx": dx[k],
                    "dy": dy[k],
                    "dz": None,
                    "dr": float(np.hypot(dx[k], dy[k])),
                    "x_ref": x0 + rng.uniform(0, 6000),
                    "y_ref": y0 + rng.uniform(0, 6000),
                    "status": "pass",
                    "decision": "kept",
                    "row": len(details) * points_per_block + k + 1,
                }
            )
        rx, ry = float(np.sqrt(np.mean(dx * dx))), float(np.sqrt(np.mean(dy * dy)))
        for p in pts:
            if abs(p["dx"]) > 3 * rx or abs(p["dy"]) > 3 * ry:
                p["status"] = "fail"
        details[b] = {
            "points": pts,
            "limit_x": 3 * rx,
            "limit_y": 3 * ry,
            "basis": "calculated",
            "unit": "m",
            "stats": {
                "n": points_per_block,
                "mean_x": float(dx.mean()),
                "mean_y": float(dy.mean()),
                "std_x": float(dx.std(ddof=1)),
                "std_y": float(dy.std(ddof=1)),
                "rmse_x": rx,
                "rmse_y": ry,
                "rmse_z": None,
                "max_abs_dx": float(np.abs(dx).max()),
                "max_abs_dy": float(np.abs(dy).max()),
                "max_dr": max(p["dr"] for p in pts),
            },
            "gcps": [
                {"point_id": f"{b}-G{j}", "x": x0 + 6000 * (j % 2), "y": y0 + 6000 * (j // 2)}
                for j in range(4)
            ],
            "area_source": "area",
        }
    for axis in ("x", "y"):
        rid = f"BLK-RMSE{axis.upper()}"
        recs = []
        for i, b in enumerate(blocks):
            v = details[b]["stats"][f"rmse_{axis}"]
            verdict = "pass" if v <= 0.5 else "fail"
            if verdict == "fail":
                rejected.add(b)
            rec = _record(rid, "block", b, v, 0.5, "m", i + 1, verdict, "tables/checkpoints.csv")
            rec["consequence"] = "reject_block"
            recs.append(rec)
        records += recs
        rules.append(_rule_summary(rid, "block", recs))
    img_rejected: list[str] = []
    for r in range(n_rules):
        rid = f"IMG-R{r + 1}"
        values = rng.normal(1.0, 0.5, n_images)
        recs = []
        for i, img in enumerate(images):
            verdict = "fail" if values[i] > 2.0 else "pass"
            if verdict == "fail":
                img_rejected.append(img)
            recs.append(
                _record(
                    rid,
                    "image",
                    img,
                    float(values[i]),
                    2.0,
                    "deg",
                    i + 1,
                    verdict,
                    "tables/images.csv",
                )
            )
        records += recs
        rules.append(_rule_summary(rid, "image", recs))
    summary = {
        k: 0 for k in ("pass", "fail", "warn", "not_applicable", "missing", "error", "waived")
    }
    for rec in records:
        summary[rec["verdict"]] += 1
    doc = {
        "schema": "orthospec.qcr/1",
        "tool": {"name": "orthospec", "version": "0.1.0"},
        "date": "2026-01-01",
        "operator": "Benchmark",
        "profile": {
            "id": "bench",
            "version": "1.0.0",
            "title": "Benchmark profile",
            "sha256": _sha("bench"),
            "source": {"title": "JRC"},
            "extends": [],
            "parameters": {"tolerance_xy": {"value": 0.5, "unit": "m", "source": "tender"}},
        },
        "delivery": {
            "id": "D-BENCH",
            "path": "bench",
            "manifest_sha256": _sha("manifest"),
            "project": {"id": "P", "name": "National delivery (synthetic)"},
            "contractor": {"name": "Synthetic"},
            "operator": {"name": "Benchmark"},
            "sensor": {"type": "aerial"},
            "dates": {},
            "files": [
                {"path": f, "sha256": _sha(f), "bytes": 1000}
                for f in ("delivery.yaml", "tables/images.csv", "tables/checkpoints.csv")
            ],
        },
        "verdict": "rejected" if summary["fail"] else "accepted",
        "fail_on": "fail",
        "summary": {"rules": len(rules), "records": len(records), **summary},
        "rollup": {
            "rejected": {"block": sorted(rejected), "image": sorted(set(img_rejected))},
            "reasons": ["synthetic"],
        },
        "waivers_unused": [],
        "rules": rules,
        "records": records,
        "details": {"checkpoints": details},
    }
    doc = stable(doc)
    jsonschema.validate(doc, qcr_schema())
    return doc


def _rule_summary(rid: str, scope: str, recs: list[dict[str, Any]]) -> dict[str, Any]:
    counts: dict[str, int] = {}
    for r in recs:
        counts[r["verdict"]] = counts.get(r["verdict"], 0) + 1
    return {
        "rule": rid,
        "title": f"{rid} within limit",
        "scope": scope,
        "level": "mandatory",
        "consequence": recs[0]["consequence"],
        "clause": "JRC EUR 23638 EN, §6.3",
        "verdict": "fail" if counts.get("fail") else "pass",
        "counts": counts,
        "offending": [r["item"] for r in recs if r["verdict"] == "fail"],
        "error": None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=1000)
    ap.add_argument("--rules", type=int, default=5)
    ap.add_argument("--blocks", type=int, default=20)
    ap.add_argument("--no-figures", action="store_true")
    ap.add_argument(
        "--points", type=int, default=None, help="check points in all (default 25 per block)"
    )
    a = ap.parse_args()
    per_block = 25 if a.points is None else max(1, math.ceil(a.points / a.blocks))
    doc = synthetic_document(a.images, a.rules, a.blocks, per_block)
    s = doc["summary"]
    print(
        f"document: {a.images} images, {s['records']} QCRs ({s['fail']} failing), {a.blocks} blocks "
        f"of {per_block} check points"
    )
    figs = not a.no_figures
    t = time.perf_counter()
    html = document.render(
        doc, formats=["html"], options=ReportOptions(bounded=False, figures=figs)
    )
    t_html = time.perf_counter() - t
    t = time.perf_counter()
    pdf = document.render(doc, formats=["pdf"], options=ReportOptions(bounded=True, figures=figs))
    t_pdf = time.perf_counter() - t
    t = time.perf_counter()
    document.render(doc, formats=["html", "pdf"])  # what `orthospec check --format html,pdf` does
    t_both = time.perf_counter() - t
    from pypdf import PdfReader

    pages = len(PdfReader(io.BytesIO(pdf["report.pdf"])).pages)
    print(
        f"html: {t_html:.2f} s, {len(html['report.html']) / 1e6:.2f} MB (figures {'on' if figs else 'off'})"
    )
    print(
        f"pdf:  {t_pdf:.2f} s, {len(pdf['report.pdf']) / 1e6:.2f} MB, {pages} pages (bounded tables)"
    )
    print(f"html+pdf together, default options (figures on, drawn once): {t_both:.2f} s")
    print(
        f"peak RSS of this run: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB"
    )


if __name__ == "__main__":
    main()
