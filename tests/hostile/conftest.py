"""Print the hostile corpus table after the run (case, exit, seconds, peak MB)."""

from __future__ import annotations

import pytest


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    from .test_hostile import RESULTS

    if not RESULTS:
        return
    tr = terminalreporter
    ok = sum(not o.problems for o in RESULTS.values())
    tr.write_line(f"hostile corpus: {len(RESULTS)} cases, {ok} as required")
    tr.write_line(f"| {'case':38} | exit | seconds | peak MB |")
    for name, o in RESULTS.items():
        ex = "kill" if o.run.exit is None else str(o.run.exit)
        tr.write_line(f"| {name:38} | {ex:>4} | {o.run.seconds:7.1f} | {o.run.peak_mb:7.0f} |")
