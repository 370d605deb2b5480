"""Benchmark: checkpoint statistics and blunder decisions on 1,000,000 points.

Prints wall time (best of ``--repeat``) and peak traced memory (tracemalloc, numpy buffers
included) for each step, plus the process's peak RSS. Usage::

    .venv/bin/python benchmarks/accuracy.py [--n 1000000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import resource
import time
import tracemalloc
from collections.abc import Callable
from typing import Any

import numpy as np

from orthospec.measures.accuracy import accuracy_stats, detect_blunders


def _measure(label: str, fn: Callable[[], Any], repeat: int) -> Any:
    best = float("inf")
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"{label:<48} {best:8.3f} s   peak {peak / 2**20:8.1f} MiB")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    n = args.n
    rng = np.random.default_rng(0)
    dx, dy, dz = rng.normal(0.05, 0.3, (3, n))
    ids = np.array([f"CP{i:07d}" for i in range(n)], dtype=object)
    print(f"n = {n:,} checkpoints (numpy {np.__version__})")
    s = _measure("accuracy_stats (dx, dy, dz), no id checks",
                 lambda: accuracy_stats(dx, dy, dz, validate=False), args.repeat)
    _measure("accuracy_stats with id/finite validation",
             lambda: accuracy_stats(dx, dy, dz, ids=ids), args.repeat)
    _measure("detect_blunders (stats + per-point decisions)",
             lambda: detect_blunders(dx, dy, dz, ids=ids), 1)
    print(f"check: RMSE_r {s.rmse_r:.4f} m, CE90 {s.ce90:.4f}")
    print(f"process peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
