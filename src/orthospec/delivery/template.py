"""`orthospec init DIR`: a commented delivery template that validates as written."""

from __future__ import annotations

from pathlib import Path

from ..errors import DeliveryError
from .convention import table_specs

MANIFEST_TEMPLATE = """\
# yaml-language-server: $schema=https://orthospec.dev/schema/delivery.schema.json
# orthospec delivery manifest. Every path is relative to this folder. Fill in, then run:
#   orthospec check {name} --profile jrc-v3
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
  type: aerial                      # aerial | satellite
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
units: {{checkpoints: m, gcps: m}}    # length unit of coordinate columns: m, ft or usft
waivers: []                         # - {{rule: RULE-ID, items: [ITEM], justification: ..., approver: ...}}
"""


def write_template(folder: Path) -> list[Path]:
    folder = Path(folder)
    if (folder / "delivery.yaml").exists():
        raise DeliveryError(f"{folder / 'delivery.yaml'} already exists; refusing to overwrite it")
    (folder / "tables").mkdir(parents=True, exist_ok=True)
    (folder / "images").mkdir(exist_ok=True)
    written = []
    lines = []
    for name, spec in table_specs().items():
        rel = f"tables/{name}.csv"
        lines.append(f"  {name}: {rel}")
        p = folder / rel
        if not p.exists():
            p.write_text(",".join(spec.required or list(spec.columns)[:1]) + "\n", encoding="utf-8")
            written.append(p)
    m = folder / "delivery.yaml"
    m.write_text(MANIFEST_TEMPLATE.format(name=folder.name, tables="\n".join(lines)), encoding="utf-8")
    return [m, *written]
