"""Whether a declared outline (a block polygon, an area of interest) is the one in force (JRC §12.4
"block/site", §5.2.2). Pure: shapely geometries in, a verdict out; no I/O.

Used by ``derived.block_outlines_agree`` and ``derived.area_of_interest_agrees``
(engine/providers/outlines.py; red team R13/R17).
"""

from __future__ import annotations

import math
from typing import Any

#: A declared outline agrees with the one in force when the area between them (symmetric difference)
#: is at most this share of the in-force outline's area, and no point of one lies farther from the
#: other (Hausdorff distance) than this share of the square root of that area. Both relative, so the
#: test reads the same in any map unit; 1 % admits rounded coordinates, a ring started at another
#: vertex or densified, not a redrawn boundary (a corridor reaching 1 % of a 6 x 7 km block's size,
#: 65 m, into its neighbour already fails the distance test whatever its area).
OUTLINE_TOLERANCE = 0.01


def disagreement(declared: Any, in_force: Any) -> str | None:
    """None when ``declared`` agrees with ``in_force`` within ``OUTLINE_TOLERANCE``, else how far
    apart."""
    area = float(in_force.area)
    sym = float(declared.symmetric_difference(in_force).area)
    far = float(declared.hausdorff_distance(in_force))
    limit = OUTLINE_TOLERANCE * math.sqrt(area)
    if sym <= OUTLINE_TOLERANCE * area and far <= limit:
        return None
    return (
        f"differs by {sym / area * 100:.3g} % of the area in force (symmetric difference; at most "
        f"{OUTLINE_TOLERANCE * 100:g} %) and by up to {far:.6g} map units (Hausdorff distance; at "
        f"most {limit:.6g})"
    )
