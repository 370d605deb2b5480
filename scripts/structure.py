#!/usr/bin/env python3
"""Structure facts of src/orthospec in a checkout (issue 28): the largest file, files over 600 lines,
functions over 80 lines, `dict[str, Any]` annotations, lines over 100 characters.

Usage: python scripts/structure.py [CHECKOUT]   (default: this checkout; e.g. a worktree of 95a2ffd)
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path


def facts(checkout: Path) -> dict[str, object]:
    root = checkout / "src" / "orthospec"
    texts = {f: f.read_text(encoding="utf-8") for f in sorted(root.rglob("*.py"))}
    sizes = {f: len(t.splitlines()) for f, t in texts.items()}
    largest = max(sizes, key=lambda f: sizes[f])
    long_functions = sum(
        1
        for t in texts.values()
        for n in ast.walk(ast.parse(t))
        if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)
        and (n.end_lineno or n.lineno) - n.lineno + 1 > 80
    )
    return {
        "files": len(texts),
        "lines": sum(sizes.values()),
        "largest": f"{largest.relative_to(root)} {sizes[largest]}",
        "over_600": sorted((f"{f.relative_to(root)} {n}" for f, n in sizes.items() if n > 600)),
        "functions_over_80": long_functions,
        "dict_str_any": sum(t.count("dict[str, Any]") for t in texts.values()),
        "lines_over_100": sum(
            1 for t in texts.values() for line in t.splitlines() if len(line) > 100
        ),
    }


if __name__ == "__main__":
    got = facts(Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parents[1]))
    for k, v in got.items():
        print(f"{k}: {', '.join(v) if isinstance(v, list) else v}")
