"""Mosaic area selection (JRC Table 11 "The most nadir chips of the images should be used for mosaicking
to reduce distortion effects (smear)"; quality check "Check the seamlines against the image nadir
points and footprints"), automating JRC-T11-AREA-SELECTION.

* ``seamline.area_selection_faults`` (delivery): seamline polygons (``vectors.seamlines``, each naming
  its image in an ``image_id`` attribute) that reach more than ``OUTSIDE_SHARE`` of their area outside
  their image's footprint (read from the raster), or whose inner point is farther from their image's
  nadir point (``images.exposure_x/_y``) than from the nadir of another image covering that point by
  more than ``NADIR_SLACK`` (a chip taken from a less nadir image). Images without a nadir point are
  judged on their footprint only. Missing when the layer names no image.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from shapely.geometry import box

from ...errors import OrthospecError
from ...provenance import Evidence
from ...raster.footprints import read_seamlines
from ..registry import Measured, ProviderContext, provider
from .satellite import footprints

NAME = "seamline.area_selection_faults"
#: a seamline polygon may stick out of its image's footprint by this share of its area (edge rounding)
OUTSIDE_SHARE = 0.01
#: another image's nadir must be this much nearer (relative) to count as "more nadir"
NADIR_SLACK = 0.05


def faults(
    polys: list[tuple[Any, str | None]], feet: dict[str, Any], nadir: dict[str, tuple[float, float]]
) -> list[str]:
    """What is wrong with each seamline polygon, as text (empty when all agree)."""
    out = []
    for k, (g, img) in enumerate(polys, start=1):
        label = f"polygon {k} ({img})" if img else f"polygon {k}"
        if img is None:
            out.append(f"{label} names no image")
            continue
        b = feet.get(img, (None, "not in the images table"))[0]
        if b is None:
            out.append(
                f"{label}: its image has no footprint ({feet.get(img, (None, 'not listed'))[1]})"
            )
            continue
        outside = g.area - g.intersection(box(*b)).area
        if g.area > 0 and outside > OUTSIDE_SHARE * g.area:
            out.append(
                f"{label}: {100 * outside / g.area:.1f} % of it outside its image's footprint"
            )
            continue
        if img not in nadir:
            continue
        p = g.representative_point()
        own = float(np.hypot(p.x - nadir[img][0], p.y - nadir[img][1]))
        covering = [
            (i, float(np.hypot(p.x - xy[0], p.y - xy[1])))
            for i, xy in nadir.items()
            if i != img and feet.get(i, (None,))[0] is not None and box(*feet[i][0]).contains(p)
        ]
        better = [(i, dist) for i, dist in covering if dist < own * (1 - NADIR_SLACK)]
        if better:
            i, dist = min(better, key=lambda t: t[1])
            out.append(
                f"{label}: {own:.0f} from its nadir point, {dist:.0f} from {i}'s, which also covers it"
            )
    return out


@provider(scope="delivery", measures={NAME: "1"})
def area_selection(ctx: ProviderContext) -> list[Measured]:
    """Seamline polygons outside their image's footprint or not taken from the most nadir image."""
    d = ctx.delivery
    seam = d.manifest.vectors.get("seamlines")
    ev: tuple[Evidence, ...] = (d.manifest_evidence("vectors.seamlines"),)
    value: Any = None
    errors = None
    if not seam:
        note = "the manifest gives no vectors.seamlines file"
    else:
        try:
            polys, field = read_seamlines(d.path(seam, what="vectors.seamlines"), name=seam)
            ev += (d.evidence(seam),)
        except (OrthospecError, OSError) as exc:
            polys, field = [], None
            errors = pd.Series({d.id: f"{seam}: cannot read seamlines: {exc}"}, dtype=object)
        if field is None:
            note = f"{seam} gives no image attribute (image_id) for its polygons"
        else:
            feet = footprints(ctx)
            imgs = d.table("images")
            nadir: dict[str, tuple[float, float]] = {}
            if imgs is not None and {"exposure_x", "exposure_y"} <= set(imgs.df):
                for i, x, y in zip(
                    imgs.ids.astype(str),
                    imgs.df["exposure_x"].tolist(),
                    imgs.df["exposure_y"].tolist(),
                    strict=True,
                ):
                    if x is not None and y is not None and np.isfinite(x) and np.isfinite(y):
                        nadir[i] = (float(x), float(y))
                ev += (imgs.evidence(imgs.df["_row"])[0],)
            found = faults(polys, feet, nadir)
            value = float(len(found))
            note = f"{len(polys)} seamline polygon(s) of {seam} ({field}): " + (
                "each within its image's footprint and nearest its nadir point"
                if not found
                else "; ".join(found[:10])
                + (f" and {len(found) - 10} more" if len(found) > 10 else "")
            )
    return [
        Measured(
            NAME,
            "delivery",
            "1",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            errors=errors,
        )
    ]
