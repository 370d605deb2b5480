"""The checker's evidence (``check --checker DIR|FILE``): who checks, their verdicts, waivers and tables.

JRC §2 separates the contractor's internal quality control from the external quality control the
buyer commissions. The delivery is the contractor's evidence, never authority: waivers written in
its delivery.yaml are only *requests*, and its ``manual_checks`` table is the contractor's own
internal-QC statement. A manual rule's verdict and a waiver in force come from the checker's side:
the tender profile's ``waivers:`` or this file, which must therefore lie outside the delivery
(a file the contractor ships cannot grant the contractor anything).

The checker's evidence lives with the checker (issue 29): ``--checker`` names a *checker folder*
(documented in docs/CHECKER.md) or, as before, its single file::

    CHECKER_DIR/
      checker.yaml              this file (required)
      tables/checkpoints.csv    the external QC's check point measurements (JRC §12.6; optional),
                                read by delivery/checker_tables.py
      inspection.gpkg           the inspection grid marked by the checker (optional), inspection/

The folder (and every file the tool reads in it) must lie outside the delivery.

Format of checker.yaml (schema: specs/schema/checker.schema.json)::

    orthospec_checker: 1
    checker: {name: "M. Keller (fictional)", role: external QC, organisation: ...}
    delivery: {id: D-2026-014, files: {tables/checkpoints.csv: {sha256: <sha256>, role: tables.checkpoints}}}
    parameters: {tolerance_xy: {value: 0.5, unit: m}, map_crs: EPSG:25832}  # ITT values in force
    blocks: [{id: B01, polygon: [[x, y], ...]}]      # block outlines in force (map_crs), optional
    area_of_interest: [[x, y], ...]                  # area the photos must cover (map_crs), optional
    manual_checks:
      - {check: JRC-5.3-IDQA, item: "*", date: 2026-06-21, verdict: pass, note: "..."}
      - {check: JRC-6.3-ARTEFACTS, item: F01_0101, file: images/F01_0101.tif, sha256: <sha256>,
         date: 2026-06-21, verdict: pass}        # bound to the image judged (written by `checker init`)
    waivers:
      - {rule: JRC-6.3-CV, items: [F03_0104], justification: "...", approver: "..."}
"""

from __future__ import annotations

import datetime as dt
import posixpath
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StringConstraints,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from ..errors import OrthospecError
from ..provenance import Evidence, sha256_file
from ..yamlio import YamlError, load_file
from .manifest import QuantityIn, Scalar
from .outlines import StatedOutlines, first_overlap, invalid_reason, ring_polygon

if TYPE_CHECKING:
    from .reader import Delivery

Sha256 = Annotated[str, StringConstraints(pattern=r"^[0-9a-fA-F]{64}$")]
#: one vertex of an outline: [x, y] in the ITT's map projection (parameter map_crs), finite
Vertex = tuple[
    Annotated[float, Field(allow_inf_nan=False)], Annotated[float, Field(allow_inf_nan=False)]
]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CheckerParty(_Closed):
    """The person (or unit) performing the external quality control."""

    name: str = Field(min_length=1)
    role: str | None = Field(None, description="e.g. external QC, paying agency GIS unit.")
    organisation: str | None = None
    contact: str | None = None
    project: str | None = Field(
        None,
        min_length=1,
        description=(
            "The contract / project id this external QC works under, as the buyer names it (e.g. ITT 2026/CAP-ORTHO "
            "lot 2). The ledger keeps the Normal/Tightened audit state and the §12.8 rounds under it, never under "
            "the manifest's project.id, which the contractor writes."
        ),
    )


class CheckerManualCheck(_Closed):
    """One human verdict on a manual rule (``manual: true``) for one item or ``*`` (all items).

    ``file`` and ``sha256`` bind the verdict to the content judged (issue 29 item 4): `checker init`
    writes them for every item that is a delivered file (an image); at check time a verdict whose
    item's file now holds other content (changed, or another file swapped in) is ``missing`` with the
    reason, never carried over. An entry without ``verdict`` is still to be judged (the skeleton
    `checker init` writes)."""

    check: str = Field(min_length=1, description="The manual rule's id, e.g. JRC-5.3-IDQA.")
    item: str = Field("*", min_length=1, description="Item id in the rule's scope, or * for all.")
    date: dt.date | None = Field(
        None, description="When the verdict was given (required with a verdict)."
    )
    verdict: Literal["pass", "fail"] | None = Field(
        None, description="pass or fail; empty: still to be judged."
    )
    inspector: str | None = Field(
        None, description="Who inspected, when not the checker named above."
    )
    note: str | None = None
    file: str | None = Field(
        None,
        min_length=1,
        description=(
            "The delivered file the verdict was given on (path inside the delivery), written by `checker init`."
        ),
    )
    sha256: Sha256 | None = Field(
        None, description="That file's SHA-256 when it was judged (written by the tool)."
    )

    @model_validator(mode="after")
    def _dated(self) -> CheckerManualCheck:
        if self.verdict is not None and self.date is None:
            raise ValueError("a verdict needs its date (date: YYYY-MM-DD)")
        if (self.file is None) != (self.sha256 is None):
            raise ValueError(
                "file and sha256 go together: the file judged and its SHA-256 when judged"
            )
        return self


class CheckerWaiver(_Closed):
    """A waiver granted by the checker: the listed items of ``rule`` are ``waived``."""

    rule: str = Field(min_length=1)
    items: list[str] = Field(default_factory=lambda: ["*"], min_length=1)
    justification: str = Field(min_length=1)
    approver: str = Field(min_length=1, description="Who, on the buyer's side, granted the waiver.")
    date: dt.date | None = None


class PinnedFile(_Closed):
    """A pinned file with the role the delivery gave it when the checker signed (`checker init` writes it)."""

    sha256: Sha256
    role: str | None = Field(
        None,
        min_length=1,
        description=(
            "Where the delivery used the file: tables.<name>, documents.<name>, vectors.<name>, "
            "project.area_of_interest, or <table>:<item id> for a table's file cell (images:F01_0101)."
        ),
    )


class CheckerDelivery(_Closed):
    """The delivery the checker's verdicts were given on: a checker file signs content, not a folder name.

    A different delivery id, manifest or pinned file at check time is exit 2 (the verdicts and
    waivers of this file were given on other content)."""

    id: str = Field(
        min_length=1, description="The delivery id (delivery.yaml `id`) this file was written for."
    )
    manifest_sha256: Sha256 | None = Field(
        None, description="SHA-256 of the delivery.yaml the checker read."
    )
    files: dict[str, Sha256 | PinnedFile] = Field(
        default_factory=dict,
        description=(
            "Evidence the checker signed: path inside the delivery -> SHA-256, or {sha256, role}. Any extension; "
            "refused at check time when the file changed, or the delivery no longer uses it (for that role, "
            "when given): a pin cannot be dodged by re-pointing the manifest or a table's file cell."
        ),
    )


class CheckerBlock(_Closed):
    """A block outline in force (JRC §12.4 "block/site", the unit of acceptance of §12.7/§12.8)."""

    id: str = Field(min_length=1, description="The block id (delivery.yaml blocks[].id).")
    polygon: list[Vertex] = Field(
        min_length=3,
        description=(
            "The outline as one ring of [x, y] vertices in the ITT's map projection (parameter map_crs); "
            "a simple ring, not overlapping another block's."
        ),
    )


class CheckerModel(_Closed):
    orthospec_checker: Literal[1]
    checker: CheckerParty
    delivery: CheckerDelivery
    parameters: dict[str, QuantityIn | Scalar] = Field(
        default_factory=dict,
        description=(
            'ITT values in force (JRC §2.5 "the tolerance stated in the ITT"), same shape as the manifest\'s '
            "tender.parameters; --param wins over them, they win over the tender profile and the standard."
        ),
    )
    blocks: list[CheckerBlock] = Field(
        default_factory=list,
        description=(
            "Block outlines in force (JRC §12.4, §12.7): when given, check points count for a block by these "
            "outlines, and the manifest's blocks[].polygon are declarations compared with them."
        ),
    )
    area_of_interest: list[Vertex] | None = Field(
        None,
        min_length=3,
        description=(
            'The area the photo lay-down must cover (JRC §5.2.2 "all the surveyed area"), one ring of [x, y] in '
            "map_crs; when given it is in force and the manifest's project.area_of_interest is a declaration."
        ),
    )
    manual_checks: list[CheckerManualCheck] = Field(default_factory=list)
    waivers: list[CheckerWaiver] = Field(default_factory=list)
    units: dict[Literal["checkpoints"], Literal["m", "ft", "usft"]] = Field(
        default_factory=dict,
        description=(
            "Length unit of the coordinate columns of the folder's tables/checkpoints.csv (m when not given); "
            "it must be the unit of the delivery's project.crs axes, as the delivery's own tables."
        ),
    )

    @field_validator("parameters", "blocks", "manual_checks", "waivers", "units", mode="before")
    @classmethod
    def _empty(cls, v: Any, info: ValidationInfo) -> Any:
        """A section written with nothing under it (``parameters:`` and only comments, as the skeleton
        `checker init` writes) is empty, not an error."""
        if v is None:
            return {} if info.field_name in ("parameters", "units") else []
        return v


#: the files of a checker folder that `check` reads (relative POSIX paths); anything else is the checker's own
CHECKER_FILE = "checker.yaml"
CHECKPOINTS_TABLE = "tables/checkpoints.csv"
INSPECTION_GRID = "inspection.gpkg"


@dataclass(frozen=True)
class Checker:
    """A loaded checker: the model, its display name, its SHA-256 and entry lines; its folder, if any."""

    model: CheckerModel
    name: str
    sha256: str
    lines: dict[tuple[Any, ...], int]
    #: the path as the user typed it, for messages
    display: str = ""
    #: the checker folder (``--checker DIR``), None for a single checker file
    folder: Path | None = None
    #: the delivery root (resolved) the checker was loaded against: no file of the folder may lie in it
    delivery_root: Path | None = None

    def at(self, *path: Any) -> str:
        """``file:line`` of a YAML path (``("delivery", "id")``), or the file alone."""
        line = self.lines.get(tuple(path))
        shown = self.display or self.name
        return f"{shown}:{line}" if line else shown

    @property
    def party(self) -> CheckerParty:
        return self.model.checker

    def who(self) -> str:
        """``name (role, organisation)`` as a report states who signed or granted."""
        p = self.model.checker
        extra = ", ".join(x for x in (p.role, p.organisation) if x)
        return f"{p.name} ({extra})" if extra else p.name

    def evidence(self, section: str, index: int) -> Evidence:
        """Where an entry stands: the file by name (never its absolute path), its YAML path and line."""
        line = self.lines.get((section, index))
        return Evidence(
            f"checker:{self.name}",
            self.sha256,
            (),
            f"{section}[{index}]" + (f" (line {line})" if line else ""),
        )

    def summary(self) -> dict[str, Any]:
        """For the QCR document: who checked, from which file (name and hash); with a folder, the folder's
        name and every file `check` read from it (path and hash), so the run names all its evidence."""
        out = {
            **self.model.checker.model_dump(mode="json", exclude_none=True),
            "file": self.name,
            "sha256": self.sha256,
        }
        if self.folder is not None:
            out["folder"] = self.folder.name
            out["files"] = [
                {"path": rel, "sha256": sha256_file(self.folder / rel)}
                for rel in (CHECKPOINTS_TABLE, INSPECTION_GRID)
                if self.has(rel)
            ]
        return out

    def has(self, rel: str) -> bool:
        """The folder holds ``rel`` (one of the files `check` reads)."""
        return self.folder is not None and (self.folder / rel).is_file()

    def file(self, rel: str) -> Path | None:
        """The folder's ``rel`` when present, refused (exit 2) when it is a link into the delivery or not a
        regular file: the checker's evidence cannot be the contractor's file under another name."""
        if self.folder is None:
            return None
        p = self.folder / rel
        if not p.exists() and not p.is_symlink():
            return None
        if not p.is_file():
            raise OrthospecError(f"checker folder {self.display}: {rel} is not a regular file")
        if self.delivery_root is not None and p.resolve().is_relative_to(self.delivery_root):
            raise OrthospecError(
                f"checker folder {self.display}: {rel} resolves to {p.resolve()}, inside the "
                "delivery: the checker's evidence cannot be a file of the contractor's delivery "
                "(JRC §2, §12.4 independent check points); copy what you measured into the folder"
            )
        return p


def _refuse_inside(path: Path, delivery_root: Path | None, what: str = "checker file") -> None:
    if delivery_root is None:
        return
    if path.resolve().is_relative_to(Path(delivery_root).resolve()):
        raise OrthospecError(
            f"{what} {str(path)!r} lies inside the delivery {str(delivery_root)!r}: the checker's "
            "verdicts and waivers cannot travel with the contractor's delivery (JRC §2, external quality "
            "control); keep it outside the delivery folder"
        )


def _duplicates(model: CheckerModel, display: str, lines: dict[tuple[str, int], int]) -> None:
    seen: dict[tuple[str, str], int] = {}
    for i, m in enumerate(model.manual_checks):
        key = (m.check, m.item)
        if key in seen:
            raise OrthospecError(
                f"{display}:{lines.get(('manual_checks', i), '?')}: manual_checks: "
                f"{m.check} item {m.item!r} is given twice (first at entry {seen[key] + 1}); "
                "one verdict per check and item"
            )
        seen[key] = i


def _check_outlines(chk: Checker) -> None:
    """The outlines the checker states are valid rings, blocks named once and not overlapping (the
    same test as the manifest's, delivery/outlines.py); exit 2 naming the file and line otherwise."""
    m = chk.model
    seen: dict[str, int] = {}
    polys = []
    for i, b in enumerate(m.blocks):
        if b.id in seen:
            raise OrthospecError(
                f"checker file {chk.at('blocks', i)}: blocks[{i}]: block {b.id} is given twice "
                f"(first at blocks[{seen[b.id]}]); one outline per block"
            )
        seen[b.id] = i
        poly = ring_polygon(b.polygon)
        why = invalid_reason(poly)
        if why:
            raise OrthospecError(
                f"checker file {chk.at('blocks', i, 'polygon')}: blocks[{i}] ({b.id}): the polygon "
                f"is not a valid block outline ({why}); a block outline is a simple ring whose "
                "edges do not cross"
            )
        polys.append(poly)
    hit = first_overlap(polys)
    if hit is not None:
        i, j, area = hit
        raise OrthospecError(
            f"checker file {chk.at('blocks', j, 'polygon')}: blocks[{j}] ({m.blocks[j].id}): the "
            f"polygon overlaps the outline of block {m.blocks[i].id} (blocks[{i}]) over an area of "
            f"{area:.6g} (map_crs units squared); blocks are the units of acceptance (JRC §12.4, "
            "§12.8) and a check point cannot belong to two: outlines may touch but not overlap"
        )
    if m.area_of_interest is not None:
        why = invalid_reason(ring_polygon(m.area_of_interest))
        if why:
            raise OrthospecError(
                f"checker file {chk.at('area_of_interest')}: area_of_interest is not a valid "
                f"outline ({why}); give one simple ring of [x, y] vertices in map_crs"
            )


def stated_outlines(chk: Checker) -> StatedOutlines | None:
    """The outlines this checker file puts in force, with evidence naming it; None when it states none."""
    m = chk.model
    if not m.blocks and m.area_of_interest is None:
        return None
    blocks = {b.id: (tuple(b.polygon), chk.evidence("blocks", i)) for i, b in enumerate(m.blocks)}
    aoi = None
    if m.area_of_interest is not None:
        line = chk.lines.get(("area_of_interest",))
        aoi = (
            tuple(m.area_of_interest),
            Evidence(
                f"checker:{chk.name}",
                chk.sha256,
                (),
                "area_of_interest" + (f" (line {line})" if line else ""),
            ),
        )
    return StatedOutlines(f"checker file {chk.name}", blocks, aoi)


def load_checker(
    path: str | Path, *, delivery_root: str | Path | None = None, delivery: Delivery | None = None
) -> Checker:
    """Read and validate a checker file; refuse one inside ``delivery_root`` (or ``delivery``'s root),
    and one written for another delivery or other content than ``delivery`` (:func:`bind`).

    Raises
    ------
    OrthospecError
        (exit 2) naming ``file:line:col`` and what was expected, or why the place is refused.
    """
    p = Path(path)
    if delivery_root is None and delivery is not None:
        delivery_root = delivery.root
    root = Path(delivery_root) if delivery_root is not None else None
    folder = None
    _refuse_inside(p, root, "checker folder" if p.is_dir() else "checker file")
    if p.is_file() and p.name == CHECKER_FILE:  # DIR/checker.yaml names the checker folder DIR
        p = p.parent
    if p.is_dir():  # a checker folder: its checker.yaml, its tables and grid (docs/CHECKER.md)
        _refuse_inside(p, root, "checker folder")
        folder, p = p, p / CHECKER_FILE
        if not p.is_file():
            raise OrthospecError(
                f"checker folder {str(folder)!r} holds no {CHECKER_FILE}: a checker folder is "
                f"{CHECKER_FILE} (who checks, the ITT values, manual verdicts, waivers) plus the "
                f"checker's tables ({CHECKPOINTS_TABLE}) and inspection grid ({INSPECTION_GRID}); "
                "`orthospec checker init` writes one"
            )
    _refuse_inside(p, root)
    display = (
        str(path)
        if folder is None or Path(path).name == CHECKER_FILE
        else str(Path(path) / CHECKER_FILE)
    )
    try:
        doc = load_file(p, display=display)
    except YamlError as exc:
        raise OrthospecError(f"checker file {exc}") from None
    if not isinstance(doc.data, dict):
        raise OrthospecError(
            f"{display}:1:1: a checker file must be a YAML mapping "
            "(orthospec_checker: 1, checker: {name: ...}, delivery: {id: ...}, parameters, "
            "manual_checks, waivers)"
        )
    try:
        model = CheckerModel.model_validate(doc.data)
    except ValidationError as exc:
        lines = doc.located_errors(exc.errors(), display)
        raise OrthospecError("invalid checker file:\n  " + "\n  ".join(lines)) from None
    marks: dict[tuple[Any, ...], int] = {
        (sec, i): doc.where((sec, i))[0] or 0
        for sec in ("manual_checks", "waivers")
        for i in range(len(doc.data.get(sec) or []))
    }
    marks[("units",)] = doc.where(("units",))[0] or 0
    extra: list[tuple[Any, ...]] = [
        ("delivery",),
        ("delivery", "id"),
        ("delivery", "manifest_sha256"),
        *(("delivery", "files", k) for k in model.delivery.files),
        ("parameters",),
        *(("parameters", k) for k in model.parameters),
    ]
    extra += [
        ("area_of_interest",),
        *(("blocks", i, "polygon") for i in range(len(model.blocks))),
        *(
            ("blocks", i, "polygon", k)
            for i, b in enumerate(model.blocks)
            for k in range(len(b.polygon))
        ),
    ]
    marks.update({k: doc.where(k)[0] or 0 for k in extra})
    marks.update(
        {("blocks", i): doc.where(("blocks", i))[0] or 0 for i in range(len(model.blocks))}
    )
    _duplicates(model, display, marks)
    chk = Checker(
        model,
        p.name,
        sha256_file(p),
        marks,
        display,
        folder,
        Path(root).resolve() if root is not None else None,
    )
    _check_outlines(chk)
    if delivery is not None:
        bind(chk, delivery)
    return chk


def bind(chk: Checker, d: Delivery) -> None:
    """Refuse (exit 2) a checker file written for another delivery, manifest or evidence content.

    The checker's manual verdicts and waivers vouch for what the checker saw; applied to other
    content they would grant the contractor verdicts nobody gave (red team R5: check points deleted
    after the checker signed their source). Nothing is written onto ``d``: the outlines the file states
    are put in force by the evaluation (``stated_outlines``, held by the engine's context)."""
    b = chk.model.delivery
    other = "the checker's verdicts were given on other content"
    if b.id != d.id:
        raise OrthospecError(
            f"checker file {chk.at('delivery', 'id')} is for delivery {b.id}; this delivery "
            f"is {d.id}: {other}"
        )
    if b.manifest_sha256 and b.manifest_sha256.lower() != d.manifest_sha256.lower():
        raise OrthospecError(
            f"checker file {chk.at('delivery', 'manifest_sha256')} pins delivery.yaml sha256 "
            f"{b.manifest_sha256.lower()}, the delivery's is {d.manifest_sha256}: {other}"
        )
    manifest_roles = file_roles(d, tables=False)
    table_roles: dict[str, str] | None = None
    for rel, pin in sorted(b.files.items()):
        want, role = (pin, None) if isinstance(pin, str) else (pin.sha256, pin.role)
        where = chk.at("delivery", "files", rel)
        try:
            path = d.path(rel, what=f"delivery.files.{rel}", file=None)
        except OrthospecError as exc:
            raise OrthospecError(f"checker file {where}: {exc}") from None
        norm = posixpath.normpath(rel)
        roles = manifest_roles
        if (role is None and norm not in roles.values()) or (
            role is not None and role not in roles
        ):
            if table_roles is None:  # a table's file cells: read only when a pin needs them
                table_roles = {**manifest_roles, **_table_file_roles(d)}
            roles = table_roles
        if role is not None:
            now = roles.get(role)
            if now != norm:
                # red team R19 and issue 29 item 4: the manifest or a table re-pointed the role at another file
                # after the checker signed, the pinned file left untouched
                said = f"uses {now} for it" if now is not None else "no longer has it"
                raise OrthospecError(
                    f"checker file {where} pins {rel} as {role}; the delivery now {said}: {other}"
                )
        elif norm not in roles.values():
            raise OrthospecError(
                f"checker file {where} pins {rel}, which the delivery no longer uses (no table, "
                f"document, vector, area of interest or table file cell names it): {other}"
            )
        if not path.is_file():
            raise OrthospecError(
                f"checker file {where} pins {rel}, which the delivery does not contain: {other}"
            )
        got = d.sha256(rel)
        if got.lower() != want.lower():
            raise OrthospecError(
                f"checker file {where} pins {rel} sha256 {want.lower()}, the delivery's is "
                f"{got}: {other}"
            )


def file_roles(d: Delivery, *, tables: bool = True) -> dict[str, str]:
    """Role -> path (normalised, relative to the delivery) of every file the delivery uses: its tables,
    documents and vectors (``tables.<name>`` ...), ``project.area_of_interest``, and (``tables=True``) each
    file cell of a table with a ``file`` column (``<table>:<item id>``, e.g. ``images:F01_0101``).

    What a pin's ``role`` names (`checker init` writes them); one place that knows where a delivery names files."""
    m = d.manifest
    out = {
        f"{kind}.{name}": posixpath.normpath(v)
        for kind, mapping in (
            ("tables", m.tables),
            ("documents", m.documents),
            ("vectors", m.vectors),
        )
        for name, v in mapping.items()
    }
    if m.project.area_of_interest:
        out["project.area_of_interest"] = posixpath.normpath(m.project.area_of_interest)
    if tables:
        out.update(_table_file_roles(d))
    return out


def _table_file_roles(d: Delivery) -> dict[str, str]:
    from .reader import PATH_COLUMNS

    out: dict[str, str] = {}
    for name in d.manifest.tables:
        t = d.table(name)
        if t is None:
            continue
        for col in sorted(PATH_COLUMNS & set(t.df.columns)):
            cells = t.df[col]
            have = cells.notna().to_numpy()
            for item, v in zip(t.ids[have].tolist(), cells[have].tolist(), strict=True):
                out.setdefault(f"{name}:{item}", posixpath.normpath(str(v)))
    return out


def checker_schema() -> dict[str, Any]:
    """The published JSON Schema of the checker file (specs/schema/checker.schema.json)."""
    s = CheckerModel.model_json_schema(mode="validation")
    s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    s["$id"] = "https://orthospec.dev/schema/checker.schema.json"
    s["title"] = "orthospec checker file (check --checker FILE)"
    s["description"] = (
        "The external quality control's manual-check verdicts and waivers in force "
        "(JRC §2). Kept outside the delivery; the delivery's own waivers are requests "
        "and its manual_checks table is the contractor's internal-QC statement."
    )
    return s
