"""Score `spec validate` on the tender-author mistake corpus (tests/data/tender-mistakes/).

Each variant is base.yaml (a valid tender profile) with one typical mistake. A variant is *caught*
when `spec validate` exits 2, and *usable* when, besides, it prints exactly one error, located at
the variant's own file and the line of the mistake (never at a shipped profile), at most
MAX_MESSAGE characters long, whose message contains the fix (``fix`` in expected.yaml: what to
write instead, or the name that was meant).

Run as a script for the before -> after counts (any orthospec on the path, old or new)::

    .venv/bin/python tests/tender_mistakes.py            # this checkout
    PYTHONPATH=/path/to/old/src .venv/bin/python tests/tender_mistakes.py
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

import yaml

CORPUS = Path(__file__).resolve().parent / "data" / "tender-mistakes"
#: a usable message fits a few lines of a terminal
MAX_MESSAGE = 600
_ERROR = re.compile(r"^error: (?P<file>[^\n]*?):(?P<line>\d+)(?::(?P<col>\d+))?: (?P<msg>.*)$")


def variants() -> list[dict[str, Any]]:
    return yaml.safe_load((CORPUS / "expected.yaml").read_text(encoding="utf-8"))["variants"]


def run_validate(path: Path) -> tuple[int, list[str]]:
    """Exit code and the error lines of `orthospec spec validate PATH` (in-process)."""
    from click.testing import CliRunner

    from orthospec.cli.main import cli

    res = CliRunner().invoke(cli(), ["spec", "validate", str(path)])  # output: stdout and stderr
    lines = [x for x in res.output.splitlines() if x.startswith("error:")]
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        lines.append(f"error: (traceback) {type(res.exception).__name__}: {res.exception}")
    return res.exit_code, lines


def score(v: dict[str, Any]) -> dict[str, Any]:
    """One variant: caught, usable, and why not."""
    path = CORPUS / v["file"]
    code, errors = run_validate(path)
    out = {
        "file": v["file"],
        "what": v["what"],
        "exit": code,
        "errors": len(errors),
        "first": errors[0] if errors else "",
        "caught": code == 2,
        "usable": False,
        "why": "",
    }
    if code != 2:
        out["why"] = "not caught"
        return out
    if len(errors) != 1:
        out["why"] = f"{len(errors)} messages"
        return out
    m = _ERROR.match(errors[0])
    if not m or Path(m["file"]).name != path.name or int(m["line"]) != v["line"]:
        out["why"] = f"not located at {v['file']}:{v['line']}"
        return out
    if len(errors[0]) > MAX_MESSAGE:
        out["why"] = f"{len(errors[0])} characters (a message is read, not searched)"
        return out
    if not re.search(v["fix"], m["msg"]):
        out["why"] = f"no fix ({v['fix']!r} not in the message)"
        return out
    out["usable"] = True
    return out


def main() -> None:
    rows = [score(v) for v in variants()]
    for r in rows:
        flag = "usable" if r["usable"] else ("caught" if r["caught"] else "MISSED")
        print(f"{flag:7s} {r['file']:40s} {r['why']}")
        if not r["usable"] and r["first"]:
            print(f"        {r['first'][:220]}")
    print(
        f"{sum(r['caught'] for r in rows)} caught, {sum(r['usable'] for r in rows)} with a usable fix, "
        f"of {len(rows)} variants"
    )


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
