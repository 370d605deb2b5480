"""Open a delivery folder: the manifest, its CSV tables and file checksums. Read-only.

This module and ``raster/`` are the only places that read a delivery. Nothing here writes into
the delivery folder.

A delivery is untrusted input (the contractor is paid on the verdict), so every path it names or
holds goes through :func:`contained` before anything opens or hashes it: no absolute path, no
``..``, no URL or GDAL ``/vsi`` prefix, no symbolic link leaving the folder, no FIFO or device.
Tables are bounded before they are parsed (file size, columns per line, bytes per cell; see
:class:`Limits`), so a hostile table fails in well under a second with file and row.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from pydantic import ValidationError

from ..errors import DeliveryError, UnitError
from ..provenance import Evidence, sha256_bytes, sha256_file
from ..units import canonical, parse_unit
from ..yamlio import YamlError, load_file
from . import vocabulary
from .convention import TableSpec, table_specs
from .draft import SourceLinks, draft_images_spec, source_links
from .manifest import Manifest
from .outlines import StatedOutlines, finite_ring, first_overlap, invalid_reason, ring_polygon
from .paths import _PLAIN_PATH, MANIFEST, check_tree, contained
from .table import BOOL_FALSE, BOOL_TRUE, _parse_body, header_names, parse_csv, rows_where
from .table_bounds import Limits, check_csv_bounds, read_table_bytes, utf8_body

#: Re-exported: the path jail (:mod:`.paths`) and the table parser (:mod:`.table`,
#: :mod:`.table_bounds`) were split out of this module; their public names stay importable here.
__all__ = ["BOOL_FALSE", "BOOL_TRUE", "MANIFEST", "PATH_COLUMNS", "Delivery", "Limits", "Table",
           "check_csv_bounds", "check_tree", "contained", "header_names", "open_delivery",
           "parse_csv", "read_table_bytes", "rows_where", "utf8_body"]

#: Columns that hold a path relative to the delivery root, in any table.
PATH_COLUMNS = frozenset({"file"})
#: Manifest fields that hold paths relative to the delivery root (mappings of name -> path).
_PATH_MAPPINGS = ("tables", "documents", "vectors")


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
        # numpy's tolist builds the ints in C; "every row" is one shared entry (a million-row table
        # is asked for it by every whole-table measure)
        arr = np.asarray(rows, dtype=np.int64)
        if len(arr) == len(self.df) and len(arr) > 1 and np.array_equal(arr, self._all_rows):
            return self._every_row
        return (Evidence(self.file, self.sha256, tuple(arr.tolist())),)

    @cached_property
    def _all_rows(self) -> np.ndarray:
        return self.df["_row"].to_numpy(np.int64)

    @cached_property
    def _every_row(self) -> tuple[Evidence, ...]:
        return (Evidence(self.file, self.sha256, tuple(self._all_rows.tolist())),)

    @cached_property
    def ids(self) -> pd.Series:
        """Item ids as text (the id column, else the row number); built once per table (a national
        table has a million rows and every measure of its scope asks)."""
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
    tree: list[str] | None = field(default=None, repr=False)  # regular files, from check_tree
    #: a draft's links into its source folder (delivery/draft.py); None for a delivery
    links: SourceLinks | None = field(default=None, repr=False)
    limits: Limits = field(default_factory=Limits, repr=False)
    _tables: dict[str, Table] = field(default_factory=dict, repr=False)
    _sha: dict[str, str] = field(default_factory=dict, repr=False)

    # --- paths and checksums -----------------------------------------------------------
    def path(self, rel: str, *, what: str = "file", file: str | None = MANIFEST,
             row: int | None = None) -> Path:
        """Resolve ``rel`` inside the delivery; refuse anything that escapes it (:func:`contained`)."""
        return contained(self.root, rel, what=what, file=file, row=row, links=self.links)

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

    def block_outlines(
        self, stated: StatedOutlines | None = None
    ) -> dict[str, tuple[Any, Evidence]]:
        """Block id -> (ring of [x, y], evidence) of the outlines in force: ``stated`` (the checker's,
        delivery/checker.py ``stated_outlines``) when it states blocks (the manifest's are then
        declarations, red team R13/R17), else the manifest's (blocks without a polygon are left out; a
        non-finite vertex is the caller's to report). The checker's outlines are an argument, never
        state of the delivery: an evaluation passes its own (``ProviderContext.block_outlines``)."""
        if stated is not None and stated.blocks:
            return dict(stated.blocks)
        return {
            b.id: (b.polygon, self.manifest_evidence(f"blocks[{i}].polygon"))
            for i, b in enumerate(self.manifest.blocks)
            if b.polygon
        }

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
        for rel in self.tree if self.tree is not None else check_tree(self.root, self.links):
            p = self.root.joinpath(
                *rel.split("/")
            )  # a real name: a backslash in it is no separator
            try:
                if rel not in self._sha:
                    self._sha[rel] = sha256_file(p)
                size = p.lstat().st_size
            except OSError as exc:
                raise DeliveryError(f"cannot read: {exc.strerror or exc}", file=rel) from None
            out.append({"path": rel, "bytes": size, "sha256": self._sha[rel]})
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
                    ids = sorted(
                        {
                            str(b)
                            for b in pd.unique(t.df["block"].to_numpy(dtype=object))
                            if b is not None and not pd.isna(b) and str(b).strip()
                        }
                    )
                    if ids:  # an images table without blocks (a draft's) names none
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

    def table_absent_reason(self, name: str) -> str:
        """Why :meth:`table` gives None for ``name`` (an evaluation's view words its own tables,
        delivery/in_force.py)."""
        return f"the manifest declares no '{name}' table"

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
            raise DeliveryError(
                f"the manifest declares no '{name}' table (tables: {name}: FILE)", file=MANIFEST
            )
        return t

    def load_all_tables(self) -> None:
        """Read every declared table now, so bad input fails before any rule runs."""
        for name in self.manifest.tables:
            self.table(name)

    def _read_table(self, name: str, rel: str) -> Table:
        spec = table_specs()[name]
        if self.links is not None and name == "images":
            spec = draft_images_spec(spec)  # a draft leaves an image's unknown block empty
        line = self.where(("tables", name))
        p = contained(self.root, rel, what=f"table {name}", line=line, links=self.links)
        if p.is_dir():
            raise DeliveryError(
                f"table '{name}' is a folder, not a file: {rel}", file=MANIFEST, line=line
            )
        if not p.is_file():
            raise DeliveryError(f"table '{name}' file not found: {rel}", file=MANIFEST, line=line)
        data = read_table_bytes(p, file=rel, limits=self.limits)
        digest = _Digest(data)  # hashed beside the parse (hashlib releases the GIL)
        try:
            held = [utf8_body(data, file=rel)]
            del data  # the table is held once (as LF-terminated UTF-8 bytes) while it is parsed
            df, units = self._parse_table(name, spec, rel, held)
        finally:
            self._sha[rel] = sha = digest.value()
        return Table(name, spec, rel, sha, df, units)

    def _parse_table(
        self, name: str, spec: TableSpec, rel: str, held: list[bytes]
    ) -> tuple[pd.DataFrame, dict[str, str]]:
        """The typed frame of a table's body (taken out of ``held``) and the canonical unit of
        its number columns."""
        length_unit = self.manifest.units.get(name, "m")
        try:
            parse_unit(length_unit)
        except UnitError as exc:
            raise DeliveryError(
                f"units.{name}: {exc}", file=MANIFEST, line=self.where(("units", name))
            ) from None
        if any(cs.unit == "length" for cs in spec.columns.values()):
            self._check_length_unit(name, length_unit)
        df = _parse_body(held, spec, file=rel, cell_bytes=self.limits.cell_bytes)
        self._check_blocks(df, rel)
        vocabulary.apply(name, df, rel)  # closed vocabularies: normalised, an unknown word refused
        for col in PATH_COLUMNS & set(df.columns):
            rows, cells = df["_row"], df[col]
            if self.tree is not None:  # lexical checks only: plain relative paths pass in bulk
                todo = ~cells.str.fullmatch(_PLAIN_PATH, na=True).to_numpy(bool)
                rows, cells = rows[todo], cells[todo]
            for r, v in zip(rows.tolist(), cells.tolist(), strict=True):
                if v is not None:
                    contained(
                        self.root,
                        v,
                        what="path",
                        file=rel,
                        row=int(r),
                        field=col,
                        follow=self.tree is None,
                        links=self.links,
                    )
        units = {}
        for col, cs in spec.columns.items():
            if cs.type == "number" and col in df:
                units[col] = canonical(length_unit if cs.unit == "length" else cs.unit)
        return df, units

    @cached_property
    def crs_unit(self) -> str | None:
        """The canonical length unit of the first axis of ``project.crs`` (``m``, ``ft``, ``usft``),
        its pyproj name when that is no length (``degree``), or None when no CRS is declared.

        Coordinates in the tables and the block polygons are in this unit (red team R2).
        pyproj is imported here, lazily: a delivery without a CRS never loads it.
        """
        crs = self.manifest.project.crs
        if not crs:
            return None
        from .crs import CrsProblem, read_crs

        try:
            axes = read_crs(crs).axis_info
        except CrsProblem as exc:
            raise DeliveryError(
                f"project.crs {exc}", file=MANIFEST, line=self.where(("project", "crs"))
            ) from None
        if not axes:
            raise DeliveryError(
                f"project.crs {crs!r} has no axes",
                file=MANIFEST,
                line=self.where(("project", "crs")),
            )
        name = axes[0].unit_name
        key = {"metre": "m", "meter": "m", "foot": "ft", "US survey foot": "usft"}.get(name)
        return key if key is not None else name

    def _check_length_unit(self, name: str, unit: str) -> None:
        """A table's coordinate unit is the unit of the project CRS (red team R2).

        ``units: {checkpoints: ft}`` in a metre CRS would shrink every residual by 0.3048 (``mm``
        by 1000) and turn a failing block into a passing one; the coordinates are positions in
        the project CRS, so the unit is not the contractor's to choose. Without ``project.crs``
        there is nothing to compare with.
        """
        crs_unit = self.crs_unit
        if crs_unit is None or canonical(unit) == crs_unit:
            return
        given = (
            f"units.{name} is {unit}"
            if name in self.manifest.units
            else f"units.{name} is not given (m is assumed)"
        )
        crs = self.manifest.project.crs
        if crs_unit in ("m", "ft", "usft"):
            why = (
                f"the coordinates of table '{name}' are in project.crs {crs}, whose axes are in "
                f"{crs_unit}: set units.{name}: {crs_unit}"
            )
        else:
            why = (
                f"project.crs {crs} has its axes in {crs_unit}, not a length: the coordinates of "
                f"table '{name}' cannot be read in a length unit"
            )
        raise DeliveryError(
            f"{given}, but {why}",
            file=MANIFEST,
            line=self.where(("units", name)) or self.where(("project", "crs")),
        )

    def _check_blocks(self, df: pd.DataFrame, rel: str) -> None:
        """Every ``block`` cell names a manifest block (red team R3).

        Rows of an undeclared block would be computed for no item and judged by no rule: four
        check points moved to ``B99`` would silently leave their block (JRC §12.5 uses all
        independent check points). This is where the manifest and every table with a ``block``
        column meet, so it is checked here once. A manifest without ``blocks:`` names its blocks
        through the tables (:attr:`block_ids`).
        """
        known = [b.id for b in self.manifest.blocks]
        if not known or "block" not in df or not len(df):
            return
        cells = df["block"]
        if all(
            u is None or u in known for u in pd.unique(cells.to_numpy())
        ):  # a few distinct texts
            return
        other = cells[
            ~cells.isin(known) & cells.notna()
        ]  # a ';'-separated list serves several (dem)
        if not len(other):
            return
        parts = other.astype(str).str.split(";").explode().str.strip()
        bad = parts[(parts != "") & ~parts.isin(known)]
        if len(bad):
            row = int(df.loc[bad.index[:1], "_row"].to_numpy(np.int64)[0])
            raise DeliveryError(
                f"block {bad.iloc[0]!r} is not a block of the manifest "
                f"(blocks: {', '.join(known)})",
                file=rel,
                row=row,
                field="block",
            )


class _Digest:
    """The SHA-256 of a table's bytes, computed in a thread beside the parse when the table is
    large enough for that to pay (hashlib releases the GIL, and so does pandas' tokenizer)."""

    def __init__(self, data: bytes, threshold: int = 4 << 20) -> None:
        self._sha: str | None = None
        self._thread: threading.Thread | None = None
        if len(data) < threshold:
            self._sha = sha256_bytes(data)
        else:
            self._thread = threading.Thread(target=self._run, args=(data,), daemon=True)
            self._thread.start()

    def _run(self, data: bytes) -> None:
        self._sha = sha256_bytes(data)

    def value(self) -> str:
        if self._thread is not None:
            self._thread.join()
        assert self._sha is not None
        return self._sha


def _to_m(value: float, unit: str) -> float:
    from ..units import convert

    return float(convert([value], unit, "m")[0])


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
        raise DeliveryError(
            f"{str(path)!r} is not a folder (a delivery is a folder with {MANIFEST})"
        )
    mpath = contained(root, MANIFEST, what="manifest", file=None)
    if not mpath.is_file():
        raise DeliveryError(
            f"no {MANIFEST} in {str(path)!r}; `orthospec init DIR` writes a template"
        )
    try:
        doc = load_file(mpath, display=MANIFEST)
    except YamlError as exc:
        raise DeliveryError(str(exc)) from None
    if not isinstance(doc.data, dict):
        raise DeliveryError("the manifest must be a YAML mapping", file=MANIFEST, line=1)
    try:
        manifest = Manifest.model_validate(doc.data)
    except ValidationError as exc:
        lines = doc.located_errors(
            exc.errors(),
            MANIFEST,
            hint=lambda e: _suggest_key(tuple(e["loc"])) if e["type"] == "extra_forbidden" else "",
        )
        raise DeliveryError("invalid manifest:\n  " + "\n  ".join(lines)) from None
    for name in manifest.tables:
        if name not in table_specs():
            raise DeliveryError(
                f"unknown table {name!r}; known tables: {', '.join(sorted(table_specs()))}",
                file=MANIFEST,
                line=doc.where(("tables", name))[0],
            )
    links = source_links(root, manifest.draft, line=doc.where(("draft", "source"))[0])
    for key in _PATH_MAPPINGS:
        section = doc.data.get(key)
        if isinstance(section, dict):
            for name, rel in section.items():
                if isinstance(rel, str):
                    contained(
                        root, rel, what=f"{key}.{name}", line=doc.where((key, name))[0], links=links
                    )
    extra_paths: list[tuple[tuple[Any, ...], str | None]] = [
        (("project", "area_of_interest"), manifest.project.area_of_interest)
    ]
    extra_paths += [
        (("blocks", i, "polygon_file"), b.polygon_file) for i, b in enumerate(manifest.blocks)
    ]
    for where, rel in extra_paths:
        if rel:
            contained(
                root, rel, what=".".join(map(str, where)), line=doc.where(where)[0], links=links
            )
    _check_block_outlines(manifest, lambda path: doc.where(path)[0])
    tree = check_tree(root, links)
    d = Delivery(
        root=root,
        manifest=manifest,
        raw=doc.data,
        manifest_sha256=sha256_file(mpath),
        positions=doc.marks,
        tree=tree,
        limits=Limits.from_env(),
        links=links,
    )
    d._sha[MANIFEST] = d.manifest_sha256
    return d


def _check_block_outlines(manifest: Manifest, line_of: Any) -> None:
    """Block outlines are valid polygons that do not overlap (red team R17); DeliveryError otherwise.

    Blocks (JRC §12.4 "block/site", §12.8) are the units of acceptance, and a check point counts for
    the block whose outline contains it (JRC-12.4-CHECKPOINTS-IN-BLOCK). Two outlines sharing area
    would let one point serve two blocks: B01 redrawn over B02 took B02's worst points as its own.
    Touching edges share no area and are fine. A self-intersecting or degenerate outline has no
    well-defined inside, so it is refused as well. Outlines with fewer than 3 vertices or a
    non-finite vertex are left to the check-point provider, which records the block as ``error``.
    shapely is imported only when a manifest has two or more outlines, or one to validate.
    """
    for i, b in enumerate(manifest.blocks):
        for k, vertex in enumerate(b.polygon or []):
            if len(vertex) != 2:
                raise DeliveryError(
                    f"blocks[{i}] ({b.id}): polygon vertex {k + 1} is {vertex}, expected [x, y]",
                    file=MANIFEST,
                    line=line_of(("blocks", i, "polygon", k)),
                )
    outlines = [(i, b) for i, b in enumerate(manifest.blocks) if finite_ring(b.polygon)]
    if not outlines:
        return
    polys = []
    for i, b in outlines:
        poly = ring_polygon(b.polygon or [])  # finite_ring: a list of vertices
        why = invalid_reason(poly)
        if why:
            raise DeliveryError(
                f"blocks[{i}] ({b.id}): the polygon is not a valid block outline ({why}); a "
                "block outline is a simple ring whose edges do not cross",
                file=MANIFEST,
                line=line_of(("blocks", i, "polygon")),
            )
        polys.append(poly)
    hit = first_overlap(polys)
    if hit is not None:
        first, second, area = hit
        (i, a), (j, b) = outlines[first], outlines[second]
        raise DeliveryError(
            f"blocks[{j}] ({b.id}): the polygon overlaps the outline of block {a.id} "
            f"(blocks[{i}]) over an area of {area:.6g} (project.crs units squared); blocks are the units "
            "of acceptance (JRC §12.4, §12.8) and a check point cannot belong to two: "
            "outlines may touch but not overlap",
            file=MANIFEST,
            line=line_of(("blocks", j, "polygon")),
        )
