"""Print the hostile corpus as a table: ``python -m tests.hostile [--timeout S] [NAME ...]``."""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from .cases import CASES
from .check import run_case


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("names", nargs="*")
    ap.add_argument("--timeout", type=float, default=60.0)
    a = ap.parse_args()
    names = a.names or list(CASES)
    print(f"{len(names)} hostile cases")
    print(f"| {'case':38} | exit | seconds | peak MB | ok | problem")
    bad = 0
    for name in names:
        with tempfile.TemporaryDirectory(prefix=f"hostile-{name}-") as tmp:
            o = run_case(name, Path(tmp), timeout=a.timeout)
        exit_text = "kill" if o.run.exit is None else str(o.run.exit)
        ok = "yes" if not o.problems else "NO"
        bad += bool(o.problems)
        print(
            f"| {name:38} | {exit_text:>4} | {o.run.seconds:7.1f} | {o.run.peak_mb:7.0f} | {ok:3}| "
            f"{'; '.join(o.problems)[:160]}",
            flush=True,
        )
    print(f"{len(names) - bad}/{len(names)} cases as required")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
