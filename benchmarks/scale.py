"""Benchmark: `orthospec check` of deliveries with many distinct small images (issue 14).

Usage::

    .venv/bin/python benchmarks/scale.py [--images 1000 4000] [--quick] [--keep DIR]
                                         [--profile jrc-v3] [--workers N]

Builds, per requested N, a copy of examples/deliveries/aerial-pass with N distinct images: the
example's 30 images plus N-30 new ones, each painted by the example generator's own scene painter
(examples/generate.py ``render_image``, seeded by its number: a picture of its own, not a near copy
of another, so the copy detection of issue 25 finds nothing, as in a real delivery) over the
footprint of one of the 30, with its own row in images.csv (image_id ``F01_c00031`` ...) carrying
its own statistics. Then runs ``orthospec check --format json`` once per N in a subprocess and prints wall
time, peak RSS (``os.wait4`` of exactly that child) and bytes of qcr.json, each per image, the
time ratio between the sizes (issue 14 target: 4,000 images <= 4.8x the time of 1,000, under
1 GB) and a linear extrapolation to 50,000 images from the two largest runs. ``--quick``
uses 100 and 400 images.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deliveries" / "aerial-pass"


def build(target: Path, n: int) -> None:
    """Copy aerial-pass to ``target`` and grow it to ``n`` distinct images."""
    import numpy as np
    import rasterio

    sys.path.insert(0, str(ROOT / "examples"))
    try:
        from generate import image_stats, render_image
    finally:
        sys.path.remove(str(ROOT / "examples"))
    shutil.copytree(EXAMPLE, target)
    with open(target / "tables" / "images.csv", newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        fields = list(reader.fieldnames or [])
        rows = list(reader)
    templates = []
    for row in rows:
        with rasterio.open(target / row["file"]) as ds:
            templates.append((row, ds.profile, ds.read(), ds.tags(), ds.colorinterp))
    out_rows = list(rows)
    for k in range(len(rows), n):
        row, profile, data, tags, colours = templates[k % len(templates)]
        image_id = f"{row['flight_id']}_c{k:05d}"
        pixels, _cloud = render_image(
            np.random.default_rng([20261121, k]), "plain", n=data.shape[-1]
        )
        stats = {key: f"{v:.3f}" for key, v in image_stats(pixels).items() if key in row}
        new = dict(
            row, image_id=image_id, file=f"images/{image_id}.tif", photo_number=f"{k:05d}", **stats
        )
        with rasterio.open(target / new["file"], "w", **profile) as ds:
            ds.write(pixels)
            ds.update_tags(**dict(tags, IMAGE_ID=image_id, PHOTO_NUMBER=new["photo_number"]))
            ds.colorinterp = colours
        out_rows.append(new)
    with open(target / "tables" / "images.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        w.writerows(out_rows[:n])


def run(cmd: list[str]) -> tuple[float, float, int, str]:
    """Wall seconds, peak RSS (MB) of exactly this child, exit code, stderr tail."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = proc.stderr.read() if proc.stderr else b""
    _pid, status, usage = os.wait4(proc.pid, 0)
    return (
        time.perf_counter() - t0,
        usage.ru_maxrss / 1024.0,
        os.waitstatus_to_exitcode(status),
        err.decode(errors="replace")[-600:],
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, nargs="+", default=[1000, 4000])
    ap.add_argument("--quick", action="store_true", help="100 and 400 images")
    ap.add_argument("--profile", default="jrc-v3")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--keep", help="build the deliveries in this folder and keep (reuse) them")
    args = ap.parse_args()
    sizes = [100, 400] if args.quick else sorted(args.images)
    orthospec = str(Path(sys.executable).parent / "orthospec")
    results = []
    with tempfile.TemporaryDirectory(prefix="orthospec-scale-") as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for n in sizes:
            delivery = work / f"scale-{n}"
            if not (delivery / "tables" / "images.csv").exists():
                t0 = time.perf_counter()
                shutil.rmtree(delivery, ignore_errors=True)
                build(delivery, n)
                print(
                    f"built {delivery.name}: {n} images in {time.perf_counter() - t0:.0f} s",
                    flush=True,
                )
            out = Path(tmp) / f"out-{n}"
            cmd = [
                orthospec,
                "check",
                str(delivery),
                "-p",
                args.profile,
                "--out",
                str(out),
                "--format",
                "json",
                "--date",
                "2026-11-21",
                "--param",
                "tolerance_xy=0.5m",
                "--param",
                "map_crs=EPSG:25832",
            ]
            if args.workers:
                cmd += ["--workers", str(args.workers)]
            wall, rss, code, err = run(cmd)
            if code not in (0, 1, 3):  # accepted, rejected, incomplete (the checker's work open)
                raise SystemExit(f"check of {n} images failed ({code}): {err}")
            size = (out / "qcr.json").stat().st_size
            results.append((n, wall, rss, size))
            print(
                f"{n:6d} images: {wall:7.1f} s ({wall / n * 1000:5.1f} ms/image, "
                f"{n / wall:5.1f} images/s), peak RSS {rss:6.0f} MB, qcr.json "
                f"{size / 1e6:7.1f} MB ({size / n / 1e3:5.1f} KB/image), exit {code}",
                flush=True,
            )
    if len(results) >= 2:
        (n1, w1, r1, s1), (n2, w2, r2, s2) = results[-2], results[-1]
        print(
            f"time {n2}/{n1} images = {w2 / w1:.2f}x for {n2 / n1:.1f}x the images "
            f"(target <= {4.8 * n2 / n1 / 4:.1f}x); peak RSS {r2:.0f} MB (target < 1024 MB)"
        )
        per_t, per_r, per_s = (w2 - w1) / (n2 - n1), (r2 - r1) / (n2 - n1), (s2 - s1) / (n2 - n1)
        big = 50_000
        print(
            f"50,000 images (linear from the last two runs): about {w2 + per_t * (big - n2):.0f} s "
            f"({per_t * 1000:.1f} ms/image), {r2 + per_r * (big - n2):.0f} MB peak RSS "
            f"({per_r * 1000:.0f} KB/image), {(s2 + per_s * (big - n2)) / 1e9:.2f} GB of qcr.json"
        )
    print(f"load average: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cpus")


if __name__ == "__main__":
    main()
