"""``orthospec init DIR --from SOURCE``: a checkable draft delivery from the files as they arrived.

The draft references the files in place (one symbolic link per delivered file under ``source/``,
delivery/draft.py says why the check accepts those links and no others); nothing is copied and
nothing is written into the source. What it writes, all or nothing (a temporary folder beside DIR,
renamed at the end), byte for byte the same for the same files:

``delivery.yaml``
    the manifest; every value a file stated, with that file and XPath in a comment beside it.
``tables/images.csv``
    one row per image, from its header facts (``raster.facts.read_facts``, the checks' own reader).
``tables/checkpoints.csv``, ``tables/gcps.csv``
    the survey spreadsheets, in the convention's columns (points/sheets modules).
``TODO.md``
    what the files could not tell, each with the rules that stay ``missing`` (todo module).
``INGEST.md``
    the draft's report: every decision stated, every file refused or not matched, with why.
``ingest/``
    the facts of every raster (``rasters.csv``), every metadata value with its source
    (``evidence.csv``), the survey mapping (``points-mapping.yaml``) and the TODO map.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import tempfile
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from .. import __version__
from ..delivery.convention import table_specs
from ..errors import DeliveryError
from ..raster.facts import RasterFacts
from ..raster.footprints import IMAGE_FIELDS
from . import points as P
from .metadata import MetadataRead, Stated, read_metadata
from .rasters import Job, read_all
from .todo import DraftState, entries, render
from .vectors import Layer, read_layer
from .walk import Refused, SourceFile, walk_source

if TYPE_CHECKING:
    from pyproj import Transformer

LINKS = "source"
#: free-text fields where two files' wordings are both kept (joined), not a conflict
STATEMENTS = frozenset({"product.accuracy_statement"})
#: colour interpretation (GDAL) -> the convention's band names
BAND_NAMES = {"red": "R", "green": "G", "blue": "B", "gray": "PAN", "grey": "PAN", "alpha": "ALPHA"}
#: manifest fields a metadata file may fill, in the order they are written
FIELDS = (
    "id",
    "project.id",
    "project.name",
    "project.crs",
    "contractor.name",
    "contractor.contact",
    "dates.acquired_from",
    "dates.acquired_to",
    "sensor.type",
    "sensor.platform",
    "sensor.camera",
    "sensor.digital",
    "product.gsd",
    "product.bit_depth",
    "product.accuracy_statement",
)


@dataclass
class Options:
    profile: str = "jrc-v3"
    sensor: str | None = None
    #: the delivery id when no metadata states one (``--id``)
    ident: str | None = None
    blocks: Path | None = None
    mapping: Path | None = None
    sha256: bool = True
    workers: int | None = None
    progress: Callable[[int, int], None] | None = None


@dataclass
class Draft:
    """What ``init --from`` found and decided (the library result; the CLI prints it)."""

    folder: Path
    sources: list[Path]
    images: int = 0
    unreadable: list[tuple[str, str]] = field(default_factory=list)
    todo: int = 0
    written: list[str] = field(default_factory=list)
    report: list[str] = field(default_factory=list)
    missing_rules: int = 0


# ------------------------------------------------------------------ public entry point


def make_draft(
    folder: str | Path, sources: Sequence[str | Path], opts: Options | None = None
) -> Draft:
    """Write the draft delivery ``folder`` from the files under ``sources`` (read in place).

    Raises
    ------
    DeliveryError
        (exit 2, naming the file) a source that is not a folder, a draft folder that exists and is
        not empty, a draft inside a source or a source inside the draft, a survey layout that must be
        named (the message shows its columns and the mapping to write), a sensor type no file states
        and ``--sensor`` does not give.
    """
    opts = opts or Options()
    out = Path(folder)
    srcs = [Path(s) for s in sources]
    _check_places(out, srcs)
    state = _Scan(out, srcs, opts)
    state.run()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(
        tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent if out.parent.exists() else None)
    )
    try:
        umask = os.umask(0)
        os.umask(umask)
        tmp.chmod(0o777 & ~umask)  # mkdtemp makes it private; the draft is an ordinary folder
        state.write(tmp)
        if out.exists():
            out.rmdir()  # empty (checked above)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return state.result


def _check_places(out: Path, srcs: list[Path]) -> None:
    if not srcs:
        raise DeliveryError("no source given: `orthospec init DIR --from SOURCE`")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise DeliveryError(f"{out} exists and is not an empty folder; refusing to overwrite it")
    real_out = out.absolute().resolve()
    for s in srcs:
        if not s.exists():
            raise DeliveryError(f"source {str(s)!r} not found")
        if not s.is_dir():
            raise DeliveryError(
                f"source {str(s)!r} is a file, not a folder; `init --from` takes the folder the "
                "delivery arrived in"
            )
        rs = s.resolve()
        if real_out.is_relative_to(rs) or rs.is_relative_to(real_out):
            raise DeliveryError(
                f"the draft {out} would lie inside the source {s} (or hold it): nothing is written "
                "into a source; put the draft beside it"
            )
    if len(srcs) > 1:
        raise DeliveryError(
            "one source folder per draft: give the folder the delivery arrived in (its "
            "subfolders are read)"
        )


# ------------------------------------------------------------------ the scan


class _Scan:
    def __init__(self, out: Path, srcs: list[Path], opts: Options) -> None:
        self.out, self.srcs, self.opts = out, srcs, opts
        self.result = Draft(out, srcs)
        self.files: list[tuple[str, SourceFile]] = []  # (name in the draft, file)
        self.refused: list[Refused] = []
        self.facts: list[RasterFacts] = []
        self.meta: list[MetadataRead] = []
        self.layers: list[Layer] = []
        self.points: list[P.PointsRead] = []
        self.point_errors: list[str] = []
        self.fields: dict[str, Stated] = {}
        self.conflicts: list[str] = []
        self.notes: list[str] = []
        self.outlines: dict[str, Any] = {}
        self.outline_source: str | None = None
        self._fps: dict[str, tuple[float, float, float, float]] | None = None
        self._frame_wkt: str | None = None

    # names in the draft: source/<rel> for one source, source/<name>/<rel> for several
    def _name(self, src: Path, rel: str) -> str:
        return f"{LINKS}/{rel}" if len(self.srcs) == 1 else f"{LINKS}/{src.resolve().name}/{rel}"

    def run(self) -> None:
        for s in self.srcs:
            files, refused = walk_source(s)
            self.files += [(self._name(s, f.rel), f) for f in files]
            self.refused += [Refused(self._name(s, r.rel), r.why) for r in refused]
        self._metadata()
        self.sensor = self._sensor()  # refused before the long part when no file states it
        self.ident = self._ident()
        self._rasters()
        self._vectors()
        self._points()

    def _rasters(self) -> None:
        jobs = [Job(str(f.path), name) for name, f in self.files if f.kind == "raster"]
        total = len(jobs)
        done = [0]

        def tick(_f: RasterFacts) -> None:
            done[0] += 1
            if self.opts.progress:
                self.opts.progress(done[0], total)

        self.facts = list(
            read_all(jobs, sha256=self.opts.sha256, workers=self.opts.workers, on_done=tick)
        )
        self.result.unreadable = [(f.path, f.error) for f in self.facts if f.error]

    def _readable(self) -> list[RasterFacts]:
        return [f for f in self.facts if f.error is None and f.georeferenced]

    def _metadata(self) -> None:
        for name, f in self.files:
            if f.kind != "xml":
                continue
            m = read_metadata(f.path, name)
            if m is not None:
                self.meta.append(m)
        for m in self.meta:
            for s in m.stated:
                if s.field not in FIELDS:
                    continue
                old = self.fields.get(s.field)
                if old is None:
                    self.fields[s.field] = s
                elif s.field in STATEMENTS and old.value != s.value:  # two statements: both quoted
                    self.fields[s.field] = Stated(
                        s.field,
                        f"{old.value} | {s.value}",
                        old.file,
                        f"{old.xpath}; {s.file}:{s.line or ''} {s.xpath}",
                        old.line,
                    )
                elif old.value != s.value:
                    self.conflicts.append(
                        f"`{s.field}`: {old.where} states {old.value!r}, {s.where} states "
                        f"{s.value!r}: left empty"
                    )
        for c in self.conflicts:
            key = c.split("`")[1]
            self.fields.pop(key, None)

    def _image_ids(self) -> dict[str, str]:
        """File name in the draft -> image id: the file's stem, or its path without suffix when two
        files share a stem."""
        stems = Counter(Path(f.path).stem for f in self.facts)
        out = {}
        for f in self.facts:
            stem = Path(f.path).stem
            out[f.path] = stem if stems[stem] == 1 else os.path.splitext(f.path.split("/", 1)[1])[0]
        return out

    def _footprints(self) -> dict[str, tuple[float, float, float, float]]:
        """Image id -> footprint in the frame CRS (:meth:`_frame`); an image in another CRS is
        reprojected (its envelope), one whose CRS cannot be transformed is left out."""
        if self._fps is not None:
            return self._fps
        ids = self._image_ids()
        frame = self._frame()
        out: dict[str, tuple[float, float, float, float]] = {}
        frame_wkt = self._frame_wkt  # set by _frame()
        to_frame: dict[str, Transformer | None] = {}  # None: that CRS cannot be transformed
        for f in self._readable():
            if f.bounds is None:
                continue
            if f.crs_name == frame:
                out[ids[f.path]] = f.bounds
                continue
            if not (frame and frame_wkt and f.crs_wkt and f.crs_name):
                continue
            if f.crs_name not in to_frame:
                from pyproj import CRS, Transformer
                from pyproj.exceptions import ProjError

                try:
                    to_frame[f.crs_name] = Transformer.from_crs(
                        CRS.from_wkt(f.crs_wkt), CRS.from_wkt(frame_wkt), always_xy=True
                    )
                except ProjError:
                    to_frame[f.crs_name] = None
            t = to_frame[f.crs_name]
            if t is not None:
                try:
                    b = t.transform_bounds(*f.bounds, densify_pts=21)
                except ProjError:
                    continue
                if all(math.isfinite(v) for v in b):
                    out[ids[f.path]] = (b[0], b[1], b[2], b[3])
        self._fps = out
        return out

    def _crs(self) -> str | None:
        """The images' CRS when they share one (None when mixed: a unit is then never taken from it)."""
        epsgs = Counter(f.crs_name for f in self._readable() if f.crs_name)
        return epsgs.most_common(1)[0][0] if len(epsgs) == 1 else None

    def _frame(self) -> str | None:
        """The CRS footprints, layers and outlines are compared in: the images' one CRS, or with mixed
        CRSs the one most images use (said in INGEST.md); a frame for geometry, never a declared value."""
        c = Counter(f.crs_name for f in self._readable() if f.crs_name and f.crs_wkt)
        if not c:
            return None
        name = sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))[0][0]
        self._frame_wkt = next(f.crs_wkt for f in self._readable() if f.crs_name == name)
        return name

    def _vectors(self) -> None:
        fps = self._footprints()
        crs = self._frame()
        for name, f in self.files:
            if f.kind != "vector":
                continue
            lay = read_layer(f.path, name, images=fps, image_crs=crs)
            self.layers.append(lay)
        if self.opts.blocks is not None:
            p = Path(self.opts.blocks)
            lay = read_layer(p, str(self.opts.blocks), images=fps, image_crs=crs, role="blocks")
            if lay.error:
                raise DeliveryError(f"--blocks: {lay.error}", file=str(self.opts.blocks))
            self.outlines, self.outline_source = lay.outlines, f"{self.opts.blocks} (--blocks)"
            self.layers.append(lay)
        else:
            blocks = [lay for lay in self.layers if lay.role == "blocks" and lay.outlines]
            if len(blocks) == 1:
                self.outlines, self.outline_source = blocks[0].outlines, blocks[0].file
            elif len(blocks) > 1:
                self.notes.append(
                    "several block layers (" + ", ".join(b.file for b in blocks) + "): none used; "
                    "give one with --blocks"
                )
        if self.outlines:
            from ..delivery.outlines import first_overlap

            ids = sorted(self.outlines)
            hit = first_overlap([self.outlines[i] for i in ids])
            if hit is not None:
                raise DeliveryError(
                    f"block outlines {ids[hit[0]]} and {ids[hit[1]]} overlap (area {hit[2]:.6g}): "
                    "a point cannot belong to two blocks",
                    file=self.outline_source,
                )

    def _points(self) -> None:
        layouts: list[dict[str, Any]] = []
        if self.opts.mapping is not None:
            layouts = _load_mapping(Path(self.opts.mapping))
        readable = self._readable()
        fps = self._footprints()
        unit = None
        crs = self._crs()
        if crs and readable:
            units = {f.pixel_unit for f in readable}
            u = units.pop() if len(units) == 1 else None
            unit = {
                "metre": "m",
                "meter": "m",
                "m": "m",
                "foot": "ft",
                "US survey foot": "usft",
            }.get(u or "")
        ctx = P.Context(
            footprints=sorted(fps.items()),
            crs_unit=unit,
            crs_name=crs,
            outlines=self.outlines,
            layouts=layouts,
        )
        errors: list[P.Ambiguous] = []
        for name, f in self.files:
            if f.kind != "sheet":
                continue
            try:
                self.points.append(P.read_points(f.path, name, ctx))
            except P.Ambiguous as exc:
                errors.append(exc)
            except DeliveryError as exc:
                self.point_errors.append(str(exc))
        if errors:  # ambiguity is refused (exit 2): every undecided file at once, with its mapping
            raise DeliveryError("\n".join(str(e) for e in errors))
        tables = Counter(p.layout.table for p in self.points)
        for t, n in tables.items():
            if n > 1:
                raise DeliveryError(
                    f"{n} survey files feed the {t} table ("
                    + ", ".join(p.file for p in self.points if p.layout.table == t)
                    + "): give one source per table, or merge them"
                )

    # ------------------------------------------------------------------ composing

    def _sensor(self) -> tuple[str, str]:
        if self.opts.sensor:
            s = self.fields.get("sensor.type")
            if s is not None and s.value != self.opts.sensor:
                raise DeliveryError(f"--sensor {self.opts.sensor} but {s.where} states {s.value!r}")
            return self.opts.sensor, "--sensor"
        s = self.fields.get("sensor.type")
        if s is None:
            raise DeliveryError(
                "the files do not state the sensor type (aerial or satellite): no metadata names "
                "the platform or camera; give it with --sensor aerial|satellite"
            )
        return str(s.value), s.where

    def _ident(self) -> tuple[str, str]:
        s = self.fields.get("id")
        if self.opts.ident:
            if s is not None and s.value != self.opts.ident:
                self.notes.append(
                    f"the metadata's identifier {s.value!r} ({s.where}) is not the delivery id "
                    f"given with --id ({self.opts.ident!r})"
                )
            return self.opts.ident, "--id"
        if s is None:
            raise DeliveryError(
                "the files do not state the delivery's identifier (no metadata fileIdentifier); "
                "give it with --id (the checker's file binds to it)"
            )
        return str(s.value), s.where

    def write(self, tmp: Path) -> None:
        sensor, sensor_src = self.sensor
        ids = self._image_ids()
        (tmp / "tables").mkdir()
        (tmp / "ingest").mkdir()
        final = self.out.parent.resolve() / self.out.name
        for name, f in self.files:
            parts = name.split("/")
            p = tmp.joinpath(*parts)
            p.parent.mkdir(parents=True, exist_ok=True)
            os.symlink(_link_target(f.path.resolve(), final.joinpath(*parts[:-1])), p)
        # --- images
        image_blocks = self._image_blocks()
        img_cols, img_rows = self._images_table(ids, image_blocks)
        _write_csv(tmp / "tables" / "images.csv", img_cols, img_rows)
        _write_csv(tmp / "ingest" / "rasters.csv", *_facts_table(self.facts))
        tables = {
            "images": {c for c in img_cols if any(r.get(c) not in (None, "") for r in img_rows)}
        }
        withheld: dict[str, str] = {}
        units: dict[str, str] = {}
        for pr in self.points:
            t = pr.layout.table
            body, filled = pr.csv_text, pr.filled
            if pr.unblocked or not pr.rows:
                (tmp / "ingest" / f"{t}.csv").write_text(body, encoding="utf-8")
                withheld[t] = (
                    f"read from {pr.file} into ingest/{t}.csv, but the points have no block (no "
                    "outlines given and no block column): add the blocks, then declare the table "
                    f"(`tables: {{{t}: ingest/{t}.csv}}`)"
                )
                continue
            (tmp / "tables" / f"{t}.csv").write_text(body, encoding="utf-8")
            tables[t] = filled
            units[t] = pr.layout.unit or "m"
        vectors = {}
        seam = [lay for lay in self.layers if lay.role == "seamlines" and lay.declarable]
        tiles = [lay for lay in self.layers if lay.role == "tiles" and lay.declarable]
        if len(seam) == 1:
            vectors["seamlines"] = seam[0].file
        if len(tiles) == 1:
            vectors["tiles"] = tiles[0].file
        manifest, comments = self._manifest(
            sensor, sensor_src, tables, units, vectors, image_blocks
        )
        # --- TODO
        from ..profile.loader import load_profile

        profile = load_profile(self.opts.profile)
        filled = {k for k in _flat(manifest)}
        if (
            len(seam) == 1
            and (seam[0].matched_by or "").lower().removeprefix("attribute ") in IMAGE_FIELDS
        ):
            filled.add("vectors.seamlines.image_id")  # the rules read each polygon's image from it
        digital = manifest.get("sensor", {}).get("digital")
        st = DraftState(
            filled=filled,
            tables=tables,
            blocks=bool(self.outlines),
            sensor=sensor,
            digital=digital,
            withheld=withheld,
            itt_params={n for n, p in profile.parameters.items() if p.authority() == "itt"},
        )
        ents = entries(profile, st)
        head = [
            f"# TODO: what the files in {', '.join(self._src_texts())} do not tell",
            "",
            f"Written by `orthospec init --from` for profile {profile.id} {profile.version} ({sensor}). Each",
            "entry below is a value the files do not state; the draft leaves it empty (never a default) and",
            "`orthospec check` reports the rules listed under it as `missing`, naming this file and line.",
            "Fill a value in delivery.yaml or the table named, or hand the checker's entries to the checker.",
            "",
        ]
        todo_text, rule_lines = render(ents, head=head)
        (tmp / "TODO.md").write_text(todo_text, encoding="utf-8")
        (tmp / "ingest" / "todo-rules.json").write_text(
            json.dumps(rule_lines, indent=0, sort_keys=True) + "\n", encoding="utf-8"
        )
        self.result.todo = sum(1 for e in ents if e.rules)
        self.result.missing_rules = len({r for e in ents for r in e.rules})
        (tmp / "delivery.yaml").write_text(
            _manifest_text(manifest, comments, self._src_texts()), encoding="utf-8"
        )
        _write_csv(
            tmp / "ingest" / "evidence.csv",
            ["field", "value", "file", "line", "xpath"],
            [
                {
                    "field": s.field,
                    "value": _scalar(s.value),
                    "file": s.file,
                    "line": s.line or "",
                    "xpath": s.xpath,
                }
                for m in self.meta
                for s in m.stated
            ],
        )
        (tmp / "ingest" / "points-mapping.yaml").write_text(self._mapping_text(), encoding="utf-8")
        report = self._report(sensor, sensor_src, withheld, vectors)
        (tmp / "INGEST.md").write_text("\n".join(report) + "\n", encoding="utf-8")
        self.result.images = sum(1 for f in self.facts if f.error is None)
        self.result.report = report
        self.result.written = sorted(
            p.relative_to(tmp).as_posix()
            for p in tmp.rglob("*")
            if p.is_file() and not p.is_symlink()
        )

    def _src_texts(self) -> list[str]:
        return [
            os.path.relpath(s.resolve(), self.out.parent.resolve() / self.out.name)
            for s in self.srcs
        ]

    def _image_blocks(self) -> dict[str, str]:
        if not self.outlines:
            return {}
        import shapely

        out = {}
        for image, bounds in sorted(
            self._footprints().items()
        ):  # in the frame CRS, as the outlines
            c = shapely.box(*bounds).centroid
            for bid in sorted(self.outlines):
                if self.outlines[bid].covers(c):
                    out[image] = bid
                    break
        return out

    def _images_table(
        self, ids: dict[str, str], blocks: dict[str, str]
    ) -> tuple[list[str], list[dict[str, Any]]]:
        cols = ["image_id", "file", "block", "gsd", "bit_depth", "bands"]
        rows = []
        for f in (
            self.facts
        ):  # an unreadable one too: the check judges it (raster.readable), never dropped
            gsd = None
            ps = f.pixel_size_m
            if ps is not None and abs(ps[0] - ps[1]) <= 1e-9 * max(ps):
                gsd = _num(ps[0])
            names = [BAND_NAMES.get(c) for c in f.colorinterp]
            bands = (
                ";".join(n for n in names if n)
                if names and all(names) and "ALPHA" not in names
                else None
            )
            rows.append(
                {
                    "image_id": ids[f.path],
                    "file": f.path,
                    "block": blocks.get(ids[f.path]),
                    "gsd": gsd,
                    "bit_depth": f.nbits,
                    "bands": bands,
                }
            )
        return cols, rows

    def _manifest(
        self,
        sensor: str,
        sensor_src: str,
        tables: dict[str, set[str]],
        units: dict[str, str],
        vectors: dict[str, str],
        image_blocks: dict[str, str],
    ) -> tuple[dict[str, Any], dict[str, str]]:
        m: dict[str, Any] = {"orthospec_delivery": 1}
        comments: dict[str, str] = {}

        def put(path: str, value: Any, why: str) -> None:
            node = m
            parts = path.split(".")
            for p in parts[:-1]:
                node = node.setdefault(p, {})
            node[parts[-1]] = value
            comments[path] = why

        for key in FIELDS:
            s = self.fields.get(key)
            if key == "sensor.type":
                put(key, sensor, sensor_src)
            elif key == "id":
                put(key, *self.ident)
            elif s is not None:
                put(key, s.value, s.where)
            elif key in ("project.id", "contractor.name"):
                put(key, "", "TODO (the files state none)")
        if any(lay.role == "seamlines" for lay in self.layers if lay.error is None):
            seam = next(lay for lay in self.layers if lay.role == "seamlines" and lay.error is None)
            put("product.mosaic", True, f"seamlines delivered: {seam.file}")
        if self.outlines:
            blocks = []
            for bid in sorted(self.outlines):
                poly = self.outlines[bid]
                if poly.geom_type == "Polygon" and not poly.interiors:
                    ring = [[_num(x), _num(y)] for x, y in poly.exterior.coords]
                    blocks.append({"id": bid, "polygon": ring})
                else:
                    self.notes.append(
                        f"block {bid}: a multipolygon or a polygon with holes, written without its "
                        "outline (the manifest holds one ring per block)"
                    )
                    blocks.append({"id": bid})
            m["blocks"] = blocks
            comments["blocks"] = f"outlines from {self.outline_source}"
        m["tables"] = {t: f"tables/{t}.csv" for t in table_specs() if t in tables}
        if units:
            m["units"] = dict(sorted(units.items()))
        if vectors:
            m["vectors"] = dict(sorted(vectors.items()))
        m["draft"] = {
            "source": self._src_texts()[0],
            "links": LINKS,
            "todo": "TODO.md",
            "todo_rules": "ingest/todo-rules.json",
            "made_by": f"orthospec {__version__} init --from",
        }
        return m, comments

    def _mapping_text(self) -> str:
        head = (
            "# The survey layouts `orthospec init --from` read (matched on the header): give this file to\n"
            "# `orthospec init DIR --from SOURCE --mapping FILE` and a survey in the same layout is read\n"
            "# the same way, without questions. Roles: the columns of specs/delivery-tables.yaml.\n"
        )
        doc = {
            "orthospec_points_mapping": 1,
            "layouts": [p.layout.to_mapping([p.file]) for p in self.points],
        }
        return head + yaml.safe_dump(doc, sort_keys=False, allow_unicode=True, width=100)

    def _report(
        self, sensor: str, sensor_src: str, withheld: dict[str, str], vectors: dict[str, str]
    ) -> list[str]:
        ok = [f for f in self.facts if f.error is None]
        lines = [
            f"# Draft of {', '.join(self._src_texts())}",
            "",
            f"Written by `orthospec init --from` (orthospec {__version__}). The files are read in place "
            f"through the links under `{LINKS}/`; nothing was copied or written into the source.",
            "",
            "## Images",
            "",
            f"{len(self.facts)} image files, {len(ok)} readable"
            + (
                f", {len(self.facts) - len(ok)} not readable (listed below; kept in tables/images.csv, where the check "
                "judges them)"
                if len(ok) < len(self.facts)
                else ""
            )
            + ". Facts of each: `ingest/rasters.csv`.",
        ]
        crs = Counter(f.crs_name or "(none)" for f in ok)
        if len(crs) > 1:
            lines.append(
                "- **Mixed CRSs**: "
                + ", ".join(f"{k} ({v} images)" for k, v in sorted(crs.items()))
            )
        elif crs:
            lines.append(f"- CRS: {next(iter(crs))}")
        gsd = Counter(
            f"{_num(f.pixel_size[0])} x {_num(f.pixel_size[1])} {f.pixel_unit or ''}".strip()
            for f in ok
            if f.pixel_size
        )
        if len(gsd) > 1:
            lines.append(
                "- **Mixed pixel sizes**: "
                + ", ".join(f"{k} ({v} images)" for k, v in sorted(gsd.items()))
            )
        elif gsd:
            lines.append(f"- Pixel size: {next(iter(gsd))}")
        nogeo = [f for f in ok if not f.georeferenced]
        for f in nogeo:
            lines.append(f"- `{f.path}`: {f.georeference}")
        frame = self._frame()
        if len(crs) > 1 and frame:
            lines.append(
                f"- footprints compared in {frame}, the CRS most images use (tile index, seamlines, block "
                "outlines and survey points are matched there); overlaps only between images of one CRS"
            )
        overlaps = sorted(
            o
            for c in sorted({f.crs_name or "" for f in ok})
            for o in _overlaps(
                [
                    (f.path, f.bounds)
                    for f in ok
                    if f.bounds and f.georeferenced and (f.crs_name or "") == c
                ]
            )
        )
        if overlaps:
            lines.append(
                f"- **Overlapping images**: {len(overlaps)} pairs, e.g. "
                + "; ".join(
                    f"`{a}` / `{b}` ({_num(area)} sq. units)" for a, b, area in overlaps[:5]
                )
            )
        for name, why in self.result.unreadable:
            lines.append(f"- not readable: `{name}`: {why}")
        lines += ["", "## Metadata", ""]
        if not self.meta:
            lines.append("No ISO 19139 or FGDC CSDGM file found.")
        for m in self.meta:
            if m.refused:
                lines.append(f"- `{m.file}`: refused: {m.refused}")
            else:
                lines.append(
                    f"- `{m.file}` ({m.standard}): "
                    + ", ".join(sorted({s.field for s in m.stated}))
                )
        lines += [f"- conflict: {c}" for c in self.conflicts]
        lines.append(f"- sensor type {sensor}: {sensor_src}")
        lines += ["", "## Vector layers", ""]
        if not self.layers:
            lines.append("None found.")
        for lay in self.layers:
            if lay.error:
                lines.append(f"- `{lay.file}` ({lay.role}): not used: {lay.error}")
                continue
            declared = [k for k, v in vectors.items() if v == lay.file]
            line = (
                f"- `{lay.file}` ({lay.role}, {lay.features} features, {lay.driver})"
                + (f", declared as vectors.{declared[0]}" if declared else "")
                + (
                    f", matched by {lay.matched_by}: {len(lay.matched)} images"
                    if lay.matched_by and lay.role != "blocks"
                    else ""
                )
            )
            lines.append(line)
            if lay.role == "blocks":
                lines.append(f"  - blocks: {', '.join(sorted(lay.outlines))}")
            if lay.unmatched_features:
                lines.append(
                    f"  - features matching no image ({len(lay.unmatched_features)}): "
                    + ", ".join(lay.unmatched_features[:20])
                )
            if lay.role == "seamlines" and lay.images_without_feature:
                lines.append(
                    f"  - **images not covered by the seamline polygons** ({len(lay.images_without_feature)}): "
                    + ", ".join(lay.images_without_feature[:20])
                )
            if lay.role in ("tiles",) and lay.images_without_feature:
                lines.append(
                    f"  - images without a feature ({len(lay.images_without_feature)}): "
                    + ", ".join(lay.images_without_feature[:20])
                )
            if lay.driver == "GeoJSON":
                lines.append(
                    "  - GeoJSON: used for matching; the check reads GeoPackage or shapefile only"
                )
            lines += [f"  - {n}" for n in lay.notes]
        lines += ["", "## Surveys", ""]
        if not self.points and not self.point_errors:
            lines.append("No check point or GCP table found (CSV, XLSX, ODS).")
        for pr in self.points:
            where = withheld.get(pr.layout.table) or f"tables/{pr.layout.table}.csv"
            lines.append(f"- `{pr.file}` -> {pr.layout.table}, {pr.rows} points ({where})")
            lines += [f"  - {n}" for n in pr.notes]
            if pr.outside:
                lines.append(
                    f"  - outside every block outline, not in the table ({len(pr.outside)}): "
                    + ", ".join(pr.outside[:20])
                )
        lines += [f"- refused: {e}" for e in self.point_errors]
        others = [(n, sf) for n, sf in self.files if sf.kind == "other"]
        lines += ["", "## Other files", ""]
        if not others and not self.refused:
            lines.append("None.")
        for n, sf in others:
            lines.append(
                f"- `{n}` ({sf.bytes} bytes): not read (documents the profile asks for are named in TODO.md)"
            )
        for r in self.refused:
            lines.append(f"- `{r.rel}`: {r.why}")
        lines += [f"- {n}" for n in self.notes]
        return lines


# ------------------------------------------------------------------ helpers


def _link_target(real: Path, final_dir: Path) -> str:
    """A relative link target (the draft and its source can move together), else absolute."""
    try:
        return os.path.relpath(real, final_dir)
    except ValueError:  # another drive (Windows)
        return str(real)


def _num(v: float) -> float | int:
    r = round(float(v), 9)
    return int(r) if r.is_integer() else r


def _scalar(v: Any) -> str:
    if isinstance(v, dict):
        return f"{v.get('value')} {v.get('unit')}"
    return str(v)


def _flat(d: dict[str, Any], prefix: str = "") -> list[str]:
    out = []
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and not {"value", "unit"} <= set(v):
            out += _flat(v, key + ".")
        elif v not in (None, "", [], {}):
            out.append(key)
    return out


def _overlaps(
    boxes: list[tuple[str, tuple[float, float, float, float] | None]],
) -> list[tuple[str, str, float]]:
    import shapely

    geoms = [shapely.box(*b) for _, b in boxes if b is not None]
    names = [n for n, b in boxes if b is not None]
    if len(geoms) < 2:
        return []
    import numpy as np

    arr = np.array(geoms, dtype=object)
    left, right = shapely.STRtree(arr).query(arr, predicate="intersects")
    keep = left < right
    left, right = left[keep], right[keep]
    areas = shapely.area(
        shapely.intersection(arr[left], arr[right])
    )  # neighbours that only touch: 0
    return sorted(
        (names[i], names[j], float(a))
        for i, j, a in zip(left.tolist(), right.tolist(), areas.tolist(), strict=True)
        if a > 0
    )


def _facts_table(facts: list[RasterFacts]) -> tuple[list[str], list[dict[str, Any]]]:
    cols = [
        "file",
        "bytes",
        "sha256",
        "error",
        "georeference",
        "driver",
        "width",
        "height",
        "count",
        "dtypes",
        "bit_depth",
        "colorinterp",
        "nodata",
        "crs",
        "epsg",
        "pixel_size_x",
        "pixel_size_y",
        "pixel_unit",
        "left",
        "bottom",
        "right",
        "top",
        "compression",
        "lossless",
        "layout",
        "block_shape",
        "overviews",
        "stored_stats",
    ]
    rows = []
    for f in facts:
        b = f.bounds or (None, None, None, None)
        ps = f.pixel_size or (None, None)
        stats = (
            ";".join(
                "" if s is None else "/".join(f"{k}={_num(v)}" for k, v in sorted(s.items()))
                for s in f.stats
            )
            if any(f.stats)
            else ""
        )
        rows.append(
            {
                "file": f.path,
                "bytes": f.bytes,
                "sha256": f.sha256,
                "error": f.error,
                "georeference": f.georeference,
                "driver": f.driver,
                "width": f.width,
                "height": f.height,
                "count": f.count,
                "dtypes": ";".join(f.dtypes),
                "bit_depth": f.bit_depth,
                "colorinterp": ";".join(f.colorinterp),
                "nodata": ";".join("" if v is None else str(_num(v)) for v in f.nodata),
                "crs": f.crs_name,
                "epsg": f.epsg,
                "pixel_size_x": None if ps[0] is None else _num(ps[0]),
                "pixel_size_y": None if ps[1] is None else _num(ps[1]),
                "pixel_unit": f.pixel_unit,
                "left": None if b[0] is None else _num(b[0]),
                "bottom": None if b[1] is None else _num(b[1]),
                "right": None if b[2] is None else _num(b[2]),
                "top": None if b[3] is None else _num(b[3]),
                "compression": f.compression,
                "lossless": f.lossless,
                "layout": f.layout,
                "block_shape": "x".join(map(str, f.block_shape)) if f.block_shape else None,
                "overviews": ";".join(map(str, f.overviews)),
                "stored_stats": stats,
            }
        )
    return cols, rows


def _write_csv(path: Path, cols: list[str], rows: list[dict[str, Any]]) -> None:
    with path.open("w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            w.writerow(["" if r.get(c) is None else _cell(r.get(c)) for c in cols])


def _cell(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)


def _load_mapping(path: Path) -> list[dict[str, Any]]:
    from ..yamlio import YamlError, load_file

    try:
        doc = load_file(path, display=str(path))
    except YamlError as exc:
        raise DeliveryError(str(exc)) from None
    data = doc.data
    if (
        not isinstance(data, dict)
        or data.get("orthospec_points_mapping") != 1
        or not isinstance(data.get("layouts"), list)
    ):
        raise DeliveryError(
            "expected `orthospec_points_mapping: 1` and `layouts: [...]`", file=str(path), line=1
        )
    out = []
    for i, lay in enumerate(data["layouts"]):
        if (
            not isinstance(lay, dict)
            or not isinstance(lay.get("match"), list)
            or not isinstance(lay.get("columns"), dict)
        ):
            raise DeliveryError(
                f"layouts[{i}]: expected match (the header as a list) and columns (role: column)",
                file=str(path),
                line=doc.where(("layouts", i))[0],
            )
        if any(k == "?" for k in lay["columns"]):
            raise DeliveryError(
                f"layouts[{i}]: a column still has the role '?'",
                file=str(path),
                line=doc.where(("layouts", i, "columns"))[0],
            )
        out.append(lay)
    return out


# ------------------------------------------------------------------ manifest text


def _manifest_text(m: dict[str, Any], comments: dict[str, str], srcs: list[str]) -> str:
    """The manifest as YAML, one value per line with its source in a comment (stable layout)."""
    out = [
        f"# Drafted by `orthospec init --from {' '.join(srcs)}`: every value below was read from a file,",
        "# named in the comment beside it. TODO.md lists what the files did not tell; INGEST.md reports",
        "# what was read, decided and refused.",
    ]

    def dump(v: Any) -> str:
        return (
            yaml.safe_dump(v, default_flow_style=True, allow_unicode=True, width=10_000)
            .strip()
            .removesuffix("\n...")
            .strip()
        )

    def emit(node: dict[str, Any], indent: int, prefix: str) -> None:
        for k, v in node.items():
            path = f"{prefix}{k}"
            pad = " " * indent
            note = comments.get(path)
            if (
                isinstance(v, dict)
                and {"value", "unit"} != set(v)
                and k not in ("tables", "units", "vectors", "draft")
            ):
                out.append(f"{pad}{k}:")
                emit(v, indent + 2, path + ".")
                continue
            if k == "blocks" and isinstance(v, list):
                out.append(f"{pad}blocks:{f'  # {note}' if note else ''}")
                for b in v:
                    out.append(f"{pad}  - id: {dump(b['id'])}")
                    if "polygon" in b:
                        out.append(f"{pad}    polygon: {dump(b['polygon'])}")
                continue
            text = f"{pad}{k}: {dump(v)}"
            if note:
                text = f"{text}  # {note}"
            out.append(text)

    emit(m, 0, "")
    return "\n".join(out) + "\n"
