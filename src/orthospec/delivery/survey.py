"""The checker's survey of check points and the hand list fed back, for ``measure checkpoints``.

Both are the checker's files, outside the delivery, parsed by the one table parser of orthospec
(:func:`orthospec.delivery.table.parse_csv`: limits, field counts, number and boolean cells, and
every complaint naming file, row and column).

* **Survey** (the "true" coordinates, JRC §12.6): ``point_id`` (or ``id``), ``x``, ``y``; optional
  ``z``, ``block``, ``image_id`` (the image to measure the point on), ``source``,
  ``precision_xy`` (>= 0, the survey's planimetric RMSE), ``chip`` (the reference chip's file name
  in a chip library). Ids are unique; coordinates finite.
* **Hand list, CSV form** (the GeoPackage form is read in ``orthospec.raster.checkpoints``):
  ``point_id``, ``status`` (``to measure`` | ``measured`` | ``unusable``), ``x``, ``y`` (where the
  checker found the point on the image; required when measured), ``comment``; other columns the tool
  wrote (``image_id``, ``reason`` ...) are read as text and ignored.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DeliveryError
from .convention import ColumnSpec, TableSpec
from .table import header_names, parse_csv
from .table_bounds import Limits, read_table_bytes, utf8_body

__all__ = ["HAND_STATUSES", "HandEntry", "SurveyPoint", "hand_entries", "read_hand_csv",
           "read_survey"]

#: the states of a hand-list row: the checker changes ``to measure`` to one of the others
HAND_STATUSES: tuple[str, ...] = ("to measure", "measured", "unusable")

_SURVEY_COLUMNS: dict[str, tuple[str, bool, str, float | None]] = {
    # name: (type, required, description, min)
    "point_id": ("text", True, "Check point identifier.", None),
    "x": ("number", True, "Surveyed ('true') easting.", None),
    "y": ("number", True, "Surveyed ('true') northing.", None),
    "z": ("number", False, "Surveyed height.", None),
    "block": ("text", False, "Block or site of the point.", None),
    "image_id": (
        "text",
        False,
        "Image to measure the point on (default: the image that holds it best).",
        None,
    ),
    "source": ("text", False, "How the coordinates were surveyed.", None),
    "precision_xy": ("number", False, "Planimetric accuracy (RMSE) of the survey.", 0.0),
    "chip": ("text", False, "Reference chip of the point in a chip library (file name).", None),
}

_HAND_COLUMNS: dict[str, tuple[str, bool, str]] = {
    "point_id": ("text", True, "Check point identifier (as in the survey)."),
    "status": ("text", True, "to measure | measured | unusable."),
    "x": ("number", False, "Easting of the point as found on the image (when measured)."),
    "y": ("number", False, "Northing of the point as found on the image (when measured)."),
    "comment": ("text", False, "The checker's note."),
}


@dataclass(frozen=True)
class SurveyPoint:
    """One surveyed point; ``row`` is its 1-based data row in ``file``."""

    point_id: str
    x: float
    y: float
    z: float | None
    block: str | None
    image_id: str | None
    source: str | None
    precision_xy: float | None
    chip: str | None
    file: str
    row: int


@dataclass(frozen=True)
class HandEntry:
    """The checker's answer for one point of the hand list (``x``/``y`` set when measured)."""

    point_id: str
    status: str
    x: float | None
    y: float | None
    comment: str
    file: str
    row: int
    crs: str | None = None  # the CRS of x and y when the file states one (a GeoPackage layer)


def _read_body(path: str | Path, what: str) -> tuple[str, bytes]:
    name = str(path)
    p = Path(path)
    if not p.is_file():
        raise DeliveryError(f"{what} not found", file=name)
    return name, utf8_body(read_table_bytes(p, file=name, limits=Limits.from_env()), file=name)


def _text(v: object) -> str | None:
    return None if v is None or (isinstance(v, float) and np.isnan(v)) else str(v)


def _number(v: object) -> float | None:
    return None if v is None or (isinstance(v, float) and np.isnan(v)) else float(v)  # type: ignore[arg-type]


def read_survey(path: str | Path) -> list[SurveyPoint]:
    """The surveyed points of a CSV file, in file order.

    Raises
    ------
    DeliveryError
        Unreadable file, missing or unknown columns (listing the expected ones), a bad or
        non-finite number, an empty id or coordinate, a duplicated id (its rows named), no point.
    """
    name, body = _read_body(path, "survey file")
    header = header_names(body)
    id_col = "id" if "id" in header and "point_id" not in header else "point_id"
    cols = {
        ("id" if c == "point_id" and id_col == "id" else c): ColumnSpec(
            "id" if c == "point_id" and id_col == "id" else c, t, None, req, d, lo  # type: ignore[arg-type]
        )
        for c, (t, req, d, lo) in _SURVEY_COLUMNS.items()
    }
    df = parse_csv(
        body, TableSpec("survey", "checkpoint", id_col, "check point survey", cols), file=name
    )
    if df.empty:
        raise DeliveryError("no survey point (only a header)", file=name)
    rows = df["_row"].to_numpy(np.int64)

    def col(c: str) -> list[object]:
        return df[c].tolist() if c in df else [None] * len(df)

    out = []
    for pid, x, y, z, block, image, source, prec, chip, row in zip(
        col(id_col),
        col("x"),
        col("y"),
        col("z"),
        col("block"),
        col("image_id"),
        col("source"),
        col("precision_xy"),
        col("chip"),
        rows.tolist(),
        strict=True,
    ):
        out.append(
            SurveyPoint(
                str(pid),
                float(x),
                float(y),
                _number(z),
                _text(block),
                _text(image),
                _text(source),
                _number(prec),
                _text(chip),
                name,
                int(row),
            )
        )
    return out


def read_hand_csv(path: str | Path) -> list[HandEntry]:
    """The hand list completed by the checker, CSV form (see the module docstring).

    Raises
    ------
    DeliveryError
        naming file, row and column: an unknown status, a measured point without finite x and y,
        a duplicated id, missing columns.
    """
    name, body = _read_body(path, "hand list")
    header = header_names(body)
    cols = {c: ColumnSpec(c, t, None, req, d) for c, (t, req, d) in _HAND_COLUMNS.items()}  # type: ignore[arg-type]
    for h in header:  # what the tool wrote besides: read, not used
        cols.setdefault(h, ColumnSpec(h, "text", None, False, "written by orthospec"))
    df = parse_csv(body, TableSpec("hand", "checkpoint", "point_id", "hand list", cols), file=name)
    rows = df["_row"].tolist()
    xs = df["x"].tolist() if "x" in df else [None] * len(df)
    ys = df["y"].tolist() if "y" in df else [None] * len(df)
    comments = df["comment"].tolist() if "comment" in df else [None] * len(df)
    return hand_entries(
        df["point_id"].tolist(), df["status"].tolist(), xs, ys, comments, file=name, rows=rows
    )


def hand_entries(
    ids: list[object],
    statuses: list[object],
    xs: list[object],
    ys: list[object],
    comments: list[object],
    *,
    file: str,
    rows: list[int],
) -> list[HandEntry]:
    """Validated hand-list entries from columns (shared by the CSV and GeoPackage readers)."""
    out: list[HandEntry] = []
    seen: dict[str, int] = {}
    for pid, status, x, y, comment, row in zip(ids, statuses, xs, ys, comments, rows, strict=True):
        p = _text(pid)
        if not p:
            raise DeliveryError("empty point_id", file=file, row=row, field="point_id")
        if p in seen:
            raise DeliveryError(
                f"duplicate point_id {p!r} (first on row {seen[p]})",
                file=file,
                row=row,
                field="point_id",
            )
        seen[p] = row
        st = (_text(status) or "").strip().lower()
        if st not in HAND_STATUSES:
            raise DeliveryError(
                f"unknown status {status!r}; expected one of: {', '.join(HAND_STATUSES)}",
                file=file,
                row=row,
                field="status",
            )
        fx, fy = _number(x), _number(y)
        if st == "measured":
            for c, v in (("x", fx), ("y", fy)):
                if v is None or not np.isfinite(v):
                    raise DeliveryError(
                        f"a measured point needs a finite {c}", file=file, row=row, field=c
                    )
        out.append(HandEntry(p, st, fx, fy, _text(comment) or "", file, row))
    return out
