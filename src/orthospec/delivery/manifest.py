"""The delivery manifest (delivery.yaml) as pydantic models; its JSON Schema is published."""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from .convention import table_specs


class _Open(BaseModel):
    """Sub-objects accept extra keys (kept as facts rules may read via manifest.* names)."""

    model_config = ConfigDict(extra="allow", frozen=True)


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class QuantityIn(_Closed):
    value: float
    unit: str


Scalar = float | int | str | bool | dt.date | None


class Project(_Open):
    id: str
    name: str | None = None
    crs: str | None = Field(
        None,
        description=(
            "The CRS the delivery's coordinates and block outlines are written in, e.g. 'EPSG:25832'. A "
            "declaration: it must name the map projection the ITT fixes (the checker's parameter map_crs, "
            "JRC §12.4 Table 12), else the delivery is returned (JRC-12.4-T12-MAP-PROJECTION)."
        ),
    )
    area_of_interest: str | None = Field(None, description="Vector file with the area of interest.")


class Party(_Open):
    name: str
    contact: str | None = None
    role: str | None = None


class Sensor(_Open):
    type: Literal["aerial", "satellite"]
    digital: bool | None = None
    camera: str | None = None
    platform: str | None = None


class Product(_Open):
    """What was bought and delivered. Facts rules gate on (``when: manifest.product.*``) are
    declared here so a profile can only read paths the schema defines. An absent fact that a
    rule's applicability depends on makes that rule ``missing`` (never silently not applicable);
    where the data can decide, the engine computes the fact (``derived.*`` measures) instead."""

    gsd: QuantityIn | None = None
    bit_depth: int | None = None
    bands: list[str] | None = None
    format: str | None = None
    dem_delivered: bool = False
    orthorectification: str | None = Field(
        None,
        description="How the orthoimages were produced: aerotriangulation, space_resection, rpc, "
        "rpc_block, polynomial, physical (JRC §8, §9, §12.8 footnote 6). The engine also "
        "derives it from blocks[].method (derived.orthorectification).",
    )
    mosaic: bool | None = Field(
        None, description="The product is a mosaic (JRC §11, Table 11, Table 12)."
    )
    pansharpened: bool | None = Field(
        None,
        description="The product is pan-sharpened (JRC §10). The engine also derives it from the bands "
        "(derived.pansharpened).",
    )
    dra_applied: bool | None = Field(
        None, description="Dynamic range adjustment was applied (JRC §6.3)."
    )
    update: bool | None = Field(
        None, description="An update of an existing orthoimage coverage (JRC §8.5)."
    )
    extracts: bool | None = Field(
        None,
        description="The contractor declares the images are extracts (JRC §12.4), not the full coverage. "
        "Evidence only: rules use the computed derived.extracts.",
    )
    accuracy_statement: str | None = Field(
        None, description="The contractor's statement of product accuracy."
    )


class Block(_Closed):
    id: str
    polygon: list[list[float]] | None = Field(
        None,
        description=(
            "Block outline [[x, y], ...] in project CRS: a simple ring; outlines of two blocks may touch but "
            "not overlap (a check point belongs to one block)."
        ),
    )
    polygon_file: str | None = None
    method: str | None = Field(
        None, description="aerotriangulation, space_resection, rpc, polynomial..."
    )
    reported: dict[str, QuantityIn] | None = Field(
        None,
        description="Contractor-reported statistics, e.g. rmse_x, rmse_y (recomputed and compared).",
    )
    tags: list[str] = Field(default_factory=list)
    problem_batch: bool = False


class Waiver(_Closed):
    """A waiver the contractor *requests* (delivery.yaml ``waivers:``). Evidence, never authority:
    it never changes a verdict; the record carries it as ``waiver_requested`` and the report lists
    it as requested, not granted. Waivers in force come from the tender profile or the checker's
    file (``check --checker FILE``, delivery/checker.py)."""

    rule: str
    items: list[str] = Field(default_factory=lambda: ["*"])
    justification: str = Field(min_length=1)
    approver: str = Field(min_length=1)
    date: dt.date | None = None


class EdgeTarget(_Closed):
    id: str
    image: str
    roi: list[int] | None = Field(
        None,
        min_length=4,
        max_length=4,
        description="x0, y0, x1, y1 in pixels; omitted: the straight edges of the image are found "
        "and measured automatically (items <id>/x1, <id>/y1, ...).",
    )
    band: int = 1
    direction: Literal["along", "across", "auto"] = "auto"


class Tender(_Closed):
    """The invitation to tender / contract the delivery answers, as the delivery records it."""

    reference: str | None = Field(None, description="ITT / contract reference.")
    parameters: dict[str, QuantityIn | Scalar] = Field(
        default_factory=dict,
        description="Contract values for profile parameters; a tender profile or --param wins over them.",
    )


class Draft(_Closed):
    """Written by ``orthospec init DIR --from SOURCE`` (delivery/draft.py, docs/INGEST.md): the
    delivered files stay in ``source`` and are read in place through the links under ``links``."""

    source: str = Field(
        description="The folder the delivered files were read from (relative to this "
        "folder, or absolute); read in place, never written."
    )
    links: str = Field(
        "source",
        description="Folder of this draft holding one symbolic link per "
        "delivered file, into source.",
    )
    todo: str = Field(
        "TODO.md",
        description="What the files could not tell, with the rules that stay "
        "missing until it is filled.",
    )
    todo_rules: str | None = Field(
        None,
        description="JSON map rule id -> [TODO line, what]: a missing record names its TODO line.",
    )
    made_by: str | None = None


class Manifest(_Closed):
    orthospec_delivery: Literal[1]
    id: str
    project: Project
    contractor: Party
    operator: Party | None = None
    dates: dict[str, dt.date | dt.datetime | str] = Field(default_factory=dict)
    sensor: Sensor
    product: Product = Field(default_factory=Product)
    tender: Tender | None = None
    blocks: list[Block] = Field(default_factory=list)
    tables: dict[str, str] = Field(default_factory=dict)
    vectors: dict[str, str] = Field(
        default_factory=dict, description="seamlines, tiles, blocks, aoi..."
    )
    documents: dict[str, str] = Field(
        default_factory=dict,
        description="Reports the standard requires (internal_qcr, gcp_report, geodetic_control...): "
        "name -> file in the delivery. A listed file that is absent counts as not delivered.",
    )
    units: dict[str, str] = Field(
        default_factory=dict, description="Length unit per table (m default)."
    )
    waivers: list[Waiver] = Field(
        default_factory=list,
        description="Waiver requests of the contractor (never in force: the tender profile or the checker's "
        "file grants waivers; see specs/schema/checker.schema.json).",
    )
    edge_targets: list[EdgeTarget] = Field(default_factory=list)
    notes: str | None = None
    draft: Draft | None = Field(
        None, description="Present in a draft written by `orthospec init --from`."
    )


def manifest_schema() -> dict[str, Any]:
    s = Manifest.model_json_schema(mode="validation")
    s["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    s["$id"] = "https://orthospec.dev/schema/delivery.schema.json"
    s["title"] = "orthospec delivery manifest (delivery.yaml)"
    s["description"] = "Known tables: " + ", ".join(sorted(table_specs())) + "."
    s["properties"]["tables"]["propertyNames"] = {"enum": sorted(table_specs())}
    return s
