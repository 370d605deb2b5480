"""Benchmark: latency of whole orthospec commands against bare-Python peers, in one run.

Usage::

    .venv/bin/python benchmarks/startup.py [--rounds 5] [--cache cold|warm|both]

Each command runs in its own subprocess (the interpreter start-up is part of what a user waits
for), best of ``--rounds``; rounds interleave the commands and their peers so that load from
other processes on the machine affects both sides alike. Printed ratios (issue 14 targets):

* ``orthospec --help`` and ``--version`` against ``python -c "import click, yaml"`` (<= 4x);
* ``spec validate specs/jrc-v3.yaml`` and ``explain JRC-12.7-RMSEX --profile jrc-v3`` against a
  bare ``yaml.safe_load`` of jrc-v3.yaml in a fresh interpreter (<= 3x, cold profile cache).

"Cold" points ``XDG_CACHE_HOME`` at a fresh empty directory for every run, "warm" at one
directory that a first untimed run has filled (the profile cache lives in the user cache dir).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROFILE = ROOT / "specs" / "jrc-v3.yaml"
ORTHOSPEC = [sys.executable, "-m", "orthospec.cli.main"]
if (Path(sys.executable).parent / "orthospec").exists():
    ORTHOSPEC = [str(Path(sys.executable).parent / "orthospec")]

PEERS = {
    "import click, yaml": [sys.executable, "-c", "import click, yaml"],
    "yaml.safe_load(jrc-v3)": [sys.executable, "-c",
                               "import sys, yaml; yaml.safe_load(open(sys.argv[1], 'rb'))",
                               str(PROFILE)],
}
# (label, argv after the orthospec executable, peer label, target ratio, profile-cache sensitive)
COMMANDS = [
    ("--help", ["--help"], "import click, yaml", 4.0, False),
    ("--version", ["--version"], "import click, yaml", 4.0, False),
    (
        "spec validate jrc-v3",
        ["spec", "validate", str(PROFILE)],
        "yaml.safe_load(jrc-v3)",
        3.0,
        True,
    ),
    (
        "explain JRC-12.7-RMSEX",
        ["explain", "JRC-12.7-RMSEX", "--profile", "jrc-v3"],
        "yaml.safe_load(jrc-v3)",
        3.0,
        True,
    ),
]


def timed(cmd: list[str], env: dict[str, str]) -> float:
    """Wall seconds of one run of ``cmd``; a failing command aborts the benchmark."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t0
    if proc.returncode not in (0, 1):
        raise SystemExit(
            f"{' '.join(cmd)} failed ({proc.returncode}): "
            f"{proc.stderr.decode(errors='replace').strip()[-400:]}"
        )
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--cache", choices=["cold", "warm", "both"], default="both")
    args = ap.parse_args()
    modes = ["cold", "warm"] if args.cache == "both" else [args.cache]
    best: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="orthospec-startup-") as tmp:
        warm_dir = Path(tmp) / "warm"
        warm_dir.mkdir()
        base = dict(os.environ)
        warm_env = base | {"XDG_CACHE_HOME": str(warm_dir)}
        for _label, argv, _peer, _target, _cached in COMMANDS:  # fill the warm cache, untimed
            subprocess.run(ORTHOSPEC + argv, capture_output=True, env=warm_env, cwd=ROOT)
        for _ in range(args.rounds):
            for name, cmd in PEERS.items():
                best[name] = min(best.get(name, 1e9), timed(cmd, base))
            for label, argv, _peer, _target, cached in COMMANDS:
                for mode in modes if cached else ["cold"]:
                    cold = Path(tempfile.mkdtemp(prefix="cold-", dir=tmp))
                    env = warm_env if mode == "warm" else base | {"XDG_CACHE_HOME": str(cold)}
                    key = f"{label} ({mode} cache)" if cached else label
                    best[key] = min(best.get(key, 1e9), timed(ORTHOSPEC + argv, env))
    print(
        f"orthospec start-up benchmark: best of {args.rounds}, load average "
        f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} cpus; {sys.version.split()[0]}"
    )
    for name in PEERS:
        print(f"  peer  {name:32s} {best[name]:6.3f} s")
    for label, _argv, peer, target, cached in COMMANDS:
        for mode in modes if cached else ["cold"]:
            key = f"{label} ({mode} cache)" if cached else label
            ratio = best[key] / best[peer]
            flag = "ok" if ratio <= target else "OVER"
            print(
                f"  {key:38s} {best[key]:6.3f} s  = {ratio:5.1f}x {peer:24s} "
                f"(target <= {target:g}x: {flag})"
            )


if __name__ == "__main__":
    main()
