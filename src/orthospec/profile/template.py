"""`orthospec init DIR [--profile ID --sensor aerial|satellite]`: a delivery template that validates
as written (in spec/: it is what a profile reads, written in the delivery convention). With a
profile, it holds every table, column and document that profile reads for that
sensor (required and optional marked in TEMPLATE.md and in the manifest's comments); the manifest
points at a local copy of the JSON Schema (an editor validates it offline)."""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..delivery.convention import table_specs
from ..errors import DeliveryError
from .applicability import cannot_apply
from .loader import load_profile

MANIFEST_TEMPLATE = """\
# yaml-language-server: $schema=./delivery.schema.json
# orthospec delivery manifest. Every path is relative to this folder. Fill in, then run:
#   orthospec check {name} --profile {profile}
# TEMPLATE.md lists every table, column and document the profile reads (required / optional).
orthospec_delivery: 1
id: D-0000-001                      # your delivery id
project:
  id: P-0000                        # project id (the same across redeliveries)
  name: Orthophoto campaign
  crs: "EPSG:25832"                 # national projection every image must be in
contractor: {{name: Contractor Ltd, contact: qa@example.org}}
operator: {{name: Operator Name, role: QA manager}}
dates: {{delivered: 2026-01-31, acquired_from: 2026-01-01, acquired_to: 2026-01-15}}
sensor:
  type: {sensor}                      # aerial | satellite
  digital: true                     # false for scanned film
  camera: UltraCam Eagle
  platform: aircraft
product:
  gsd: {{value: 0.25, unit: m}}       # output pixel size
  bit_depth: 8
  bands: [R, G, B, NIR]
  format: GeoTIFF
  dem_delivered: false
tender:
  reference: ITT reference
  parameters:                       # values the tender fixed (a tender profile or --param wins)
    tolerance_xy: {{value: 0.5, unit: m}}
blocks:
  - id: B01
    method: aerotriangulation       # or space_resection: each image is then its own block
    # polygon: [[x, y], [x, y], [x, y]]          # block outline in the project CRS
    # reported: {{rmse_x: {{value: 0.3, unit: m}}, rmse_y: {{value: 0.3, unit: m}}}}
tables:                             # CSV files; columns: specs/delivery-tables.yaml
{tables}
{documents}units: {{checkpoints: m, gcps: m}}    # length unit of coordinate columns: m, ft or usft
waivers: []                         # - {{rule: RULE-ID, items: [ITEM], justification: ..., approver: ...}}
"""


#: measures computed from tables (not ``<table>.<column>``): what each reads. Prefix match, longest
#: first. ("table", T), ("column", T, C), ("manifest", path), ("param", name), ("blocks",), ("checker", what)
NEEDS: dict[str, tuple[tuple[str, ...], ...]] = {
    "raster.reported_mean_diff": (("column", "images", "mean_dn"),),
    "raster.reported_min_diff": (("column", "images", "min_dn"),),
    "raster.reported_max_diff": (("column", "images", "max_dn"),),
    "raster.reported_std_diff": (("column", "images", "std_dn"),),
    "raster.stats_mean_diff": (("column", "images", "mean_dn"),),
    "raster.crs_ok": (("param", "map_crs"),),
    "raster.cloud_cover_declared": (("column", "images", "cloud_cover"),),
    "raster.": (("table", "images"),),
    "checkpoints.reported_diff": (("manifest", "blocks.reported"),),
    "checkpoints.": (("table", "checkpoints"), ("blocks",)),
    "gcps.": (("table", "gcps"), ("blocks",)),
    "camera.": (("table", "cameras"),),
    "flight.": (("table", "flights"), ("column", "images", "roll")),
    "geometry.gsd_from_flying_height": (
        ("column", "images", "flying_height"),
        ("table", "cameras"),
        ("column", "images", "flight_id"),
    ),
    "derived.photo_coverage": (
        ("table", "flights"),
        ("table", "cameras"),
        ("column", "images", "exposure_x"),
        ("column", "images", "flying_height"),
    ),
    "derived.area_of_interest_agrees": (
        ("manifest", "project.area_of_interest"),
        ("checker", "area_of_interest"),
    ),
    "derived.block_outlines_agree": (("blocks",), ("checker", "blocks")),
    "derived.project_crs_agrees": (("manifest", "project.crs"), ("param", "map_crs")),
    "derived.resolution_class_agrees": (("table", "scenes"),),
    "derived.master_images": (("table", "scenes"),),
    "derived.is_master": (("table", "scenes"),),
    "demfile.": (("table", "dem"),),
    "derived.orthorectification": (
        ("blocks",),
        ("manifest", "blocks.method"),
        ("manifest", "product.orthorectification"),
    ),
    "derived.dem_blocks": (("table", "dem"),),
    "derived.": (),
    "mosaic.": (
        ("manifest", "vectors.seamlines"),
        ("blocks",),
        ("manifest", "project.area_of_interest"),
    ),
    "edge.": (("manifest", "edge_targets"),),
    "seamline.": (("manifest", "vectors.seamlines"), ("manifest", "vectors.seamlines.image_id")),
    "acquisition.": (("column", "images", "exposure_time"), ("manifest", "dates")),
    "rollup.block": (("blocks",),),
    "rollup.": (),
}
_NAME = re.compile(r"\b([a-z_][a-z_0-9]*(?:\.[a-z_][a-z_0-9]*)+)\b")
_WORD = re.compile(r"\b([a-z_][a-z_0-9]*)\b")


def rule_inputs(rule: Any, params: Iterable[str]) -> list[tuple[str, ...]]:
    """The delivery facts a rule reads (see :data:`NEEDS`), in the order it reads them."""
    specs = table_specs()
    texts = [rule.when or "", rule.measure]
    req = rule.requirement
    texts += [str(v) for v in (req.value, req.min, req.max) if isinstance(v, str)]
    out: list[tuple[str, ...]] = []
    if rule.manual or rule.measure.startswith("manual."):
        return [("checker", "manual_checks")]
    for text in texts:
        for name in _NAME.findall(text):
            head, rest = name.split(".", 1)
            if head == "manifest" and rest.startswith("tables."):
                out.append(("table", rest.split(".", 1)[1]))
            elif head == "manifest":
                out.append(("manifest", rest))
            elif head in specs and rest.split(".", 1)[0] in specs[head].columns:
                out.append(("column", head, rest.split(".", 1)[0]))  # images.flight_id.complete too
            else:
                for prefix in sorted(NEEDS, key=len, reverse=True):
                    if name.startswith(prefix):
                        out.extend(NEEDS[prefix])
                        break
                else:
                    if head in specs:
                        out.append(("table", head))
        for word in _WORD.findall(text):
            if word in params:
                out.append(("param", word))
    if rule.scope == "block":
        out.insert(0, ("blocks",))  # without blocks a block rule has no item at all
    seen: list[tuple[str, ...]] = []
    for x in out:
        if x not in seen:
            seen.append(x)
    return seen


def profile_needs(
    profile: str, sensor: str
) -> tuple[dict[str, dict[str, list[str]]], dict[str, str]]:
    """What ``profile`` reads for ``sensor``: {table: {column: [rule ids]}} and {document: level}
    (from :func:`rule_inputs`, the reading ``init --from`` builds its TODO.md on)."""
    prof = load_profile(profile)
    params = set(prof.parameters)
    tables: dict[str, dict[str, list[str]]] = {}
    documents: dict[str, str] = {}
    for rule in prof.rules:
        if cannot_apply(rule, {sensor}, True if sensor == "aerial" else None):
            continue
        if rule.manual or rule.measure.startswith("manual."):
            tables.setdefault("manual_checks", {})
            continue
        for inp in rule_inputs(rule, params):
            if inp[0] == "table":
                tables.setdefault(inp[1], {})
            elif inp[0] == "column":
                tables.setdefault(inp[1], {}).setdefault(inp[2], []).append(rule.id)
        m = re.match(r"manifest\.documents\.(\w+)", rule.measure)
        if m:
            level = "required" if rule.level == "mandatory" else "recommended"
            if documents.get(m.group(1)) != "required":
                documents[m.group(1)] = level
    return tables, documents


def write_template(
    folder: Path, *, profile: str | None = None, sensor: str = "aerial"
) -> list[Path]:
    from ..resources import specs_dir

    folder = Path(folder)
    if (folder / "delivery.yaml").exists():
        raise DeliveryError(f"{folder / 'delivery.yaml'} already exists; refusing to overwrite it")
    specs = table_specs()
    needs, documents = profile_needs(profile, sensor) if profile else ({n: {} for n in specs}, {})
    (folder / "tables").mkdir(parents=True, exist_ok=True)
    (folder / "images").mkdir(exist_ok=True)
    written = []
    lines = []
    guide = [
        f"# Delivery template{f' for {profile} ({sensor})' if profile else ''}",
        "",
        "Every table below is a CSV file under tables/ (header row written). Columns marked "
        "*required* must be present; *optional* ones are read when given (a rule that needs a "
        "missing value records `missing`, never `pass`).",
        "",
    ]
    for name in specs:
        if name not in needs:
            continue
        spec = specs[name]
        read = needs[name]
        cols = [c for c in spec.columns if spec.columns[c].required or c in read or not profile]
        rel = f"tables/{name}.csv"
        lines.append(f"  {name}: {rel}")
        p = folder / rel
        if not p.exists():
            p.write_text(",".join(cols) + "\n", encoding="utf-8")
            written.append(p)
        guide += [
            f"## {name} ({rel}): {spec.description}",
            "",
            "| column | required | unit | description |",
            "|---|---|---|---|",
        ]
        for c in cols:
            cs = spec.columns[c]
            used = (
                f" Read by {', '.join(sorted(set(read.get(c, []))))[:200]}." if read.get(c) else ""
            )
            guide.append(
                f"| {c} | {'required' if cs.required else 'optional'} | {cs.unit or ''} | "
                f"{cs.description}{used} |"
            )
        guide.append("")
    docs = ""
    if documents:
        docs = (
            "documents:                          # files under documents/ (required / recommended)\n"
            + "".join(
                f"  {k}: documents/{k}.pdf{' ' * max(1, 24 - len(k) * 2)}# {v}\n"
                for k, v in sorted(documents.items())
            )
        )
        guide += [
            "## documents",
            "",
            "| document | level |",
            "|---|---|",
            *(f"| {k} | {v} |" for k, v in sorted(documents.items())),
            "",
        ]
    m = folder / "delivery.yaml"
    m.write_text(
        MANIFEST_TEMPLATE.format(
            name=folder.name,
            tables="\n".join(lines),
            profile=profile or "jrc-v3",
            sensor=sensor,
            documents=docs,
        ),
        encoding="utf-8",
    )
    schema = folder / "delivery.schema.json"
    schema.write_text(
        (specs_dir() / "schema" / "delivery.schema.json").read_text(encoding="utf-8"),
        encoding="utf-8",
    )
    g = folder / "TEMPLATE.md"
    g.write_text("\n".join(guide), encoding="utf-8")
    return [m, schema, g, *written]
