"""Benchmark: `orthospec init DRAFT --from SOURCE` over a folder of tiles vs GDAL's `gdaltindex`.

Usage::

    .venv/bin/python benchmarks/ingest.py [--tiles 10000] [--px 256] [--rounds 2] [--keep DIR]
                                          [--workers N]

Writes ``--tiles`` GeoTIFF tiles (``--px`` square, 3-band uint8, tiled DEFLATE, a 100 x 100 grid
in UTM 32N, content from a seeded generator) into one folder, then in the same run, A B A B ...,
best of ``--rounds`` each, every command as a user runs it in its own process:

- the peer: ``gdaltindex -f GPKG INDEX.gpkg TILE...`` (GDAL's own tool: opens every tile's header
  in one process and writes the tile index);
- ``orthospec init DRAFT --from SOURCE --no-sha256`` (header facts only: what gdaltindex does, plus
  the draft: images table, facts table, links, TODO.md);
- ``orthospec init DRAFT --from SOURCE`` (with the SHA-256 of every file, a full read of each).

Prints each time, the ratio of init (no hashing) to gdaltindex (issue 27 target: <= 1.5x), and
peak memory: the largest single process (its own VmHWM, sampled from /proc: ru_maxrss would
carry over this script's peak across fork + exec) and the peak of the whole process tree's proportional set size (PSS:
shared pages divided among the processes sharing them), sampled every 20 ms (target < 500 MB). The
load average is printed beside every figure: the machine is shared.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

EPSG = 32632
ORIGIN = (500000.0, 5600000.0)
GSD = 0.2


def write_tiles(folder: Path, n: int, px: int, seed: int = 0) -> None:
    """``n`` tiles of ``px`` x ``px`` pixels on a grid of 100 columns (written once, kept with --keep)."""
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 255, size=(3, px, px), dtype=np.uint8)
    base = (base // 16 * 16).astype(np.uint8)  # compressible, like an image, not noise
    size = px * GSD
    profile = {
        "driver": "GTiff",
        "width": px,
        "height": px,
        "count": 3,
        "dtype": "uint8",
        "crs": f"EPSG:{EPSG}",
        "tiled": True,
        "blockxsize": 256 if px >= 256 else 16 * (px // 16 or 1),
        "blockysize": 256 if px >= 256 else 16 * (px // 16 or 1),
        "compress": "deflate",
        "photometric": "RGB",
    }
    for i in range(n):
        r, c = divmod(i, 100)
        name = folder / f"T_R{r:03d}_C{c:03d}.tif"
        if name.exists():
            continue
        t = from_origin(ORIGIN[0] + c * size, ORIGIN[1] - r * size, GSD, GSD)
        with rasterio.open(name, "w", transform=t, **profile) as ds:
            ds.write(np.roll(base, i, axis=2))


def _hwm(pid: int) -> int:
    """The process's own peak resident set (VmHWM), in bytes: unlike ru_maxrss it does not carry
    over the forking parent's peak across exec."""
    try:
        with open(f"/proc/{pid}/status", "rb") as fh:
            for line in fh:
                if line.startswith(b"VmHWM:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return 0
    return 0


def _pss(pid: int) -> int | None:
    """Proportional set size in bytes (shared pages divided among their users), from smaps_rollup."""
    try:
        with open(f"/proc/{pid}/smaps_rollup", "rb") as fh:
            for line in fh:
                if line.startswith(b"Pss:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _tree_mb(root: int) -> tuple[float, float]:
    """(sum of PSS now, largest own peak RSS so far) of ``root`` and its descendants, in MB (Linux
    /proc). The sum is of proportional sizes: the workers' shared libraries are not counted once per
    worker."""
    parents: dict[int, int] = {}
    rss: dict[int, int] = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/stat", "rb") as fh:
                fields = fh.read().rsplit(b")", 1)[1].split()
            parents[int(entry.name)] = int(fields[1])
            rss[int(entry.name)] = int(fields[21]) * os.sysconf("SC_PAGE_SIZE")
        except (OSError, IndexError, ValueError):
            continue
    tree, frontier = {root}, [root]
    while frontier:
        p = frontier.pop()
        kids = [c for c, pp in parents.items() if pp == p and c not in tree]
        tree.update(kids)
        frontier += kids
    pss = [_pss(p) for p in tree]
    total = sum(v if v is not None else rss.get(p, 0) for p, v in zip(tree, pss, strict=True))
    return total / 1e6, max((max(_hwm(p), rss.get(p, 0)) for p in tree), default=0) / 1e6


def run(cmd: list[str], *, ok: tuple[int, ...] = (0,)) -> tuple[float, float, float]:
    """Wall seconds, peak of the process tree's summed PSS (sampled every 20 ms) and the largest
    single process's own peak RSS (VmHWM, sampled), in MB."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    peak_sum, peak_one, done = 0.0, 0.0, threading.Event()

    def sample() -> None:
        nonlocal peak_sum, peak_one
        while not done.is_set():
            total, one = _tree_mb(proc.pid)
            peak_sum, peak_one = max(peak_sum, total), max(peak_one, one)
            done.wait(0.02)

    th = threading.Thread(target=sample, daemon=True)
    th.start()
    err = proc.stderr.read() if proc.stderr else b""
    _pid, status, _usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    done.set()
    th.join()
    code = os.waitstatus_to_exitcode(status)
    if code not in ok:
        raise SystemExit(
            f"{' '.join(cmd[:4])} ... failed ({code}): {err.decode(errors='replace')[-800:]}"
        )
    return wall, peak_sum, peak_one


def load() -> str:
    return "load " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiles", type=int, default=10_000)
    ap.add_argument("--px", type=int, default=256, help="tile width and height in pixels")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument(
        "--workers", type=int, default=None, help="init --from --workers (default: CPU count)"
    )
    ap.add_argument(
        "--keep", help="write the tiles in this folder and keep them (reused by the next run)"
    )
    args = ap.parse_args()
    orthospec = str(Path(sys.executable).parent / "orthospec")
    gdaltindex = shutil.which("gdaltindex")
    if gdaltindex is None:
        raise SystemExit(
            "gdaltindex not found (GDAL's command-line tools: apt-get install gdal-bin)"
        )
    with tempfile.TemporaryDirectory(prefix="orthospec-ingest-") as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        source = work / f"tiles-{args.tiles}-{args.px}px"
        t0 = time.perf_counter()
        write_tiles(source, args.tiles, args.px)
        files = sorted(p for p in source.iterdir() if p.suffix == ".tif")[: args.tiles]
        size = sum(p.stat().st_size for p in files)
        print(
            f"source: {len(files):,} tiles of {args.px} x {args.px} px, {size / 1e6:.0f} MB "
            f"({time.perf_counter() - t0:.0f} s to make or find); {os.cpu_count()} cpus, {load()}"
        )
        peer_cmd = [gdaltindex, "-f", "GPKG", "INDEX", *map(str, files)]
        workers = ["--workers", str(args.workers)] if args.workers else []
        variants = {
            "gdaltindex": peer_cmd,
            "init --from --no-sha256": [
                orthospec,
                "init",
                "DRAFT",
                "--from",
                str(source),
                "--sensor",
                "satellite",
                "--id",
                "BENCH",
                "--no-sha256",
                *workers,
            ],
            "init --from (SHA-256)": [
                orthospec,
                "init",
                "DRAFT",
                "--from",
                str(source),
                "--sensor",
                "satellite",
                "--id",
                "BENCH",
                *workers,
            ],
        }
        best: dict[str, tuple[float, float, float, str]] = {}
        for r in range(args.rounds):
            for k, (name, cmd) in enumerate(variants.items()):
                out = Path(tmp) / f"out-{r}-{k}"
                out.mkdir()
                target = str(out / ("index.gpkg" if name == "gdaltindex" else "draft"))
                wall, tree_mb, one_mb = run([target if c in ("INDEX", "DRAFT") else c for c in cmd])
                shutil.rmtree(out, ignore_errors=True)
                print(
                    f"  round {r + 1} {name}: {wall:.2f} s, peak {one_mb:.0f} MB (one process), "
                    f"{tree_mb:.0f} MB (process tree); {load()}"
                )
                old = best.get(name)
                if old is None or wall < old[0]:
                    best[name] = (wall, tree_mb, one_mb, load())
        peer = best["gdaltindex"][0]
        print(f"best of {args.rounds}:")
        for name, (wall, tree_mb, one_mb, ld) in best.items():
            ratio = "" if name == "gdaltindex" else f"; {wall / peer:.2f}x gdaltindex"
            print(
                f"  {name}: {wall:.2f} s{ratio}, peak {one_mb:.0f} MB (one process), {tree_mb:.0f} MB (tree); {ld}"
            )
        nohash, hashed = best["init --from --no-sha256"][0], best["init --from (SHA-256)"][0]
        tree = max(v[1] for k, v in best.items() if k != "gdaltindex")
        print(
            f"init --from without hashing: {nohash / peer:.2f}x gdaltindex (target <= 1.5x); with SHA-256: "
            f"{hashed:.2f} s ({hashed / peer:.2f}x); peak memory {tree:.0f} MB, process tree (target < 500 MB)"
        )


if __name__ == "__main__":
    main()
