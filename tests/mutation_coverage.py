"""The mutation suite's coverage line, computed from its table and the shipped profiles (YAML only).

Kept apart from tests/test_mutations.py so that the pytest controller can print it under xdist
(`make test` runs `pytest -n 2`): the controller never imports test modules, but tests/conftest.py
can register :class:`CoverageReport` (see the lead request in the issue 12 report).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
TABLE_FILE = Path(__file__).parent / "data" / "mutations.yaml"
PLUGIN_NAME = "orthospec-mutation-coverage"


def mandatory_automatic(profile: str) -> set[str]:
    """Ids of the mandatory, non-manual rules a shipped profile defines."""
    rules = yaml.safe_load((ROOT / "specs" / f"{profile}.yaml").read_text(encoding="utf-8"))[
        "rules"
    ]
    return {r["id"] for r in rules if r.get("level") == "mandatory" and not r.get("manual")}


def coverage_line() -> str:
    table = yaml.safe_load(TABLE_FILE.read_text(encoding="utf-8"))
    total = sum(len(mandatory_automatic(p)) for p in table["profiles"])
    cases = [(g["profile"], c) for g in table["groups"] for c in g["cases"]]
    planted = len({(p, c["rule"]) for p, c in cases})
    refused = len({(p, c["rule"]) for p, c in cases if "refused" in c})
    exceptions = len(table.get("exceptions") or [])
    return (
        f"mutation coverage: {planted}/{total} mandatory automatic rules planted "
        f"({refused} of them refused at load, exit 2), {exceptions} listed exceptions "
        "(tests/data/mutations.yaml)"
    )


class CoverageReport:
    """Prints the coverage line in the terminal summary."""

    @staticmethod
    def pytest_terminal_summary(terminalreporter: Any) -> None:
        terminalreporter.write_sep("-", "mutation suite")
        terminalreporter.write_line(coverage_line())
