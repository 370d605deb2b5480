"""Whether the delivery's coordinates are written in the map projection in force (JRC §12.4 Table
12).

* ``derived.project_crs_agrees`` (delivery): the manifest's ``project.crs`` (the CRS its coordinates
  and block outlines are written in) names the map projection in force, the ITT parameter
  ``map_crs`` (JRC §12.4 Table 12; red team R16: the contractor relabelled every image and
  project.crs alike). Absent or unreadable is False, never "not applicable".
"""

from __future__ import annotations

import pandas as pd

from ..registry import Measured, ProviderContext, provider

PROJECT_CRS = {"derived.project_crs_agrees": "bool"}


@provider(scope="delivery", measures=PROJECT_CRS)
def project_crs_agrees(ctx: ProviderContext) -> list[Measured]:
    """The manifest's project.crs is the map projection in force (parameter map_crs, JRC Table 12)."""
    from ...delivery.crs import CrsProblem, same_crs

    d = ctx.delivery
    in_force = ctx.parameters.get("map_crs")
    declared = d.manifest.project.crs
    ev = (d.manifest_evidence("project.crs"),)
    na = None
    value: bool | None
    if in_force is None:
        value, note = (
            None,
            "no map projection in force (the profile's parameter map_crs has no value)",
        )
        na = pd.Series({d.id: note}, dtype=object)
    elif not declared:
        value, note = (
            False,
            (
                f"delivery.yaml states no project.crs: the CRS of its coordinates and block "
                f"outlines is not stated; the map projection in force is {in_force}"
            ),
        )
    else:
        try:
            value = same_crs(declared, in_force)
        except CrsProblem as exc:
            value, note = False, f"delivery.yaml project.crs: {exc}"
        else:
            note = (
                f"delivery.yaml project.crs {declared} is the map projection in force {in_force}"
                if value
                else f"delivery.yaml project.crs is {declared}, the map projection in force is "
                f"{in_force}: the "
                "delivery's coordinates and block outlines are not in the ITT's projection"
            )
    return [
        Measured(
            "derived.project_crs_agrees",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=na,
        )
    ]
