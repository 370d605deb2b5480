"""The checker's inspection grid as measures (issue 29 item 3; inspection/grid.py).

* ``inspection.present`` (delivery, bool): the checker folder holds a marked inspection grid.
* ``inspection.inspected_share`` (delivery, %): share of the gridded (sampled) area whose cells the
  checker inspected; the cells of an image changed since the grid was written count as not inspected.
  JRC Table 6 QCR 13 "Ortho-images (inspection result)" and §12.3 ("at least a sample ... of the images
  delivered"): the sample the checker drew is inspected in full, or the check is not complete.

The per-image verdicts the grid gives the manual rules it answers are in engine/manual.py.
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from ...provenance import Evidence
from ..registry import Measured, ProviderContext, provider

MEASURES = {"inspection.present": "bool", "inspection.inspected_share": "%"}
#: marked cells kept for the report's block maps at most (qcr.json stays bounded; the grid holds them all)
MAX_CELLS = 2000


def _marked(ctx: ProviderContext, grid: Any) -> dict[str, Any]:
    """The grid's marked cells for the report (block maps): id, image, block, classes, comment, bounds."""
    t = ctx.delivery.table("images")
    block = (
        {}
        if t is None or "block" not in t.df
        else dict(zip(t.ids.tolist(), t.df["block"].astype(str).tolist(), strict=True))
    )
    marked = grid.defect_cells()
    cells = []
    for r in marked.head(MAX_CELLS).itertuples(index=False):
        cells.append(
            {
                "cell_id": r.cell_id,
                "image_id": r.image_id,
                "block": block.get(r.image_id),
                "defects": [c for c in grid.codes if getattr(r, c)],
                "comment": r.comment if isinstance(r.comment, str) else None,
                "bounds": list(r.bounds) if r.bounds is not None else None,
            }
        )
    return {"file": grid.path.name, "sha256": grid.sha256, "marked": len(marked), "cells": cells}


@provider(scope="delivery", measures=MEASURES)
def inspection(ctx: ProviderContext) -> list[Measured]:
    """Whether the checker marked an inspection grid, and the share of its area inspected."""
    d = ctx.delivery
    grid = ctx.inspection
    if grid is None:
        ev = (d.manifest_evidence("id"),)
        why = "the checker folder holds no inspection grid (inspection.gpkg; orthospec inspect grid writes one)"
        return [
            Measured(
                "inspection.present",
                "delivery",
                "bool",
                pd.Series({d.id: False}, dtype=object),
                pd.Series({d.id: ev}, dtype=object),
                notes=pd.Series({d.id: why}, dtype=object),
            ),
            Measured(
                "inspection.inspected_share",
                "delivery",
                "%",
                pd.Series({d.id: None}, dtype=object),
                pd.Series({d.id: ev}, dtype=object),
                na=pd.Series({d.id: why}, dtype=object),
            ),
        ]
    ev = (Evidence(f"checker:{grid.path.name}", grid.sha256),)
    share, note = grid.inspected_share()
    return [
        Measured(
            "inspection.present",
            "delivery",
            "bool",
            pd.Series({d.id: True}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            detail={"inspection": _marked(ctx, grid)},
        ),
        Measured(
            "inspection.inspected_share",
            "delivery",
            "%",
            pd.Series({d.id: share}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        ),
    ]
