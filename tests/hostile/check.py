"""Run one hostile case and judge it (shared by the pytest module and the table runner)."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from .cases import CASES, MARKER_TEXT, Setup, World
from .harness import Run, all_output_text, run_cli, tree_state


@dataclass
class Outcome:
    name: str
    setup: Setup
    run: Run
    problems: list[str]


def _error_records(w: World, setup: Setup) -> list[dict]:
    q = w.out / "qcr.json"
    if not q.is_file():
        return []
    doc = json.loads(q.read_text(encoding="utf-8"))
    return [r for r in doc.get("records", []) if r.get("verdict") == "error"]


def run_case(name: str, base: Path, *, timeout: float = 60.0) -> Outcome:
    w = World(base)
    setup = CASES[name](w)
    before = tree_state(w.delivery)
    outside_before = tree_state(w.outside)
    marker_hashes = [hashlib.sha256(p.read_bytes()).hexdigest() for p in w.markers()]
    run = run_cli(setup.args, cwd=setup.cwd or w.work, timeout=timeout)
    problems: list[str] = []
    if run.timed_out:
        problems.append(f"timed out after {timeout:.0f} s")
    if "Traceback" in run.stderr or "Traceback" in run.stdout:
        problems.append("traceback in the output")
    if "internal error" in run.stderr:
        problems.append("internal error: " + run.stderr.strip().splitlines()[-1][:200])
    if run.exit is not None and run.exit not in (0, 1, 2, 3):
        problems.append(f"exit {run.exit} (killed by a signal or the memory cap?)")
    if run.exit == 2 and "error:" not in run.stderr and "Error:" not in run.stderr:
        problems.append("exit 2 without an error message")
    message = run.stderr
    if setup.expect == "exit2":
        if run.exit != 2:
            problems.append(f"expected exit 2, got {run.exit}")
        for n in setup.names:
            if n not in message:
                problems.append(f"message does not name {n!r}: {message.strip()[:300]!r}")
    elif setup.expect == "record":
        if run.exit == 2:
            for n in setup.names:
                if n not in message:
                    problems.append(f"message does not name {n!r}: {message.strip()[:300]!r}")
        else:
            errs = _error_records(w, setup)
            hit = [r for r in errs if all(n in json.dumps(r) for n in setup.names)]
            if not hit:
                problems.append(f"no error record naming {setup.names} (exit {run.exit}, "
                                f"{len(errs)} error records)")
    after = tree_state(w.delivery) if w.delivery.exists() else {}
    if after != before:
        changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
        problems.append(f"delivery tree changed: {changed[:5]}")
    if tree_state(w.outside) != outside_before:
        problems.append("the folder outside the delivery changed")
    leaked = (
        all_output_text(w.out, *setup.extra_outputs) + run.stdout.encode() + run.stderr.encode()
    )
    if MARKER_TEXT.encode() in leaked:
        problems.append("marker text found in the outputs")
    for h in marker_hashes:
        if h.encode() in leaked:
            problems.append("a marker file's SHA-256 found in the outputs")
    if not run.timed_out:
        if run.seconds > setup.seconds:
            problems.append(f"took {run.seconds:.1f} s (budget {setup.seconds:.0f} s)")
        if run.peak_mb > setup.peak_mb:
            problems.append(f"peak RSS {run.peak_mb:.0f} MB (budget {setup.peak_mb:.0f} MB)")
    if setup.check is not None and not problems:
        try:
            setup.check(w)
        except AssertionError as exc:
            problems.append(f"case check failed: {exc}")
    return Outcome(name, setup, run, problems)
