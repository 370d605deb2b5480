"""An output format: ``--format example-tiles`` writes ``qcr.tiles.csv``, one row per image with
its worst verdict (a list an agency's GIS joins to its tile index)."""

from __future__ import annotations

import csv
import io
from typing import Any

from orthospec import verdicts as V
from orthospec.qcr import all_records


def tiles_csv(doc: dict[str, Any]) -> str:
    """image, worst verdict, failing rules (';'-separated), from every image-scope record."""
    per: dict[str, list[dict[str, Any]]] = {}
    for rec in all_records(doc):
        if rec["scope"] == "image":
            per.setdefault(str(rec["item"]), []).append(rec)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["image", "verdict", "failing_rules"])
    for item in sorted(per):
        recs = per[item]
        failing = sorted({r["rule"] for r in recs if r["verdict"] in V.FAILING})
        w.writerow([item, V.worst(r["verdict"] for r in recs), ";".join(failing)])
    return buf.getvalue()


tiles_csv.suffix = ".tiles.csv"  # type: ignore[attr-defined]
