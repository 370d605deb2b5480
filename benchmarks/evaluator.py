"""Evaluate a profile's image-scope rules over N synthetic image records (default 1,000,000).

Prints records/second for each stage (parse the delivery's tables, evaluate the rules, build the
QCR records) and the process's peak memory. The peer measured in the same run is pandas itself
reading the same CSV (`pd.read_csv`), the floor for any table-driven checker.

    .venv/bin/python benchmarks/evaluator.py [--rows 1000000] [--profile jrc-v3]
"""

from __future__ import annotations

import argparse
import dataclasses
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from orthospec.delivery.reader import open_delivery
from orthospec.engine.evaluator import Evaluator
from orthospec.engine.params import resolve_parameters
from orthospec.profile.loader import load_profile
from orthospec.qcr import build_document


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def write_delivery(root: Path, n: int, seed: int = 1) -> None:
    rng = np.random.default_rng(seed)
    (root / "tables").mkdir(parents=True)
    ids = np.char.add("IMG_", np.arange(n).astype(str))
    df = pd.DataFrame(
        {
            "image_id": ids,
            "file": np.char.add(np.char.add("images/", ids), ".tif"),
            "block": np.char.add("B", (np.arange(n) // 5000).astype(str)),
            "flight_id": np.char.add("F", (np.arange(n) // 200).astype(str)),
            "photo_number": np.arange(n).astype(str),
            "flying_height": np.round(rng.normal(3800, 40, n), 1),
            "exposure_x": np.round(rng.uniform(4e5, 6e5, n), 2),
            "exposure_y": np.round(rng.uniform(5e6, 6e6, n), 2),
            "exposure_z": np.round(rng.normal(4100, 40, n), 2),
            "exposure_time": "2026-04-10T10:00:00",
            "gsd": 0.25,
            "bit_depth": 8,
            "mean_dn": np.round(rng.normal(110, 10, n), 2),
            "std_dn": np.round(rng.normal(38, 4, n), 2),
            "saturation_low": np.round(rng.exponential(0.05, n), 4),
            "saturation_high": np.round(rng.exponential(0.05, n), 4),
            "cloud_cover": np.round(rng.exponential(1.0, n), 2),
            "sun_elevation": np.round(rng.normal(45, 5, n), 2),
            "roll": np.round(rng.normal(0, 0.8, n), 3),
        }
    )
    df.to_csv(root / "tables" / "images.csv", index=False)
    (root / "delivery.yaml").write_text(f"""\
orthospec_delivery: 1
id: BENCH
project: {{id: P, crs: "EPSG:25832"}}
contractor: {{name: bench}}
sensor: {{type: aerial, digital: true}}
product: {{gsd: {{value: 0.25, unit: m}}, bit_depth: 8}}
tender: {{parameters: {{tolerance_xy: {{value: 0.5, unit: m}}, ortho_pixel_size: {{value: 0.25, unit: m}}}}}}
blocks: [{", ".join(f"{{id: B{i}}}" for i in range((n + 4999) // 5000))}]
tables: {{images: tables/images.csv}}
""")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--profile", default="jrc-v3")
    ap.add_argument("--records", action="store_true", help="also build the full QCR document")
    args = ap.parse_args()
    prof = load_profile(args.profile)
    rules = tuple(
        r
        for r in prof.rules
        if r.scope == "image" and r.measure.startswith("images.") and not r.manual
    )
    prof = dataclasses.replace(prof, rules=rules)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "d"
        t0 = time.perf_counter()
        write_delivery(root, args.rows)
        print(f"wrote {args.rows:,} image records in {time.perf_counter() - t0:.1f} s")
        t0 = time.perf_counter()
        pd.read_csv(root / "tables" / "images.csv", dtype=str, keep_default_na=False)
        peer = time.perf_counter() - t0
        t0 = time.perf_counter()
        d = open_delivery(root)
        d.load_all_tables()
        parse = time.perf_counter() - t0
        params = resolve_parameters(prof, dict(d.manifest.tender.parameters), {})
        t0 = time.perf_counter()
        ev = Evaluator(prof, d, params).run()
        evaluate = time.perf_counter() - t0
        n_rec = sum(len(r.items) for r in ev.results)
        print(f"profile {prof.id} {prof.version}: {len(rules)} image-scope rules on table columns")
        print(f"{'stage':<28}{'seconds':>10}{'records/s':>16}")
        print(f"{'pandas read_csv (peer)':<28}{peer:>10.2f}{args.rows / peer:>16,.0f}")
        print(f"{'open + validate tables':<28}{parse:>10.2f}{args.rows / parse:>16,.0f}")
        print(
            f"{'evaluate rules':<28}{evaluate:>10.2f}{n_rec / evaluate:>16,.0f}  ({n_rec:,} QCRs)"
        )
        if args.records:
            t0 = time.perf_counter()
            build_document(ev, date="2026-01-01")
            build = time.perf_counter() - t0
            print(f"{'build QCR records':<28}{build:>10.2f}{n_rec / build:>16,.0f}")
        print(f"ratio open+validate / pandas read_csv: {parse / peer:.2f}")
        print(f"peak memory (RSS): {peak_mb():,.0f} MB")


if __name__ == "__main__":
    main()
