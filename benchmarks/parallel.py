"""Benchmark: speed-up of 2 worker processes and of a 2-worker Dask LocalCluster over 1.

Usage::

    .venv/bin/python benchmarks/parallel.py [--tiles 50] [--side 1024]

Writes ``--tiles`` 3-band uint8 GeoTIFF tiles into a temporary directory and scans them with
the full default settings (exact statistics, histograms, luminosity, noise,
misregistration) three ways. Pool and cluster start-up are included in the times (that is
what a user waits for); the cluster start-up is also printed on its own.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import rasterio
from affine import Affine

from orthospec.raster.parallel import scan_images


def make_tiles(folder: Path, n: int, side: int) -> list[Path]:
    rng = np.random.default_rng(0)
    x = np.linspace(0, 12, side)
    base = (np.sin(x[None, :] + x[:, None]) + 1) * 90 + 20
    out = []
    for i in range(n):
        a = np.clip(base[None] + rng.normal(0, 6, (3, side, side)), 1, 255).astype(np.uint8)
        p = folder / f"tile_{i:03d}.tif"
        with rasterio.open(p, "w", driver="GTiff", width=side, height=side, count=3,
                           dtype="uint8", tiled=True, blockxsize=256, blockysize=256,
                           crs="EPSG:25832", nodata=0, photometric="RGB",
                           transform=Affine(0.2, 0, 500000 + i * side * 0.2, 0, -0.2,
                                            5600000)) as ds:
            ds.write(a)
        out.append(p)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tiles", type=int, default=50)
    ap.add_argument("--side", type=int, default=1024)
    args = ap.parse_args()
    print(f"cpus: {os.cpu_count()}, load average before: {os.getloadavg()[0]:.2f} "
          "(other jobs on the machine take cores and memory bandwidth)")
    with tempfile.TemporaryDirectory(prefix="orthospec-par-") as tmp:
        files = make_tiles(Path(tmp), args.tiles, args.side)
        mb = sum(f.stat().st_size for f in files) / 1e6
        print(f"{len(files)} tiles of {args.side}x{args.side}x3 uint8, {mb:.0f} MB")
        times = {}
        t0 = time.perf_counter()
        ref = scan_images(files, workers=1)
        times["1 process"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        two = scan_images(files, workers=2)
        times["2 worker processes"] = time.perf_counter() - t0
        from distributed import LocalCluster

        t0 = time.perf_counter()
        import dask

        # workers spawned without the nanny's single-thread BLAS and malloc-trim overrides;
        # orthospec also tunes the allocator of workers it did not start (raster.parallel)
        with dask.config.set({"distributed.nanny.pre-spawn-environ": {}}), \
                LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                             dashboard_address=None) as cluster:
            t_cluster = time.perf_counter() - t0
            t1 = time.perf_counter()
            dsk = scan_images(files, scheduler=cluster.scheduler_address)
            times["dask LocalCluster(2)"] = time.perf_counter() - t1 + t_cluster
        same = all(a.to_dict()["band1.mean"] == b.to_dict()["band1.mean"] ==
                   c.to_dict()["band1.mean"] for a, b, c in zip(ref, two, dsk, strict=True))
        for name, t in times.items():
            print(f"{name:22s} {t:6.2f} s  speed-up {times['1 process'] / t:4.2f}x  "
                  f"{len(files) / t:5.1f} files/s")
        print(f"dask cluster start-up {t_cluster:.2f} s (included above)")
        print(f"identical results: {same}; load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
