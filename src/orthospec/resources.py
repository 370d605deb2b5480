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
