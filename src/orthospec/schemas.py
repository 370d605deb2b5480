"""Write the published JSON Schemas and the measure catalog: ``python -m orthospec.schemas``.

Rewrites ``specs/schema/``: profile.schema.json (profile/models.py), delivery.schema.json
(delivery/manifest.py), qcr.schema.json (qcr_model.py), checker.schema.json (delivery/checker.py), the
checker folder's table and grid (checker-checkpoints.schema.json: delivery/checker_tables.py,
checker-inspection.schema.json: inspection/grid.py) and measures.json (engine/catalog.py, the
snapshot profile/catalog.py reads). Tests fail when a shipped
file differs from what this writes.
It sits at the api level because it reads every layer below.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from .delivery.checker import checker_schema
from .delivery.checker_tables import checkpoints_schema
from .delivery.manifest import manifest_schema
from .engine import catalog as engine_catalog
from .inspection.grid import cells_schema
from .profile import catalog as spec_catalog
from .profile.schema import dumps, profile_schema
from .qcr import qcr_schema


def all_schemas() -> dict[str, dict[str, Any]]:
    return {
        "profile.schema.json": profile_schema(),
        "delivery.schema.json": manifest_schema(),
        "qcr.schema.json": qcr_schema(),
        "checker.schema.json": checker_schema(),
        "checker-checkpoints.schema.json": checkpoints_schema(),
        "checker-inspection.schema.json": cells_schema(),
    }


def write(folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, schema in all_schemas().items():
        p = folder / name
        p.write_text(dumps(schema), encoding="utf-8")
        out.append(p)
    p = folder / spec_catalog.CATALOG_NAME
    p.write_text(spec_catalog.dumps(engine_catalog.snapshot()), encoding="utf-8")
    out.append(p)
    return out


def main(argv: list[str]) -> None:
    target = Path(argv[0]) if argv else Path("specs/schema")
    for p in write(target):
        print(p)


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
