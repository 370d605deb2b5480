"""Whether the manifest's block outlines and area of interest are the ones in force.

* ``derived.block_outlines_agree`` and ``derived.area_of_interest_agrees`` (delivery): when the
  checker's file states block outlines / an area of interest (delivery/checker.py), those are in
  force (``Delivery.block_outlines``: the check points' blocks, the DEM's blocks, the area the
  photos must cover) and the manifest's are declarations compared with them (red team R13: B02's
  outline shrunk to hide a coverage hole; R17: B01's redrawn over B02's worst points). A declared
  outline agrees within ``OUTLINE_TOLERANCE`` (measures/outlines.py); a block only one side lists is
  a disagreement. Not applicable when the checker's file states none (the manifest's are then in
  force).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import pandas as pd

from ...delivery.outlines import finite_ring
from ...errors import OrthospecError
from ...measures.outlines import OUTLINE_TOLERANCE
from ...measures.outlines import disagreement as _disagreement
from ..registry import Measured, ProviderContext, provider

__all__ = ["OUTLINE_TOLERANCE", "area_of_interest_agrees", "block_outlines_agree"]

OUTLINES_AGREE = {"derived.block_outlines_agree": "bool"}
AOI_AGREE = {"derived.area_of_interest_agrees": "bool"}


@provider(scope="delivery", measures=OUTLINES_AGREE)
def block_outlines_agree(ctx: ProviderContext) -> list[Measured]:
    """The manifest's block outlines are the ones the checker's file puts in force (JRC §12.4 "block/site")."""
    from ...delivery.outlines import ring_polygon

    d = ctx.delivery
    stated = ctx.outlines
    ev: tuple[Any, ...] = (d.manifest_evidence("blocks"),)
    na = None
    value: bool | None
    if stated is None or not stated.blocks:
        value, note = (
            None,
            "the checker's file states no block outlines: the manifest's are in force",
        )
        na = pd.Series({d.id: note}, dtype=object)
    else:
        ev += tuple(e for _, e in stated.blocks.values())
        declared = {b.id: (i, b.polygon) for i, b in enumerate(d.manifest.blocks)}
        problems = []
        for block in sorted(set(declared) | set(stated.blocks)):
            if block not in declared:
                problems.append(
                    f"block {block}: the {stated.source} gives its outline, delivery.yaml lists no "
                    "such block"
                )
            elif block not in stated.blocks:
                problems.append(
                    f"block {block} (delivery.yaml blocks[{declared[block][0]}]): the "
                    f"{stated.source} "
                    "gives no outline for it, so none of its check points lies in a block in force"
                )
            elif not finite_ring(declared[block][1]):
                problems.append(
                    f"block {block}: delivery.yaml blocks[{declared[block][0]}] declares no valid "
                    "polygon"
                )
            else:
                ring = cast(
                    "Sequence[Sequence[float]]", declared[block][1]
                )  # finite_ring: not None
                why = _disagreement(ring_polygon(ring), ring_polygon(stated.blocks[block][0]))
                if why:
                    problems.append(
                        f"block {block}: delivery.yaml blocks[{declared[block][0]}].polygon {why}"
                    )
        value = not problems
        note = (
            "; ".join(problems[:5])
            + (f"; and {len(problems) - 5} more" if len(problems) > 5 else "")
            if problems
            else f"the {len(stated.blocks)} block outline(s) of delivery.yaml agree with the "
            f"{stated.source} (within {OUTLINE_TOLERANCE * 100:g} %)"
        )
    return [
        Measured(
            "derived.block_outlines_agree",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=na,
        )
    ]


@provider(scope="delivery", measures=AOI_AGREE)
def area_of_interest_agrees(ctx: ProviderContext) -> list[Measured]:
    """The manifest's area of interest is the one the checker's file puts in force (JRC §5.2.2).

    Declared: project.area_of_interest, else the union of the manifest's block polygons; in force:
    the checker's area_of_interest, else the union of its block outlines (``mosaic.aoi_in_force``).
    Not applicable when the checker states neither, or when it states an area and the manifest
    declares no area file (the union of blocks is then no statement about the area)."""
    d = ctx.delivery
    stated = ctx.outlines
    rel = d.manifest.project.area_of_interest
    ev: tuple[Any, ...] = (d.manifest_evidence("project.area_of_interest"),)
    na: str | None = None
    value: bool | None = None
    if stated is None:
        note = na = (
            "the checker's file states no area of interest or block outlines: the manifest's are "
            "in force"
        )
    elif stated.area_of_interest is not None and not rel:
        note = na = (
            f"delivery.yaml declares no project.area_of_interest; the {stated.source}'s is in "
            "force "
            "and nothing is declared to compare with it"
        )
    else:
        from .mosaic import aoi_in_force, declared_aoi

        try:
            in_force, in_force_ev, in_force_what = aoi_in_force(ctx)
            declared, declared_ev, declared_what = declared_aoi(ctx)
        except (OrthospecError, OSError) as exc:
            note = f"cannot form the declared area of interest: {exc}"
        else:
            ev = (*declared_ev, *in_force_ev)
            if declared is None:
                note = na = "delivery.yaml declares no area of interest and no block polygon"
            else:
                why = _disagreement(declared, in_force)
                value = why is None
                note = (
                    f"the {declared_what} (delivery.yaml) is not the {in_force_what}: it {why}"
                    if why
                    else f"the {declared_what} (delivery.yaml) agrees with the {in_force_what} "
                    f"(within {OUTLINE_TOLERANCE * 100:g} %)"
                )
    return [
        Measured(
            "derived.area_of_interest_agrees",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=None if na is None else pd.Series({d.id: na}, dtype=object),
        )
    ]
