"""Check point and GCP surveys with their own headers -> the convention's ``checkpoints`` / ``gcps``.

A surveyor's spreadsheet names its columns in its own words and language ("Punkt", "Rechtswert
[m]", "E_GNSS", "X ortho"), writes decimal commas, puts units in a second header row and a group
title over merged cells. This module finds the header, reads each column's role from common names
(the vocabulary is :data:`WORDS`; docs/INGEST.md prints it), detects the unit and the decimal mark
and *states* each decision in the draft's report. What it cannot decide it refuses, showing the
columns it saw and the mapping to write (:func:`proposal`); a mapping (``--mapping FILE``, and the
one every draft saves as ``ingest/points-mapping.yaml``) is matched on the header, so a second file
in the same layout needs no question.

Nothing is guessed: "X"/"Y" without a direction are read as easting/northing only when the points
then lie on the delivered images and do not in the other order; a file without a stated unit takes
the unit of the delivery's CRS axes only when its points lie on the images; image or reference
coordinates are told apart only by a qualifier in the header (ortho/image/Bild vs GNSS/survey/Soll).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DeliveryError
from .sheets import HEADER_SCAN, Cell, count_guard, read_cells, text_of

#: the convention's columns a survey may fill, per table (specs/delivery-tables.yaml)
COLUMNS = {
    "checkpoints": (
        "point_id",
        "block",
        "x",
        "y",
        "x_ref",
        "y_ref",
        "z",
        "z_ref",
        "image_id",
        "source",
        "excluded",
        "exclusion_reason",
        "precision_xy",
    ),
    "gcps": ("point_id", "block", "x", "y", "z", "precision_xy", "precision_z", "source"),
}
LENGTH_ROLES = frozenset({"x", "y", "z", "x_ref", "y_ref", "z_ref", "precision_xy", "precision_z"})
NUMBER_ROLES = LENGTH_ROLES

#: header words -> meaning (lower case, whole tokens). Languages: en, de, fr, es, it, nl.
WORDS: dict[str, tuple[str, ...]] = {
    "id": (
        "id",
        "point",
        "pt",
        "pkt",
        "punkt",
        "punktnr",
        "punktnummer",
        "pointid",
        "point_id",
        "name",
        "nr",
        "no",
        "num",
        "number",
        "nummer",
        "pid",
        "station",
        "numero",
        "numéro",
        "punto",
        "nom",
        "nombre",
        "code",
        "label",
        "cp",
        "gcp",
        "icp",
        "pnr",
    ),
    "east": (
        "e",
        "east",
        "easting",
        "rechtswert",
        "rw",
        "ost",
        "ostwert",
        "est",
        "este",
        "oost",
        "x_e",
    ),
    "north": ("n", "north", "northing", "hochwert", "hw", "nord", "norte", "noord", "nordwert"),
    "x": ("x",),
    "y": ("y",),
    "z": (
        "z",
        "h",
        "height",
        "elev",
        "elevation",
        "höhe",
        "hoehe",
        "alt",
        "altitude",
        "hgt",
        "ellh",
        "altezza",
        "hauteur",
        "cota",
        "quota",
    ),
    "ref": (
        "ref",
        "reference",
        "referenz",
        "soll",
        "true",
        "survey",
        "surveyed",
        "gnss",
        "gps",
        "rtk",
        "terrain",
        "ground",
        "field",
        "known",
        "vermessung",
        "vermessen",
        "geodetic",
        "terrestrial",
        "référence",
        "referencia",
        "riferimento",
        "check",
    ),
    "image": (
        "img",
        "image",
        "ortho",
        "orthofoto",
        "orthophoto",
        "orthoimage",
        "photo",
        "bild",
        "measured",
        "meas",
        "observed",
        "obs",
        "ist",
        "mesuré",
        "mesure",
        "medido",
        "misurato",
        "map",
    ),
    "delta": (
        "d",
        "delta",
        "diff",
        "difference",
        "differenz",
        "residual",
        "residuum",
        "abw",
        "abweichung",
        "error",
        "err",
        "écart",
        "ecart",
        "dx",
        "dy",
        "dz",
        "de",
        "dn",
        "dh",
    ),
    "block": ("block", "lot", "los", "site", "bloc", "lotto", "lote"),
    "image_id": ("image_id", "imageid", "tile", "kachel", "photo_id", "bildnr", "scene", "dalle"),
    "source": (
        "source",
        "quelle",
        "method",
        "methode",
        "méthode",
        "origine",
        "fuente",
        "fonte",
        "instrument",
    ),
    "precision": (
        "precision",
        "prec",
        "sigma",
        "accuracy",
        "genauigkeit",
        "std",
        "stddev",
        "rms",
        "rmse",
        "précision",
        "precisión",
        "precisione",
    ),
    "excluded": (
        "excluded",
        "exclude",
        "ausgeschlossen",
        "blunder",
        "ausreisser",
        "ausreißer",
        "exclu",
        "excluido",
        "escluso",
    ),
    "reason": ("reason", "grund", "ausschlussgrund", "raison", "motivo"),
}
UNITS = {
    "m": "m",
    "meter": "m",
    "metre": "m",
    "meters": "m",
    "metres": "m",
    "ft": "ft",
    "feet": "ft",
    "usft": "usft",
    "us-ft": "usft",
    "ftus": "usft",
    "us_ft": "usft",
    "survey ft": "usft",
}
_TOKEN = re.compile(r"[a-zäöüßéèêáíóúñç0-9]+")
_UNIT_IN = re.compile(
    r"[\[(]\s*([a-z_ -]+?)\s*[\])]|\bin\s+(m|ft|usft|meter|metre|meters|metres|feet)\b"
)
_NUM_DOT = re.compile(r"[+-]?(\d+\.\d+|\d+|\.\d+)([eE][+-]?\d+)?")
_NUM_COMMA = re.compile(r"[+-]?\d+,\d+")
_THOUSANDS_DOT_COMMA = re.compile(r"[+-]?\d{1,3}(\.\d{3})+,\d+")
_THOUSANDS_COMMA_DOT = re.compile(r"[+-]?\d{1,3}(,\d{3})+\.\d+")
_AMBIGUOUS_COMMA = re.compile(r"[+-]?\d{1,3},\d{3}")


class Ambiguous(DeliveryError):
    """A survey layout this module will not decide; the message shows the columns and the mapping."""


@dataclass
class Column:
    index: int
    name: str
    kind: str  # number | text | empty
    unit: str | None
    sample: str

    @property
    def letter(self) -> str:
        n, s = self.index + 1, ""
        while n:
            n, r = divmod(n - 1, 26)
            s = chr(65 + r) + s
        return s

    def describe(self) -> str:
        u = f", {self.unit}" if self.unit else ""
        return f"{self.letter} {self.name!r} ({self.kind}{u}; e.g. {self.sample!r})"


@dataclass
class Layout:
    """How one survey file reads: its table, header rows, column roles, unit and decimal mark."""

    table: str
    header: list[str]
    roles: dict[str, str]
    unit: str | None
    decimal: str
    header_rows: int
    #: why each decision was taken (lines of the draft's report)
    said: list[str] = field(default_factory=list)

    def to_mapping(self, files: Sequence[str]) -> dict[str, Any]:
        return {
            "match": list(self.header),
            "table": self.table,
            "columns": dict(self.roles),
            "unit": self.unit,
            "decimal": self.decimal,
            "files": list(files),
        }


@dataclass
class Context:
    """What the rest of the draft knows that a survey's reading may use (all optional)."""

    #: (left, bottom, right, top) of every readable image, in the delivery's CRS
    footprints: list[tuple[str, tuple[float, float, float, float]]] = field(default_factory=list)
    crs_unit: str | None = None
    crs_name: str | None = None
    #: block id -> shapely polygon (outlines in the delivery's CRS)
    outlines: dict[str, Any] = field(default_factory=dict)
    #: mapping layouts given (``--mapping``)
    layouts: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class PointsRead:
    file: str
    layout: Layout
    rows: int
    csv_text: str
    notes: list[str]
    outside: list[str] = field(default_factory=list)
    #: columns with a value in at least one row
    filled: set[str] = field(default_factory=set)
    #: rows written without a block
    unblocked: int = 0


def tokens(name: str) -> list[str]:
    low = name.lower().replace("_", " ")
    return _TOKEN.findall(low)


def _has(toks: list[str], key: str) -> bool:
    words = WORDS[key]
    return any(t in words for t in toks) or any(
        ("_".join(toks[i : i + 2])) in words for i in range(len(toks) - 1)
    )


def unit_of(name: str) -> str | None:
    low = name.lower()
    for m in _UNIT_IN.finditer(low):
        u = (m.group(1) or m.group(2) or "").strip()
        if u in UNITS:
            return UNITS[u]
    toks = tokens(name)
    if toks and toks[-1] in ("m", "ft", "usft") and len(toks) > 1:
        return UNITS[toks[-1]]
    return None


def _dotted(text: str, decimal: str) -> str | None:
    """A number's text with a decimal point and no thousands separators, or None if not a number."""
    t = text.strip().replace("\u00a0", "").replace(" ", "").replace("'", "")
    if decimal == ",":
        if _THOUSANDS_DOT_COMMA.fullmatch(t):
            t = t.replace(".", "")
        t = t.replace(",", ".")
    elif _THOUSANDS_COMMA_DOT.fullmatch(t):
        t = t.replace(",", "")
    return t if _NUM_DOT.fullmatch(t) else None


def parse_number(text: str, decimal: str) -> float | None:
    t = _dotted(text, decimal)
    if t is None:
        return None
    v = float(t)
    return v if np.isfinite(v) else None


def number_text(v: Cell, decimal: str) -> str | None:
    """The cell as a number written with a dot, digits kept (no float round trip for text)."""
    if v is None:
        return None
    if isinstance(v, bool):
        return None
    if isinstance(v, int | float):
        return repr(float(v)) if isinstance(v, float) and not float(v).is_integer() else str(int(v))
    return _dotted(str(v), decimal)


def _decimal(samples: list[str], file: str) -> tuple[str, str | None]:
    """The file's decimal mark from its number-like text cells, and the example that decided it."""
    comma = [
        s
        for s in samples
        if (_NUM_COMMA.fullmatch(s) and not _AMBIGUOUS_COMMA.fullmatch(s))
        or _THOUSANDS_DOT_COMMA.fullmatch(s)
    ]
    dot = [
        s for s in samples if re.fullmatch(r"[+-]?\d+\.\d+", s) or _THOUSANDS_COMMA_DOT.fullmatch(s)
    ]
    ambiguous = [s for s in samples if _AMBIGUOUS_COMMA.fullmatch(s)]
    if comma and dot:
        raise Ambiguous(
            f"numbers written with a decimal comma ({comma[0]!r}) and a decimal point ({dot[0]!r}) "
            "in one file: one decimal mark per file",
            file=file,
        )
    if comma:
        return ",", comma[0]
    if ambiguous and not dot:
        raise Ambiguous(
            f"{ambiguous[0]!r} may be a number with a decimal comma or with a thousands separator; "
            "state it in the mapping (decimal: ',' or '.')",
            file=file,
        )
    return ".", dot[0] if dot else None


def _is_number_like(v: Cell) -> bool:
    if v is None or isinstance(v, bool):
        return False
    if isinstance(v, int | float):
        return True
    t = str(v).strip().replace("\u00a0", "").replace(" ", "").replace("'", "")
    return bool(
        _NUM_DOT.fullmatch(t)
        or _NUM_COMMA.fullmatch(t)
        or _THOUSANDS_DOT_COMMA.fullmatch(t)
        or _THOUSANDS_COMMA_DOT.fullmatch(t)
    )


# ------------------------------------------------------------------ header and columns


def _find_header(
    first: list[list[Cell]], merged: list[tuple[int, int, int, int]], file: str
) -> tuple[int, list[str], list[str]]:
    """(index of the first data row, combined column names, notes) of a sheet's first rows."""

    def numeric(row: list[Cell]) -> int:
        return sum(_is_number_like(c) for c in row)

    data = None
    for i, row in enumerate(first):
        if numeric(row) >= 2 and (i + 1 >= len(first) or numeric(first[i + 1]) >= 2):
            data = i
            break
    if data is None:
        raise DeliveryError(
            f"no data rows found in the first {len(first)} rows (a row with two or more numbers)",
            file=file,
        )
    above = [i for i in range(data) if sum(c is not None for c in first[i]) > 1]
    if not above:
        raise DeliveryError(
            f"no header row above the first data row (row {data + 1}): the columns have no names",
            file=file,
        )
    header_rows = above[-3:]
    width = max(len(first[i]) for i in range(data, min(len(first), data + 5)))
    notes = []
    names = [[] for _ in range(width)]  # type: list[list[str]]
    for r in header_rows:
        row = list(first[r]) + [None] * (width - len(first[r]))
        filled = [text_of(c) for c in row[:width]]
        for r0, c0, r1, c1 in merged:
            if r0 <= r <= r1 and c0 < width:
                for c in range(c0, min(c1, width - 1) + 1):
                    filled[c] = text_of(row[c0])
                if c1 > c0 and filled[c0]:
                    notes.append(
                        f"header {filled[c0]!r} spans merged cells of columns "
                        f"{Column(c0, '', '', None, '').letter}-{Column(min(c1, width - 1), '', '', None, '').letter}"
                    )
        if r != header_rows[-1] and not merged:  # a group title over the columns to its right
            last = ""
            below = [text_of(c) for c in (list(first[header_rows[-1]]) + [None] * width)[:width]]
            for c in range(width):
                if filled[c]:
                    last = filled[c]
                elif last and below[c] and c > 0 and filled[c - 1] == "" and _group(first[r], c):
                    filled[c] = last
        for c in range(width):
            if filled[c]:
                names[c].append(filled[c])
    for r0, _c0, r1, _c1 in merged:
        if r1 >= data and r0 != r1:
            raise DeliveryError(
                f"merged cells over data rows {r0 + 1}-{r1 + 1}: a value standing for several "
                "rows is not a measurement of each; unmerge them",
                file=file,
            )
    if len(header_rows) > 1:
        notes.append(
            f"header in {len(header_rows)} rows ({', '.join(str(r + 1) for r in header_rows)}), "
            "read as one name per column"
        )
    if header_rows[0] > 0:
        notes.append(f"rows 1-{header_rows[0]} above the header skipped (title)")
    return data, [" ".join(n) for n in names], notes


def _group(row: list[Cell], c: int) -> bool:
    """An empty header cell belongs to the group title on its left (CSV has no merges): the title
    row is sparse (fewer names than columns)."""
    filled = sum(x is not None for x in row)
    return filled < len(row) - 1 and any(x is not None for x in row[:c])


def _columns(names: list[str], data_rows: list[list[Cell]], decimal: str) -> list[Column]:
    out = []
    for i, name in enumerate(names):
        vals = [r[i] if i < len(r) else None for r in data_rows]
        present = [v for v in vals if v is not None]
        if not present:
            kind = "empty"
        elif sum(_is_number_like(v) for v in present) >= 0.8 * len(present):
            kind = "number"  # a stray word in a number column is refused later, naming its row
        else:
            kind = "text"
        out.append(
            Column(
                i,
                name or f"(column {i + 1})",
                kind,
                unit_of(name),
                text_of(present[0]) if present else "",
            )
        )
    return out


def _table_of(file: str, cols: list[Column]) -> str | None:
    toks = tokens(Path(file).stem)
    joined = " ".join(toks)
    if any(
        w in joined for w in ("gcp", "passpunkt", "control", "ground control", "pass point", "pp ")
    ):
        return "gcps"
    if any(
        w in joined
        for w in (
            "checkpoint",
            "check point",
            "check",
            "kontrollpunkt",
            "kontrolle",
            "icp",
            "cp",
            "controle",
            "contrôle",
            "verifica",
            "punti di controllo",
        )
    ):
        return "checkpoints"
    return None


def detect(file: str, cols: list[Column], ctx: Context, xy_sample: Any) -> Layout:
    """Column roles of a survey from its header names; Ambiguous when they do not decide."""
    said: list[str] = []
    coords: list[tuple[Column, str, str | None]] = []  # (column, axis, qualifier)
    roles: dict[str, str] = {}
    table = _table_of(file, cols)
    for c in cols:
        toks = tokens(c.name)
        if c.kind == "empty":
            continue
        if c.kind == "text" or not toks:
            for key, role in (
                ("id", "point_id"),
                ("block", "block"),
                ("image_id", "image_id"),
                ("source", "source"),
                ("excluded", "excluded"),
                ("reason", "exclusion_reason"),
            ):
                if toks and _has(toks, key) and role not in roles:
                    roles[role] = c.name
                    break
            continue
        # a number column: an id written as numbers, a precision, a delta or a coordinate
        if _has(toks, "id") and not any(_has(toks, k) for k in ("east", "north", "x", "y", "z")):
            roles.setdefault("point_id", c.name)
            continue
        if _has(toks, "precision"):
            role = "precision_z" if _has(toks, "z") else "precision_xy"
            roles.setdefault(role, c.name)
            continue
        if _has(toks, "delta") and not (_has(toks, "image") or _has(toks, "ref")):
            continue  # recomputed by the check from the two coordinate sets
        axis = (
            "east"
            if _has(toks, "east")
            else "north"
            if _has(toks, "north")
            else "x"
            if _has(toks, "x")
            else "y"
            if _has(toks, "y")
            else "z"
            if _has(toks, "z")
            else None
        )
        if axis is None:
            continue
        qual = "image" if _has(toks, "image") else "ref" if _has(toks, "ref") else None
        coords.append((c, axis, qual))
    if "point_id" not in roles:
        raise Ambiguous("no column names the points (id, Punkt, point, Nr, name...)", file=file)
    # easting / northing: named directions win; bare X/Y are checked against the images
    axes = {a for _, a, _ in coords}
    if axes & {"east", "north"} and axes & {"x", "y"}:
        coords = [
            t for t in coords if t[1] not in ("x", "y")
        ]  # X/Y beside E/N: E/N are the coordinates
    elif axes & {"x", "y"}:
        order = _xy_order(coords, ctx, xy_sample)
        if order is None:
            raise Ambiguous(
                "columns named X and Y do not say which is the easting: with the images' "
                "footprints the files could not decide either (surveys in Germany, Austria or "
                "Switzerland often write X for the northing)",
                file=file,
            )
        coords = [(c, order.get(a, a), q) for c, a, q in coords]
        said.append(
            f"X/Y read as {order['x']}ing/{order['y']}ing: in that order the points lie on the "
            "delivered images, in the other they do not"
        )
    quals = {q for _, _, q in coords}
    sets: dict[str | None, dict[str, Column]] = {}
    for c, a, q in coords:
        s = sets.setdefault(q, {})
        if a in s:
            raise Ambiguous(
                f"two columns for the {a} coordinate ({s[a].name!r}, {c.name!r}) with nothing in "
                "their names telling image from reference coordinates",
                file=file,
            )
        s[a] = c
    if None in sets and len(sets) > 1:
        other = "ref" if "image" in quals else "image"
        sets[other] = {**sets.pop(None), **sets.get(other, {})}
        said.append(
            f"the unqualified coordinate columns read as the {'reference' if other == 'ref' else 'image'} "
            "coordinates (the others are named as "
            f"{'image' if other == 'ref' else 'reference'} ones)"
        )
    if table is None:
        table = "checkpoints" if ("image" in sets and "ref" in sets) else None
    if table is None:
        raise Ambiguous(
            "the file name does not say check points or GCPs (Kontrollpunkte, checkpoints, GCP, "
            "Passpunkte...) and the columns hold one coordinate set",
            file=file,
        )
    if table == "checkpoints":
        if set(sets) == {None}:
            raise Ambiguous(
                "one coordinate set with nothing in its names telling image (ortho, Bild, measured) "
                "from reference (GNSS, survey, Soll) coordinates",
                file=file,
            )
        img, ref = sets.get("image", {}), sets.get("ref", {})
        for role, s, axis in (
            ("x", img, "east"),
            ("y", img, "north"),
            ("x_ref", ref, "east"),
            ("y_ref", ref, "north"),
            ("z", img, "z"),
            ("z_ref", ref, "z"),
        ):
            if axis in s:
                roles[role] = s[axis].name
        if not img:
            raise Ambiguous(
                "only reference coordinates: the image coordinates of each point are the checker's "
                "measurement (not in this file)",
                file=file,
            )
    else:
        s = sets.get(None) or sets.get("ref") or sets.get("image") or {}
        for role, axis in (("x", "east"), ("y", "north"), ("z", "z")):
            if axis in s:
                roles[role] = s[axis].name
    need = [
        r
        for r in (("x", "y", "x_ref", "y_ref") if table == "checkpoints" else ("x", "y"))
        if r not in roles
    ]
    if need:
        raise Ambiguous(f"no column for {', '.join(need)}", file=file)
    return Layout(table, [c.name for c in cols], roles, None, ".", 1, said)


def _xy_order(
    coords: list[tuple[Column, str, str | None]], ctx: Context, sample: Any
) -> dict[str, str] | None:
    """{'x': 'east', 'y': 'north'} or the swap: the one order that puts points on the images."""
    if not ctx.footprints or sample is None:
        return None
    xs = [c for c, a, _ in coords if a == "x"]
    ys = [c for c, a, _ in coords if a == "y"]
    if not xs or not ys:
        return None
    x, y = sample(xs[0]), sample(ys[0])
    if x is None or y is None or not len(x):
        return None
    on = [_on_images(x, y, ctx), _on_images(y, x, ctx)]
    if on[0] > 0 and on[1] == 0:
        return {"x": "east", "y": "north"}
    if on[1] > 0 and on[0] == 0:
        return {"x": "north", "y": "east"}
    return None


def _on_images(e: np.ndarray, n: np.ndarray, ctx: Context) -> int:
    """How many points (rows where both values are numbers) lie on an image's footprint."""
    ok = np.isfinite(e) & np.isfinite(n)
    e, n = e[ok], n[ok]
    hit = np.zeros(len(e), dtype=bool)
    for _, (left, bottom, right, top) in ctx.footprints:
        hit |= (e >= left) & (e <= right) & (n >= bottom) & (n <= top)
    return int(hit.sum())


# ------------------------------------------------------------------ the mapping


def _given(header: list[str], ctx: Context) -> dict[str, Any] | None:
    for lay in ctx.layouts:
        if [str(h) for h in lay.get("match", [])] == header:
            return lay
    return None


def proposal(
    file: str, cols: list[Column], header: list[str], table: str | None, decimal: str | None = None
) -> str:
    """The mapping to write for an undecided layout, with every column listed (the unit, and the
    decimal mark when it was not detected, left as '?': the user states them, nothing defaults)."""
    lines = [
        f"  - match: {_flow(header)}",
        f"    table: {table or 'checkpoints'}          # checkpoints or gcps",
        "    columns:                     # role: column name as read (roles: point_id, block, x, y, "
        "x_ref, y_ref, z, z_ref, image_id, source, precision_xy)",
    ]
    for c in cols:
        if c.kind != "empty":
            lines.append(f"      ?: {_quote(c.name)}    # {c.kind}, e.g. {c.sample!r}")
    lines += [
        "    unit: '?'                    # m, ft or usft",
        f"    decimal: {_quote(decimal) if decimal else chr(39) + '?' + chr(39)}                 # '.' or ','",
    ]
    return (
        "columns read:\n    "
        + "\n    ".join(c.describe() for c in cols)
        + "\n  name the mapping in a file (replace each ? by a role, delete the columns not used) and run "
        "`orthospec init DIR --from SOURCE --mapping FILE`:\n"
        "orthospec_points_mapping: 1\nlayouts:\n" + "\n".join(lines)
    )


def _unit_proposal(layout: Layout) -> str:
    """The mapping to write when only the unit is undecided: the layout as read, the unit asked."""
    lines = [f"  - match: {_flow(layout.header)}", f"    table: {layout.table}", "    columns:"]
    lines += [f"      {role}: {_quote(col)}" for role, col in layout.roles.items()]
    lines += [
        "    unit: '?'                    # the survey's unit: m, ft or usft",
        f"    decimal: {_quote(layout.decimal)}",
    ]
    return (
        "the columns were read as "
        + ", ".join(f"{r} <- {c!r}" for r, c in layout.roles.items())
        + "; state the unit in a mapping file and run `orthospec init DIR --from SOURCE --mapping FILE`:\n"
        "orthospec_points_mapping: 1\nlayouts:\n" + "\n".join(lines)
    )


def _quote(s: str) -> str:
    return "'" + s.replace("'", "''") + "'"


def _flow(items: list[str]) -> str:
    return "[" + ", ".join(_quote(s) for s in items) + "]"


# ------------------------------------------------------------------ reading


def read_points(path: Path, name: str, ctx: Context) -> PointsRead:
    """Read one survey file into the convention table it feeds.

    Raises
    ------
    DeliveryError
        (Ambiguous for an undecided layout, with the columns and the mapping to write) naming the
        file, and the row and column of a bad cell.
    """
    cells = read_cells(path, name)
    rows = count_guard(cells.rows, name)
    first: list[tuple[int, list[Cell]]] = []
    for item in rows:
        first.append(item)
        if len(first) >= HEADER_SCAN:
            break
    sheet_rows = [r for _, r in first]
    data_at, header, notes = _find_header(sheet_rows, cells.merged, name)
    notes = cells.notes + notes
    given = _given(header, ctx)
    sample_rows = sheet_rows[data_at:]
    texts = [str(c).strip() for r in sample_rows for c in r if isinstance(c, str)]
    if given is not None:
        decimal = str(given.get("decimal") or ".")
        if decimal not in (".", ","):
            raise Ambiguous(f"the mapping's decimal {decimal!r} is not '.' or ','", file=name)
    else:
        try:
            decimal, example = _decimal(texts, name)
        except Ambiguous as exc:
            cols = _columns(header, sample_rows, ".")
            raise Ambiguous(f"{exc}\n  {proposal(name, cols, header, None)}") from None
        if decimal == ",":
            notes.append(f"decimal comma (e.g. {example!r})")
    cols = _columns(header, sample_rows, decimal)
    by_name = {c.name: c for c in cols}

    def sample(c: Column) -> np.ndarray | None:
        vals = [
            parse_number(text_of(r[c.index]), decimal)
            if c.index < len(r) and r[c.index] is not None
            else None
            for r in sample_rows
        ]
        return np.array(
            [np.nan if x is None else x for x in vals], dtype=float
        )  # aligned on the rows

    if given is not None:
        layout = _layout_given(given, header, name, by_name)
        layout.said.append("layout from the mapping given (matched on the header)")
    else:
        try:
            layout = detect(name, cols, ctx, sample)
        except Ambiguous as exc:
            raise Ambiguous(
                f"{exc}\n  {proposal(name, cols, header, _table_of(name, cols), decimal)}"
            ) from None
    layout.decimal = decimal
    layout.header_rows = data_at
    try:
        layout.unit = _unit(layout, by_name, ctx, name, sample, given)
    except Ambiguous as exc:
        raise Ambiguous(f"{exc}\n  {_unit_proposal(layout)}") from None
    layout.said.insert(
        0,
        f"read as {layout.table}: "
        + ", ".join(f"{role} <- {col!r}" for role, col in layout.roles.items()),
    )
    unused = [c.name for c in cols if c.kind != "empty" and c.name not in layout.roles.values()]
    if unused:
        notes.append("columns not used: " + ", ".join(repr(u) for u in unused))
    tally: dict[str, Any] = {"moved": [], "on_image": 0, "no_image": 0}
    body, n, outside, filled, unblocked = _write(
        layout, first[data_at:], rows, by_name, ctx, name, tally
    )
    if tally["moved"]:
        moved = tally["moved"]
        notes.append(
            f"block stated in the file differs from the outline the point lies in ({len(moved)}; the "
            "location decides): " + ", ".join(moved[:20]) + (" ..." if len(moved) > 20 else "")
        )
    if tally["on_image"] or tally["no_image"]:
        notes.append(
            f"image_id: the image whose footprint holds the point ({tally['on_image']} points)"
            + (
                f"; {tally['no_image']} on no image or on several, left empty"
                if tally["no_image"]
                else ""
            )
        )
    return PointsRead(name, layout, n, body, notes + layout.said, outside, filled, unblocked)


def _layout_given(
    given: dict[str, Any], header: list[str], file: str, by_name: dict[str, Column]
) -> Layout:
    table = given.get("table")
    if table not in COLUMNS:
        raise Ambiguous(f"the mapping's table {table!r} is not checkpoints or gcps", file=file)
    roles = {str(k): str(v) for k, v in (given.get("columns") or {}).items()}
    for role, col in roles.items():
        if role not in COLUMNS[table]:
            raise Ambiguous(
                f"the mapping names role {role!r}; {table} has {', '.join(COLUMNS[table])}",
                file=file,
            )
        if col not in by_name:
            raise Ambiguous(f"the mapping names column {col!r}, not in the header", file=file)
    return Layout(table, header, roles, given.get("unit"), str(given.get("decimal") or "."), 1, [])


def _unit(
    layout: Layout,
    by_name: dict[str, Column],
    ctx: Context,
    file: str,
    sample: Any,
    given: dict[str, Any] | None,
) -> str:
    if given is not None and given.get("unit"):
        u = str(given["unit"])
        if u not in ("m", "ft", "usft"):
            raise Ambiguous(f"the mapping's unit {u!r} is not m, ft or usft", file=file)
        return u
    stated = {
        unit for r, c in layout.roles.items() if r in LENGTH_ROLES and (unit := by_name[c].unit)
    }
    if len(stated) > 1:
        raise Ambiguous(
            f"the length columns state different units ({', '.join(sorted(stated))}); the "
            "convention has one unit per table: convert the file or map one unit",
            file=file,
        )
    if stated:
        u = stated.pop()
        layout.said.append(f"unit {u}, stated in the header")
        return u
    if ctx.crs_unit in ("m", "ft", "usft") and ctx.footprints:
        e = sample(by_name[layout.roles["x_ref" if "x_ref" in layout.roles else "x"]])
        n = sample(by_name[layout.roles["y_ref" if "y_ref" in layout.roles else "y"]])
        if e is not None and n is not None and len(e) and _on_images(e, n, ctx):
            layout.said.append(
                f"no unit in the file: {ctx.crs_unit}, the axis unit of the images' CRS "
                f"{ctx.crs_name or ''} (the points lie on the images)".replace("  ", " ")
            )
            return ctx.crs_unit
    why = (
        "the images do not share one CRS to take its unit from"
        if ctx.crs_name is None
        else "the points do not lie on the images to take their CRS's unit"
    )
    raise Ambiguous(
        "no unit stated for the coordinates (a header such as 'E [m]' or a unit row) and " + why,
        file=file,
    )


def _write(
    layout: Layout,
    first: list[tuple[int, list[Cell]]],
    rest: Iterator[tuple[int, list[Cell]]],
    by_name: dict[str, Column],
    ctx: Context,
    file: str,
    tally: dict[str, Any],
) -> tuple[str, int, list[str], set[str], int]:
    """The convention CSV text of every data row (streamed, in chunks), the row count, the points
    outside every block outline, the columns filled and the rows without a block."""
    import csv
    import io
    import itertools

    cols = [
        c
        for c in COLUMNS[layout.table]
        if c in layout.roles
        or c == "block"
        or (c == "image_id" and ctx.footprints and layout.table == "checkpoints")
    ]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(cols)
    idx = {role: by_name[c].index for role, c in layout.roles.items()}
    seen: dict[str, int] = {}
    outside: list[str] = []
    filled: set[str] = set()
    unblocked = 0
    n = 0
    stream = itertools.chain(first, rest)
    while True:
        chunk = list(itertools.islice(stream, 50_000))
        if not chunk:
            break
        recs = []
        for row_no, row in chunk:
            if all(c is None for c in row):
                continue
            rec: dict[str, str | None] = {}
            for role, i in idx.items():
                v = row[i] if i < len(row) else None
                if role in NUMBER_ROLES:
                    t = number_text(v, layout.decimal)
                    if v is not None and t is None:
                        raise DeliveryError(
                            f"column {by_name[layout.roles[role]].letter} "
                            f"{layout.roles[role]!r} ({role}): {text_of(v)!r} is not a number",
                            file=file,
                            row=row_no,
                        )
                    rec[role] = t
                elif role == "excluded":
                    rec[role] = _bool_text(v, file, row_no, layout.roles[role])
                else:
                    rec[role] = text_of(v) or None
            for role in ("point_id", "x", "y") + (
                ("x_ref", "y_ref") if layout.table == "checkpoints" else ()
            ):
                if not rec.get(role):
                    col = by_name[layout.roles[role]]
                    raise DeliveryError(
                        f"column {col.letter} {col.name!r} ({role}) is empty (a formula without a "
                        "stored result reads as empty: save the file in a spreadsheet program)",
                        file=file,
                        row=row_no,
                    )
            pid = str(rec["point_id"])
            if pid in seen:
                raise DeliveryError(
                    f"point id {pid!r} also on row {seen[pid]}: ids must be unique",
                    file=file,
                    row=row_no,
                )
            seen[pid] = row_no
            recs.append(rec)
        _place(recs, layout, ctx, outside, tally)
        for rec in recs:
            if rec.get("block") is None and ctx.outlines:
                continue  # outside every outline: listed, not a point of any block
            cells = [rec.get(c) or "" for c in cols]
            filled.update(c for c, v in zip(cols, cells, strict=True) if v)
            unblocked += not rec.get("block")
            w.writerow(cells)
            n += 1
    return out.getvalue(), n, outside, filled, unblocked


def _bool_text(v: Cell, file: str, row: int, col: str) -> str | None:
    if v is None:
        return None
    if isinstance(v, bool):
        return "true" if v else "false"
    t = text_of(v).lower()
    yes = ("true", "yes", "y", "1", "x", "ja", "oui", "si", "sí", "wahr")
    no = ("false", "no", "n", "0", "nein", "non", "falsch", "")
    if t in yes:
        return "true"
    if t in no:
        return "false"
    raise DeliveryError(f"column {col!r}: {text_of(v)!r} is not a yes/no word", file=file, row=row)


def _place(
    recs: list[dict[str, str | None]],
    layout: Layout,
    ctx: Context,
    outside: list[str],
    tally: dict[str, Any],
) -> None:
    """Blocks by location (outlines given) and, for check points, the image each lies on (counted in
    ``tally``: the points whose stated block the location overrules, those on one image or not)."""
    if not recs:
        return
    ex = "x_ref" if "x_ref" in layout.roles else "x"
    ey = "y_ref" if "y_ref" in layout.roles else "y"
    e = np.array([float(r[ex]) for r in recs])  # type: ignore[arg-type]
    n = np.array([float(r[ey]) for r in recs])  # type: ignore[arg-type]
    if ctx.outlines:
        import shapely

        found = np.full(len(recs), None, dtype=object)
        for bid, poly in ctx.outlines.items():
            inside = shapely.contains_xy(poly, e, n) | shapely.intersects_xy(
                shapely.boundary(poly), e, n
            )
            found[inside & (found == None)] = bid  # noqa: E711 (object array)
        for r, b in zip(recs, found.tolist(), strict=True):
            stated = r.get("block")
            if stated and stated != b:
                tally["moved"].append(f"{r['point_id']} ({stated} -> {b or 'no block'})")
            if b is None:
                outside.append(str(r["point_id"]))
            r["block"] = b
    if layout.table == "checkpoints" and ctx.footprints and "image_id" not in layout.roles:
        hits = np.zeros(len(recs), dtype=np.int32)
        first = np.full(len(recs), None, dtype=object)
        for img, (left, bottom, right, top) in ctx.footprints:
            on = (e >= left) & (e < right) & (n > bottom) & (n <= top)
            first[on & (hits == 0)] = img
            hits += on
        for r, img, h in zip(recs, first.tolist(), hits.tolist(), strict=True):
            r["image_id"] = img if h == 1 else None
            tally["on_image" if h == 1 else "no_image"] += 1
