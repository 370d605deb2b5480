"""Benchmark: orthospec exact radiometry vs ``gdalinfo -stats -hist`` on the same big GeoTIFF.

Usage::

    .venv/bin/python benchmarks/radiometry.py [--size-mb 400] [--dtype uint8|uint16]
                                              [--compress none|deflate] [--rounds 2]
                                              [--image FILE] [--no-bytecode]

Creates a tiled 3-band GeoTIFF of about ``--size-mb`` MB in a temporary directory, warms the
page cache, then runs each tool in its own subprocess (fair: the same interpreter start-up
cost for orthospec is included) and reads wall time and peak RSS of that very child with
``os.wait4``. orthospec runs three ways: ``stats`` (min/max/mean/std + full histogram, what
gdalinfo computes) and ``full`` (plus luminosity, both noise estimators, misregistration), both
as a bare library scan, and as whole commands (CLI start-up, file checks, scan and the file's
SHA-256): ``command`` is ``orthospec measure radiometry --json`` (by default the job of
``gdalinfo -stats -hist``: exact statistics and histograms) and ``command_full`` adds ``--full``
(the whole JRC §6.3 scan). Issue 14 targets, in one run on the same file: command <= 1.0x
gdalinfo, command_full <= 1.5x, peak memory < 300 MB. Wall and CPU ratios are both printed:
wall time favours the tool that uses more threads while cores are free (orthospec hashes and
counts in threads; gdalinfo is single-threaded) and the single-threaded tool while other work
takes the cores; CPU seconds say how much work each tool does. Report the load average.

The Python children run byte-compiled, as an installed package does (pip compiles every module
at install): bytecode goes to a private ``PYTHONPYCACHEPREFIX`` in the temporary directory and
one untimed warm-up run of each Python child writes it. Without that, an environment with
``PYTHONDONTWRITEBYTECODE`` set (CI, sandboxes) recompiles every edited module at each start,
a cost (compiling the nine modules of this command: about 35 ms here) no installed orthospec
pays; ``--no-bytecode`` measures that case.
Needs ``gdalinfo`` (Debian: ``apt-get install gdal-bin``).
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

ORTHOSPEC = """
import sys, time
t0 = time.perf_counter()
from orthospec.raster.reading import ScanSettings, scan_raster
t1 = time.perf_counter()
full = sys.argv[2] == "full"
s = ScanSettings(noise=full, luminosity=full, misregistration=full)
r = scan_raster(sys.argv[1], s)
print(t1 - t0, time.perf_counter() - t1)
"""

#: The file's SHA-256 alone, as the command computes it (its CPU is part of the command's).
SHA256 = """
import sys
from orthospec.provenance import sha256_file
sha256_file(sys.argv[1])
"""


def make_image(path: Path, size_mb: int, dtype: str, compress: str) -> None:
    """A 3-band tiled GeoTIFF with textured content, written tile-row by tile-row.

    Runs in a child process so that this (measuring) process stays small: a child's peak
    RSS (ru_maxrss) starts from the parent's RSS at fork time.
    """
    import numpy as np
    import rasterio
    from affine import Affine
    from rasterio.windows import Window

    itemsize = np.dtype(dtype).itemsize
    side = int((size_mb * 1e6 / (3 * itemsize)) ** 0.5) // 512 * 512
    top = 255 if dtype == "uint8" else 2047
    profile = dict(driver="GTiff", width=side, height=side, count=3, dtype=dtype, tiled=True,
                   blockxsize=512, blockysize=512, crs="EPSG:25832", nodata=0,
                   transform=Affine(0.2, 0, 500000, 0, -0.2, 5600000), BIGTIFF="IF_SAFER")
    if dtype == "uint16":
        profile["nbits"] = 11
    if compress != "none":
        profile["compress"] = compress
    rng = np.random.default_rng(0)
    x = np.linspace(0, 20, side)
    with rasterio.open(path, "w", **profile) as ds:
        for row in range(0, side, 512):
            y = np.linspace(row / side * 20, (row + 512) / side * 20, 512)[:, None]
            base = (np.sin(x[None, :] + y) + 1) * top / 3
            for b in range(3):
                noise = rng.normal(0, top / 40, (512, side))
                block = np.clip(base * (0.8 + 0.1 * b) + noise + top / 10, 0, top)
                ds.write(block.astype(dtype), b + 1, window=Window(0, row, side, 512))


def run(cmd: list[str], env: dict[str, str] | None = None) -> tuple[float, float, str, float]:
    """Wall seconds, peak RSS (MB) of exactly this child, its stdout and its CPU seconds.

    CPU seconds (user + system) say how much work a tool does even when other processes share
    the cores; wall time says how long one waits for it on this machine now.
    """
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    out = proc.stdout.read() if proc.stdout else ""
    err = proc.stderr.read() if proc.stderr else ""
    _pid, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{cmd[0]} failed ({proc.returncode}): {err.strip()}")
    return wall, usage.ru_maxrss / 1024.0, out, usage.ru_utime + usage.ru_stime


def _self_rss() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size-mb", type=int, default=400)
    ap.add_argument("--dtype", choices=["uint8", "uint16"], default="uint8")
    ap.add_argument("--compress", choices=["none", "deflate"], default="none")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--image", help="use this existing GeoTIFF instead of creating one")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="keep the environment's PYTHONDONTWRITEBYTECODE (no warm-up compile)")
    ap.add_argument("--make", help=argparse.SUPPRESS)
    args = ap.parse_args()
    gdalinfo = shutil.which("gdalinfo")
    if gdalinfo is None:
        raise SystemExit("gdalinfo not found: install it (Debian: apt-get install gdal-bin)")
    gdal_version = subprocess.run([gdalinfo, "--version"], capture_output=True,
                                  text=True).stdout.strip()
    if args.make:
        make_image(Path(args.make), args.size_mb, args.dtype, args.compress)
        return
    print(f"orthospec bench: parent peak RSS {_self_rss():.0f} MB (children inherit it); "
          f"load average at start: {_load()}")
    with tempfile.TemporaryDirectory(prefix="orthospec-bench-") as tmp:
        img = Path(args.image) if args.image else Path(tmp) / "big.tif"
        t0 = time.perf_counter()
        if not args.image:
            subprocess.run([sys.executable, __file__, "--make", str(img), "--size-mb",
                            str(args.size_mb), "--dtype", args.dtype, "--compress",
                            args.compress], check=True)
        size = img.stat().st_size
        print(f"image: {img.name} {size / 1e6:.0f} MB, ready in {time.perf_counter() - t0:.1f} s")
        with open(img, "rb") as fh:  # warm the page cache for both tools
            while fh.read(1 << 24):
                pass
        results: dict[str, list[tuple[float, float]]] = {"gdal": [], "stats": [], "full": [],
                                                           "command": [], "command_full": []}
        cpu: dict[str, list[float]] = {k: [] for k in results}
        cpu["sha256"] = []
        cpu["python"] = []
        orthospec = str(Path(sys.executable).parent / "orthospec")
        inner: dict[str, list[tuple[float, float]]] = {}
        env = dict(os.environ)
        if not args.no_bytecode:  # byte-compiled like an installed package (see the docstring)
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / "pycache")
            for warm in ([gdalinfo, "-stats", "-hist", str(img)],  # its libraries warm too
                         [sys.executable, "-c", ORTHOSPEC, str(img), "full"],
                         [sys.executable, "-c", SHA256, str(img)],
                         [orthospec, "measure", "radiometry", "--json", "--full", str(img)]):
                run(warm, env)
            Path(str(img) + ".aux.xml").unlink(missing_ok=True)
        print("python children: " + ("as the environment says (PYTHONDONTWRITEBYTECODE="
                                     f"{os.environ.get('PYTHONDONTWRITEBYTECODE', '')!r})"
                                     if args.no_bytecode else "byte-compiled (warm-up run)"))
        for _ in range(args.rounds):
            aux = Path(str(img) + ".aux.xml")
            aux.unlink(missing_ok=True)
            w, m, _, c = run([gdalinfo, "-stats", "-hist", str(img)])
            aux.unlink(missing_ok=True)  # gdalinfo caches statistics there
            results["gdal"].append((w, m))
            cpu["gdal"].append(c)
            for mode in ("stats", "full"):
                w, m, out, c = run([sys.executable, "-c", ORTHOSPEC, str(img), mode], env)
                results[mode].append((w, m))
                cpu[mode].append(c)
                imp, scan = (float(v) for v in out.split())
                inner.setdefault(mode, []).append((imp, scan))
            cpu["sha256"].append(run([sys.executable, "-c", SHA256, str(img)], env)[3])
            cpu["python"].append(run([sys.executable, "-c", "pass"], env)[3])
            for key, extra in (("command", []), ("command_full", ["--full"])):
                w, m, _, c = run([orthospec, "measure", "radiometry", "--json", *extra, str(img)],
                                 env)
                results[key].append((w, m))
                cpu[key].append(c)
        best = {k: (min(w for w, _ in v), max(m for _, m in v)) for k, v in results.items()}
        median = {k: sorted(w for w, _ in v)[len(v) // 2] for k, v in results.items()}
        print(f"gdalinfo -stats -hist ({gdal_version}): {best['gdal'][0]:.2f} s, "
              f"peak {best['gdal'][1]:.0f} MB")
        for mode in ("stats", "full"):
            w, m = best[mode]
            imp = min(i for i, _ in inner[mode])
            scan = min(sc for _, sc in inner[mode])
            print(f"orthospec {mode:5s}: {w:.2f} s, peak {m:.0f} MB, "
                  f"time ratio orthospec/gdal = {w / best['gdal'][0]:.2f}  "
                  f"(of which import {imp:.2f} s, scan {scan:.2f} s: scan/gdal = "
                  f"{scan / best['gdal'][0]:.2f})")
        g_cpu = min(cpu["gdal"])
        for key, what, target in (("command", "statistics + histograms", "1.0"),
                                  ("command_full", "--full, the JRC §6.3 scan", "1.5")):
            w, m = best[key]
            print(f"orthospec measure radiometry (whole command, {what} + file checks + SHA-256): "
                  f"{w:.2f} s, peak {m:.0f} MB, {key}/gdal = {w / best['gdal'][0]:.2f} wall, "
                  f"{min(cpu[key]) / g_cpu:.2f} CPU (target <= {target}x, peak < 300 MB); "
                  f"median of the rounds {median[key] / median['gdal']:.2f} wall")
        print("CPU seconds (user+system, least of the rounds): " + ", ".join(
            f"{k} {min(v):.2f} s ({min(v) / g_cpu:.2f}x gdal)" for k, v in cpu.items()))
        floor = min(cpu["stats"]) + min(cpu["sha256"]) - min(cpu["python"])
        print(f"command CPU without CLI and file checks (stats child + sha256 child - one python "
              f"start-up): {floor:.2f} s = {floor / g_cpu:.2f}x gdal")
        print(f"throughput orthospec stats: {size / 1e6 / best['stats'][0]:.0f} MB/s; "
              f"load average at the end: {_load()} on {os.cpu_count()} cpus (other work on the "
              "cores makes wall times noisy: compare the CPU ratios)")


def _load() -> str:
    """The 1, 5 and 15 minute load averages."""
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


if __name__ == "__main__":
    main()
