"""Open a delivery folder: the manifest, its CSV tables and file checksums. Read-only.

This module and ``raster/`` are the only places that read a delivery. Nothing here writes into
the delivery folder.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
import pandas as pd
from pydantic import ValidationError

from ..errors import DeliveryError, UnitError
from ..provenance import Evidence, sha256_bytes, sha256_file
from ..spec.yamlio import YamlError, load_file
from ..units import canonical, parse_unit
from .convention import TableSpec, table_specs
from .manifest import Manifest

MANIFEST = "delivery.yaml"
_TRUE = {"true", "yes", "y", "1", "t"}
_FALSE = {"false", "no", "n", "0", "f"}


@dataclass(frozen=True)
class Table:
    """A validated delivery table. ``df`` keeps a ``_row`` column: 1-based data row numbers."""

    name: str
    spec: TableSpec
    file: str
    sha256: str
    df: pd.DataFrame
    units: dict[str, str]

    def evidence(self, rows: Any = ()) -> tuple[Evidence, ...]:
        return (Evidence(self.file, self.sha256, tuple(int(r) for r in rows)),)

    @property
    def ids(self) -> pd.Series:
        col = self.spec.id
        if col is None:
            return self.df["_row"].astype(str)
        return self.df[col].astype(str)


@dataclass
class Delivery:
    root: Path
    manifest: Manifest
    raw: dict[str, Any]
    manifest_sha256: str
    positions: dict[tuple[Any, ...], tuple[int, int]] = field(repr=False, default_factory=dict)
    _tables: dict[str, Table] = field(default_factory=dict, repr=False)
    _sha: dict[str, str] = field(default_factory=dict, repr=False)

    # --- paths and checksums -----------------------------------------------------------
    def path(self, rel: str, *, what: str = "file") -> Path:
        """Resolve ``rel`` inside the delivery; refuse anything that escapes it."""
        pp = PurePosixPath(rel.replace("\\", "/"))
        if pp.is_absolute() or ".." in pp.parts:
            raise DeliveryError(f"{what} path {rel!r} must be relative and inside the delivery",
                                file=MANIFEST)
        return self.root / Path(*pp.parts)

    def sha256(self, rel: str) -> str:
        if rel not in self._sha:
            self._sha[rel] = sha256_file(self.path(rel))
        return self._sha[rel]

    def remember_sha256(self, rel: str, sha256: str) -> None:
        """A checksum another reader already computed (the raster scan), so no file is hashed twice."""
        self._sha.setdefault(rel, sha256)

    def evidence(self, rel: str, *, rows: Any = (), path: str | None = None) -> Evidence:
        return Evidence(rel, self.sha256(rel), tuple(int(r) for r in rows), path)

    def manifest_evidence(self, path: str) -> Evidence:
        return Evidence(MANIFEST, self.manifest_sha256, (), path)

    def where(self, path: tuple[Any, ...]) -> int | None:
        p = tuple(path)
        while p:
            if p in self.positions:
                return self.positions[p][0]
            p = p[:-1]
        return None

    @cached_property
    def files(self) -> list[dict[str, Any]]:
        """Every file of the delivery with size and SHA-256, sorted (for the QCR appendix)."""
        out = []
        for p in sorted(self.root.rglob("*")):
            if p.is_file() and not p.is_symlink():
                rel = p.relative_to(self.root).as_posix()
                out.append({"path": rel, "bytes": p.stat().st_size, "sha256": self.sha256(rel)})
        return out

    # --- facts ------------------------------------------------------------------------
    @property
    def id(self) -> str:
        return self.manifest.id

    @property
    def project_id(self) -> str:
        return self.manifest.project.id

    @property
    def gsd_m(self) -> float | None:
        g = self.manifest.product.gsd
        if g is None:
            return None
        return _to_m(g.value, g.unit)

    @property
    def block_ids(self) -> list[str]:
        ids = [b.id for b in self.manifest.blocks]
        if not ids:
            for name in ("images", "checkpoints"):
                t = self.table(name)
                if t is not None and "block" in t.df:
                    ids = sorted(set(t.df["block"].astype(str)))
                    break
        return ids

    def flat_manifest(self) -> dict[str, Any]:
        """``manifest.a.b`` -> value for every scalar (and {value, unit} quantity) in delivery.yaml."""
        out: dict[str, Any] = {}

        def walk(obj: Any, prefix: str) -> None:
            if isinstance(obj, dict):
                if set(obj) == {"value", "unit"}:
                    out[prefix] = obj
                    return
                for k, v in obj.items():
                    walk(v, f"{prefix}.{k}")
            elif isinstance(obj, list):
                out[prefix] = obj
            else:
                out[prefix] = obj

        walk(self.raw, "manifest")
        return out

    # --- tables -----------------------------------------------------------------------
    def has_table(self, name: str) -> bool:
        return name in self.manifest.tables

    def table(self, name: str) -> Table | None:
        """The validated table, or None when the manifest does not declare it."""
        if name not in self.manifest.tables:
            return None
        if name not in self._tables:
            self._tables[name] = self._read_table(name, self.manifest.tables[name])
        return self._tables[name]

    def require_table(self, name: str) -> Table:
        t = self.table(name)
        if t is None:
            raise DeliveryError(f"the manifest declares no '{name}' table (tables: {name}: FILE)",
                                file=MANIFEST)
        return t

    def load_all_tables(self) -> None:
        """Read every declared table now, so bad input fails before any rule runs."""
        for name in self.manifest.tables:
            self.table(name)

    def _read_table(self, name: str, rel: str) -> Table:
        spec = table_specs()[name]
        p = self.path(rel, what=f"table {name}")
        if not p.is_file():
            raise DeliveryError(f"table '{name}' file not found: {rel}", file=MANIFEST,
                                line=self.where(("tables", name)))
        data = p.read_bytes()
        sha = sha256_bytes(data)
        self._sha[rel] = sha
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise DeliveryError(f"not UTF-8 text (byte {exc.start})", file=rel) from None
        length_unit = self.manifest.units.get(name, "m")
        try:
            parse_unit(length_unit)
        except UnitError as exc:
            raise DeliveryError(f"units.{name}: {exc}", file=MANIFEST,
                                line=self.where(("units", name))) from None
        df = parse_csv(text, spec, file=rel)
        units = {}
        for col, cs in spec.columns.items():
            if cs.type == "number" and col in df:
                units[col] = canonical(length_unit if cs.unit == "length" else cs.unit)
        return Table(name, spec, rel, sha, df, units)


def _to_m(value: float, unit: str) -> float:
    from ..units import convert

    return float(convert([value], unit, "m")[0])


def parse_csv(text: str, spec: TableSpec, *, file: str) -> pd.DataFrame:
    """Parse and type a CSV table against its spec; every problem names file, row and column.

    pandas' C parser reads every cell as text (empty cells stay ''), so a national table of a
    million rows parses in seconds; types are then converted column by column, vectorised.
    """
    first = text.split("\n", 1)[0]
    header = [h.strip() for h in next(csv.reader([first]))] if first.strip() else []
    if not header:
        raise DeliveryError("empty table: expected a header row with columns "
                            + ", ".join(spec.columns), file=file)
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DeliveryError(f"duplicate column(s) {', '.join(dup)}", file=file, line=1)
    unknown = [h for h in header if h not in spec.columns]
    missing = [c for c in spec.required if c not in header]
    if unknown or missing:
        parts = []
        if missing:
            parts.append("missing required column(s) " + ", ".join(missing))
        if unknown:
            parts.append("unexpected column(s) " + ", ".join(unknown))
        raise DeliveryError(
            "; ".join(parts) + f". Expected columns for table '{spec.name}': required "
            + ", ".join(spec.required) + "; optional "
            + ", ".join(c for c in spec.columns if c not in spec.required),
            file=file, line=1)
    try:
        raw = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False, skip_blank_lines=False,
                          skipinitialspace=False, engine="c")
    except pd.errors.ParserError as exc:
        m = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        if m:
            raise DeliveryError(f"has {m.group(3)} fields, the header has {m.group(1)}", file=file,
                                row=int(m.group(2)) - 1) from None
        raise DeliveryError(f"not a valid CSV table: {exc}", file=file) from None
    raw.columns = header
    rows = np.arange(1, len(raw) + 1, dtype=np.int64)
    cells = {c: np.strings.strip(raw[c].to_numpy(dtype=str)) for c in header}
    if len(raw):
        blank = np.logical_and.reduce([cells[c] == "" for c in header])
        # pandas pads short rows silently; the csv module (C) counts the fields of every record
        counts = np.fromiter((len(r) for r in csv.reader(io.StringIO(text))), dtype=np.int64)[1:]
        counts = counts[: len(raw)] if len(counts) >= len(raw) else np.pad(counts, (0, len(raw) - len(counts)))
        short = (counts != len(header)) & ~blank & (counts > 0)
        if short.any():
            i = int(np.flatnonzero(short)[0])
            raise DeliveryError(f"has {int(counts[i])} fields, the header has {len(header)}", file=file,
                                row=int(rows[i]))
        if blank.any():
            rows = rows[~blank]
            cells = {c: v[~blank] for c, v in cells.items()}
    df = pd.DataFrame({"_row": rows})
    for col in header:
        cs = spec.columns[col]
        df[col] = _convert_column(cells[col], rows, cs.type, col, file, cs.required)
    if spec.id and spec.id in df:
        ids = df[spec.id]
        dups = ids[ids.duplicated(keep=False)]
        if len(dups):
            first_dup = dups.iloc[0]
            where = df.loc[ids == first_dup, "_row"].tolist()
            raise DeliveryError(f"duplicate id {first_dup!r} in rows {', '.join(map(str, where))}",
                                file=file, field=spec.id)
    return df


_NONFINITE = ["nan", "inf", "-inf", "+inf", "infinity", "-infinity", "+infinity"]


def _convert_column(cells: np.ndarray, rows: np.ndarray, kind: str, col: str, file: str,
                    required: bool) -> pd.Series:
    """Vectorised type conversion of one column of stripped text cells."""
    empty = cells == ""
    if required and empty.any():
        raise DeliveryError("required value is empty", file=file, row=int(rows[empty][0]), field=col)

    def bad(mask: np.ndarray, what: str) -> DeliveryError:
        i = int(np.flatnonzero(mask)[0])
        return DeliveryError(f"expected {what}, got {str(cells[i])!r}", file=file, row=int(rows[i]), field=col)

    if kind == "text":
        out = cells.astype(object)
        out[empty] = None
        return pd.Series(out, dtype=object)
    if kind == "number":
        num = pd.to_numeric(pd.Series(np.where(empty, "nan", cells)), errors="coerce").to_numpy(dtype=float)
        suspect = ~np.isfinite(num) & ~empty
        if suspect.any():
            nonfinite = suspect & (np.isin(np.strings.lower(cells), _NONFINITE) | np.isinf(num))
            if nonfinite.any():
                raise bad(nonfinite, "a finite number (leave the cell empty when the value is unknown)")
            raise bad(suspect, "a number")
        return pd.Series(num, dtype=float)
    if kind == "bool":
        lowered = np.strings.lower(cells)
        t, f = np.isin(lowered, list(_TRUE)), np.isin(lowered, list(_FALSE))
        wrong = ~(t | f | empty)
        if wrong.any():
            raise bad(wrong, "true/false")
        out = np.full(len(cells), None, dtype=object)
        out[t], out[f] = True, False
        return pd.Series(out, dtype=object)
    if kind in ("date", "datetime"):
        text = pd.Series(np.where(empty, "", cells), dtype=object)
        parsed = pd.to_datetime(text.where(~empty, None), format="ISO8601", errors="coerce", utc=False) \
            if len(text) else pd.Series([], dtype="datetime64[ns]")
        wrong = parsed.isna().to_numpy() & ~empty
        if kind == "date":
            wrong |= ~empty & (np.strings.str_len(cells) != 10)
        if wrong.any():
            fmt = "YYYY-MM-DD" if kind == "date" else "ISO 8601 (YYYY-MM-DDTHH:MM:SS)"
            raise bad(wrong, f"a {kind} {fmt}")
        out = cells.astype(object)
        out[empty] = None
        return pd.Series(out, dtype=object)
    raise AssertionError(kind)


def _suggest_key(loc: tuple[Any, ...]) -> str:
    """'; did you mean contractor?' for a misspelt top-level manifest key."""
    import difflib

    if len(loc) != 1:
        return ""
    near = difflib.get_close_matches(str(loc[0]), list(Manifest.model_fields), n=1, cutoff=0.75)
    return f"; did you mean {near[0]!r}?" if near else ""


def open_delivery(path: str | Path) -> Delivery:
    """Open and validate a delivery folder; raise DeliveryError naming file and line."""
    root = Path(path)
    if not root.exists():
        raise DeliveryError(f"delivery folder {str(path)!r} not found")
    if not root.is_dir():
        raise DeliveryError(f"{str(path)!r} is not a folder (a delivery is a folder with {MANIFEST})")
    mpath = root / MANIFEST
    if not mpath.is_file():
        raise DeliveryError(f"no {MANIFEST} in {str(path)!r}; `orthospec init DIR` writes a template")
    try:
        doc = load_file(mpath, display=MANIFEST)
    except YamlError as exc:
        raise DeliveryError(str(exc)) from None
    if not isinstance(doc.data, dict):
        raise DeliveryError("the manifest must be a YAML mapping", file=MANIFEST, line=1)
    try:
        manifest = Manifest.model_validate(doc.data)
    except ValidationError as exc:
        lines = []
        for e in exc.errors()[:20]:
            loc = tuple(e["loc"])
            line, col = doc.where(loc)
            where = f"{MANIFEST}:{line}:{col}" if line else MANIFEST
            hint = _suggest_key(loc) if e["type"] == "extra_forbidden" else ""
            lines.append(f"{where}: {'.'.join(map(str, loc)) or '(document)'}: {e['msg']}{hint}")
        raise DeliveryError("invalid manifest:\n  " + "\n  ".join(lines)) from None
    for name in manifest.tables:
        if name not in table_specs():
            raise DeliveryError(f"unknown table {name!r}; known tables: {', '.join(sorted(table_specs()))}",
                                file=MANIFEST, line=doc.where(("tables", name))[0])
    d = Delivery(root=root, manifest=manifest, raw=doc.data,
                 manifest_sha256=sha256_file(mpath), positions=doc.marks)
    d._sha[MANIFEST] = d.manifest_sha256
    return d
