"""Block outlines and the area of interest: which are in force, and the one validity test.

Blocks are the units of acceptance (JRC §12.4 "block/site", §12.7, §12.8) and a check point counts
for the block whose outline contains it; the area of interest is what the photo lay-down must cover
(§5.2.2). Outlines drawn by the contractor (delivery.yaml) are declarations; when the checker's
file states outlines (delivery/checker.py), those are in force and the manifest's are only
compared with them (red team R13/R17: a redrawn outline hid a coverage hole or took another
block's worst points). :class:`StatedOutlines` is what the checker's file attaches to the
delivery; ``Delivery.block_outlines()`` answers from it, else from the manifest.

shapely is imported inside the functions, so reading a delivery without outlines stays light.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..provenance import Evidence

if TYPE_CHECKING:
    from shapely.geometry import Polygon

Ring = tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class StatedOutlines:
    """Outlines the checker's file states: block id -> (ring, evidence); the area of interest."""

    #: the checker's file by name, for messages ("checker file qc.yaml")
    source: str
    blocks: dict[str, tuple[Ring, Evidence]] = field(default_factory=dict)
    area_of_interest: tuple[Ring, Evidence] | None = None


def finite_ring(coords: Sequence[Sequence[float]] | None) -> bool:
    """At least three vertices, every coordinate a finite number: a ring a polygon can be made of
    (a non-finite vertex leaves its block unchecked, reported where the outline is used)."""
    import math

    return (
        coords is not None
        and len(coords) >= 3
        and all(math.isfinite(float(v)) for xy in coords for v in xy)
    )


def ring_polygon(coords: Sequence[Sequence[float]]) -> Polygon:
    """A shapely polygon of one ring of ``[x, y]`` vertices (closed or not)."""
    from shapely.geometry import Polygon

    return Polygon([(float(x), float(y)) for x, y in coords])


def invalid_reason(poly: Polygon) -> str | None:
    """Why ``poly`` is no outline (self-intersection, no area), or None: a block outline is a simple
    ring whose edges do not cross, so that "inside" is defined."""
    if not poly.is_valid:
        from shapely.validation import explain_validity

        return str(explain_validity(poly))
    if poly.area <= 0:
        return "it encloses no area"
    return None


def first_overlap(polys: Sequence[Any]) -> tuple[int, int, float] | None:
    """``(first, second, area)`` of the first pair (by the second's index) of outlines that share
    area, or None. Touching edges share no area and are fine."""
    if len(polys) < 2:
        return None
    from shapely import STRtree

    left, right = STRtree(list(polys)).query(list(polys), predicate="intersects")
    pairs = sorted(
        (int(b), int(a))
        for a, b in zip(left.tolist(), right.tolist(), strict=True)
        if a < b and polys[a].intersection(polys[b]).area > 0
    )
    if not pairs:
        return None
    second, first = pairs[0]
    return first, second, float(polys[first].intersection(polys[second]).area)
