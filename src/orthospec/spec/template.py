"""`orthospec init DIR [--profile ID --sensor aerial|satellite]`: a delivery template that validates
as written (in spec/: it is what a profile reads, written in the delivery convention). With a profile, it holds every table, column and document that profile reads for that
sensor (required and optional marked in TEMPLATE.md and in the manifest's comments); the manifest
points at a local copy of the JSON Schema (an editor validates it offline)."""

from __future__ import annotations

from pathlib import Path

from ..delivery.convention import table_of_scope, table_specs
from ..errors import DeliveryError
from .applicability import cannot_apply
from .catalog import measure_info
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


def _table_read(head: str, col: str) -> str | None:
    """The delivery table a measure reference reads: the table it names, else the items table of
    the measure's scope (``raster.gsd`` is an image measure: images)."""
    if head in table_specs():
        return head
    info = measure_info(f"{head}.{col}")
    return table_of_scope(info[0]) if info is not None else None


def profile_needs(profile: str, sensor: str) -> tuple[dict[str, dict[str, list[str]]], dict[str, str]]:
    """What ``profile`` reads for ``sensor``: {table: {column: [rule ids]}} and {document: level}."""
    import re

    prof = load_profile(profile)
    specs = table_specs()
    tables: dict[str, dict[str, list[str]]] = {}
    documents: dict[str, str] = {}
    for rule in prof.rules:
        if cannot_apply(rule, {sensor}, True if sensor == "aerial" else None):
            continue
        texts = [rule.measure, rule.when or ""]
        for text in texts:
            for ref in re.findall(r"\b([a-z_]+)\.([a-z_]+)", text):
                head, col = ref
                if head == "manifest":
                    continue
                table = _table_read(head, col)
                if table is None:
                    continue
                cols = tables.setdefault(table, {})
                if table == head and col in specs[table].columns:
                    cols.setdefault(col, []).append(rule.id)
        if rule.manual or rule.measure.startswith("manual."):
            tables.setdefault("manual_checks", {})
        m = re.match(r"manifest\.documents\.(\w+)", rule.measure)
        if m:
            level = "required" if rule.level == "mandatory" else "recommended"
            if documents.get(m.group(1)) != "required":
                documents[m.group(1)] = level
    return tables, documents


def write_template(folder: Path, *, profile: str | None = None, sensor: str = "aerial") -> list[Path]:
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
    guide = [f"# Delivery template{f' for {profile} ({sensor})' if profile else ''}", "",
             "Every table below is a CSV file under tables/ (header row written). Columns marked "
             "*required* must be present; *optional* ones are read when given (a rule that needs a "
             "missing value records `missing`, never `pass`).", ""]
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
        guide += [f"## {name} ({rel}): {spec.description}", "", "| column | required | unit | description |",
                  "|---|---|---|---|"]
        for c in cols:
            cs = spec.columns[c]
            used = f" Read by {', '.join(sorted(set(read.get(c, []))))[:200]}." if read.get(c) else ""
            guide.append(f"| {c} | {'required' if cs.required else 'optional'} | {cs.unit or ''} | "
                         f"{cs.description}{used} |")
        guide.append("")
    docs = ""
    if documents:
        docs = "documents:                          # files under documents/ (required / recommended)\n" + "".join(
            f"  {k}: documents/{k}.pdf{' ' * max(1, 24 - len(k) * 2)}# {v}\n" for k, v in sorted(documents.items()))
        guide += ["## documents", "", "| document | level |", "|---|---|",
                  *(f"| {k} | {v} |" for k, v in sorted(documents.items())), ""]
    m = folder / "delivery.yaml"
    m.write_text(MANIFEST_TEMPLATE.format(name=folder.name, tables="\n".join(lines), profile=profile or "jrc-v3",
                                          sensor=sensor, documents=docs), encoding="utf-8")
    schema = folder / "delivery.schema.json"
    schema.write_text((specs_dir() / "schema" / "delivery.schema.json").read_text(encoding="utf-8"),
                      encoding="utf-8")
    g = folder / "TEMPLATE.md"
    g.write_text("\n".join(guide), encoding="utf-8")
    return [m, schema, g, *written]
