"""Declared fields the rules now compute from the files (issue 25), for tests/test_declared_property.py.

Each :class:`DeclaredField` says how to write a drawn value into a copied delivery (a table column on
every row, or a manifest path) and which values to draw. Another helper whose rules now compute a fact
from the files adds its field here (one entry) and the property test covers it: an edited
declaration never turns a REJECTED planted example into ACCEPTED.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hypothesis import strategies as st
from tests.checking import manifest, read_table, write_manifest, write_table


@dataclass(frozen=True)
class DeclaredField:
    name: str
    values: st.SearchStrategy[Any]
    write: Callable[[Path, Any], None]
    #: the delivery must have this table (None: always applicable)
    needs_table: str | None = None
    #: one typical manipulated value (the registry's self-test writes it)
    sample: Any = 3.5


def column(table: str, col: str) -> Callable[[Path, Any], None]:
    """Write the value into ``col`` of every row of ``table`` (the column is added when absent)."""

    def write(d: Path, value: Any) -> None:
        header, rows = read_table(d, table)
        if col not in header:
            header.append(col)
        text = (
            "" if value is None else (str(value).lower() if isinstance(value, bool) else str(value))
        )
        for r in rows:
            r[col] = text
        write_table(d, table, header, rows)

    return write


def manifest_path(dotted: str) -> Callable[[Path, Any], None]:
    def write(d: Path, value: Any) -> None:
        m = manifest(d)
        node = m
        parts = dotted.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
        write_manifest(d, m)

    return write


def _scaled(table: str, cols: tuple[str, ...]) -> Callable[[Path, Any], None]:
    """Multiply numeric columns by the drawn factor (a camera format declared k times larger)."""

    def write(d: Path, factor: Any) -> None:
        header, rows = read_table(d, table)
        for r in rows:
            for c in cols:
                if r.get(c):
                    r[c] = str(round(float(r[c]) * factor))
        write_table(d, table, header, rows)

    return write


_metres = st.floats(min_value=0.05, max_value=30.0, allow_nan=False).map(lambda v: round(v, 3))
_share = st.floats(min_value=0.0, max_value=100.0, allow_nan=False).map(lambda v: round(v, 1))
_dn = st.floats(min_value=0.0, max_value=255.0, allow_nan=False).map(lambda v: round(v, 2))

DECLARED_FIELDS: list[DeclaredField] = [
    DeclaredField("images.gsd", _metres, column("images", "gsd"), "images"),
    DeclaredField("images.acquisition_gsd", _metres, column("images", "acquisition_gsd"), "images"),
    DeclaredField(
        "images.bit_depth",
        st.integers(min_value=1, max_value=16),
        column("images", "bit_depth"),
        "images",
        12,
    ),
    DeclaredField("images.cloud_cover", _share, column("images", "cloud_cover"), "images", 42.0),
    DeclaredField("images.mean_dn", _dn, column("images", "mean_dn"), "images"),
    DeclaredField("images.std_dn", _dn, column("images", "std_dn"), "images"),
    DeclaredField("images.min_dn", _dn, column("images", "min_dn"), "images"),
    DeclaredField("images.max_dn", _dn, column("images", "max_dn"), "images"),
    DeclaredField(
        "scenes.input_pixel_size", _metres, column("scenes", "input_pixel_size"), "scenes"
    ),
    DeclaredField(
        "scenes.resolution_class",
        st.sampled_from(["VHR", "HR", "MR", "LR"]),
        column("scenes", "resolution_class"),
        "scenes",
        "HR",
    ),
    DeclaredField("scenes.cloud_cover", _share, column("scenes", "cloud_cover"), "scenes"),
    DeclaredField(
        "cameras.format",
        st.sampled_from([0.5, 2.0, 3.0, 10.0]),
        _scaled("cameras", ("format_across_px", "format_along_px")),
        "cameras",
        3.0,
    ),
    DeclaredField(
        "product.gsd",
        _metres.map(lambda v: {"value": v, "unit": "m"}),
        manifest_path("product.gsd"),
        sample={"value": 3.5, "unit": "m"},
    ),
    DeclaredField(
        "product.bit_depth",
        st.integers(min_value=1, max_value=16),
        manifest_path("product.bit_depth"),
        sample=12,
    ),
    DeclaredField(
        "product.dem_delivered", st.booleans(), manifest_path("product.dem_delivered"), sample=True
    ),
    DeclaredField(
        "product.extracts", st.booleans(), manifest_path("product.extracts"), sample=False
    ),
]
