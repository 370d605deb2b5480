"""Where the shipped specs and report templates live (wheel data or the source checkout)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

_HERE = Path(__file__).resolve().parent


@cache
def data_dir(name: str) -> Path:
    """``specs`` or ``reports/templates``: packaged copy first, then the repository's folder."""
    packaged = _HERE / "_data" / name
    if packaged.is_dir():
        return packaged
    checkout = _HERE.parent.parent / name
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(f"orthospec data folder {name!r} not found (broken installation)")


def specs_dir() -> Path:
    return data_dir("specs")


def templates_dir() -> Path:
    return data_dir("reports/templates")


def shown(path: str | Path) -> str:
    """How a message names a file: a shipped data file as ``specs/jrc-v3.yaml``, never by the absolute
    folder it was installed in (which says nothing to the reader and differs between machines); any
    other path as given."""
    text = str(path)
    try:
        p = Path(path).resolve()
    except (OSError, RuntimeError, ValueError):
        return text
    for name in ("specs", "reports/templates"):
        try:
            return f"{name}/{p.relative_to(data_dir(name).resolve()).as_posix()}"
        except (ValueError, FileNotFoundError):
            continue
    return text
