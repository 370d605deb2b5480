"""Benchmark: `orthospec check` of a delivery with many check points vs ``pandas.read_csv``.

Usage::

    .venv/bin/python benchmarks/checkpoints.py [--points 1000000] [--rounds 2] [--keep DIR]
                                               [--profile jrc-v3]

Copies examples/deliveries/aerial-pass and replaces its checkpoints.csv with ``--points``
generated rows (the columns of specs/delivery-tables.yaml: points spread over the three blocks'
rectangles, image minus reference errors ~ N(0, 0.15 m), every other column filled as in the
example). Then, in one run and each in its own subprocess, best of ``--rounds``:
``pandas.read_csv`` of that file (the peer) and ``orthospec check`` of the delivery twice: as a
user runs it (no ``--format``: the default terminal, json, csv and junit outputs) and with
``--format json`` only. Prints the times, each check's ratio to read_csv (issue 14 target:
<= 10x), peak RSS (target < 1 GB) and the size of what it wrote.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deliveries" / "aerial-pass"
# block -> (x0, x1, y0, y1): the part of each block polygon below its cut corner
BLOCKS = {"B01": (500000.0, 506000.0, 5400000.0, 5407000.0),
          "B02": (507500.0, 513500.0, 5403000.0, 5410000.0),
          "B03": (512500.0, 518500.0, 5411000.0, 5418000.0)}
SOURCE = '"GNSS RTK survey, independent of the contractor (SAPOS HEPS), 2026-03"'
READ_CSV = "import sys, pandas; pandas.read_csv(sys.argv[1])"


def write_checkpoints(path: Path, n: int, seed: int = 0) -> None:
    """``n`` check points in the delivery-tables layout, written in chunks (bounded memory)."""
    import numpy as np

    images: dict[str, list[str]] = {}
    for line in (EXAMPLE / "tables" / "images.csv").read_text().splitlines()[1:]:
        cells = line.split(",")
        images.setdefault(cells[2], []).append(cells[0])
    rng = np.random.default_rng(seed)
    names = sorted(BLOCKS)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("point_id,block,x,y,x_ref,y_ref,image_id,source,excluded,exclusion_reason,"
                 "precision_xy\n")
        for start in range(0, n, 100_000):
            m = min(100_000, n - start)
            b = rng.integers(0, len(names), m)
            lo = np.array([BLOCKS[k] for k in names])[b]
            xr = lo[:, 0] + rng.random(m) * (lo[:, 1] - lo[:, 0])
            yr = lo[:, 2] + rng.random(m) * (lo[:, 3] - lo[:, 2])
            x = xr + rng.normal(0, 0.15, m)
            y = yr + rng.normal(0, 0.15, m)
            fh.writelines(
                f"P{start + i:07d},{names[b[i]]},{x[i]:.3f},{y[i]:.3f},{xr[i]:.3f},{yr[i]:.3f},"
                f"{images[names[b[i]]][i % len(images[names[b[i]]])]},{SOURCE},false,,0.03\n"
                for i in range(m))


def run(cmd: list[str]) -> tuple[float, float, int]:
    """Wall seconds, peak RSS (MB) of exactly this child, and its exit code."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = proc.stderr.read() if proc.stderr else b""
    _pid, status, usage = os.wait4(proc.pid, 0)
    code = os.waitstatus_to_exitcode(status)
    if code not in (0, 1):
        raise SystemExit(f"{' '.join(cmd)} failed ({code}): {err.decode(errors='replace')[-600:]}")
    return time.perf_counter() - t0, usage.ru_maxrss / 1024.0, code


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--profile", default="jrc-v3")
    ap.add_argument("--keep", help="build the delivery in this folder and keep it")
    args = ap.parse_args()
    orthospec = str(Path(sys.executable).parent / "orthospec")
    with tempfile.TemporaryDirectory(prefix="orthospec-cp-") as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        delivery = work / f"cp-{args.points}"
        if not (delivery / "tables" / "checkpoints.csv").exists():
            shutil.copytree(EXAMPLE, delivery, dirs_exist_ok=True)
            write_checkpoints(delivery / "tables" / "checkpoints.csv", args.points)
        csv = delivery / "tables" / "checkpoints.csv"
        print(f"delivery: {delivery.name}, checkpoints.csv {args.points:,} rows, "
              f"{csv.stat().st_size / 1e6:.0f} MB")
        # what a user runs (default formats: terminal, json, csv, junit), and the json alone
        variants = {"default formats": [], "--format json": ["--format", "json"]}
        best = {name: (1e9, 0.0, 0, "") for name in variants}
        peer = 1e9
        for r in range(args.rounds):
            peer = min(peer, run([sys.executable, "-c", READ_CSV, str(csv)])[0])
            for k, (name, fmt) in enumerate(variants.items()):
                out = Path(tmp) / f"out-{r}-{k}"
                # the ITT tolerance and map projection the example's checker file gives (a
                # manifest's value is evidence only)
                wall, mb, code = run(
                    [
                        orthospec,
                        "check",
                        str(delivery),
                        "-p",
                        args.profile,
                        "--out",
                        str(out),
                        *fmt,
                        "--date",
                        "2026-11-21",
                        "--param",
                        "tolerance_xy=0.5",
                        "--param",
                        "map_crs=EPSG:25832",
                    ]
                )
                written = ", ".join(
                    f"{f.name} {f.stat().st_size / 1e6:.1f} MB"
                    for f in sorted(out.iterdir())
                    if f.is_file()
                )
                shutil.rmtree(out, ignore_errors=True)
                check, rss = best[name][:2]
                best[name] = (min(check, wall), max(rss, mb), code, written)
        print(f"pandas.read_csv: {peer:.2f} s")
        for name, (check, rss, code, written) in best.items():
            print(
                f"orthospec check ({name}): {check:.2f} s, peak {rss:.0f} MB, exit {code}; "
                f"ratio check/read_csv = {check / peer:.1f}x (target <= 10x, < 1024 MB); {written}"
            )
        print(f"load average: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cpus")


if __name__ == "__main__":
    main()
