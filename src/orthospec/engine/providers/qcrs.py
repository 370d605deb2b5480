"""The essential (minimum) set of QCRs, JRC §2.4 ("These guidelines identify the essential (minimum) set
of QCRs required for QA of orthorectification"): Table 6 for air-photo orthocorrection, Table 10 for
satellite image rectification, each row looked up in what the delivery carries.

* ``qcr.minimum_set_missing`` (delivery): QCRs of the sensor's table with no record in the delivery,
  named in the note with what was looked for.

Each row's record is the delivery convention's table or column that holds it ("100%" production
level: filled for every row; "Sample": at least one), or the document the manifest lists. Rows
whose "Contractor Production Level" is "-" (CV/training certificates, software) are no QCR of the
delivery and are not looked for; the scanner control chart applies to film only, the DEM comparison
"(if available...)" when a DEM table is delivered, the master-image accuracy when a scene is a master.
Inspection results (Table 6 rows 8 and 13, Table 10 row 9) are records of the internal QC:
``documents.internal_qcr``.
"""

from __future__ import annotations

from dataclasses import dataclass

import pandas as pd

from ...errors import OrthospecError
from ...provenance import Evidence
from ..registry import Measured, ProviderContext, provider

NAME = "qcr.minimum_set_missing"


@dataclass(frozen=True)
class Qcr:
    table: int
    row: str
    name: str
    #: records, each "table", "table.column" (every row filled), "table.column?" (at least one row)
    #: or "documents.<key>"
    needs: tuple[str, ...]
    when: str = ""  # "", "film", "dem", "master"


AERIAL = (
    Qcr(6, "1", "Camera calibration certificate", ("cameras.certificate",)),
    Qcr(
        6,
        "2",
        "Flight data including log of photo centres and flying height",
        ("flights", "images.exposure_x", "images.exposure_y", "images.flying_height"),
    ),
    Qcr(
        6, "3", "Control chart for the scanner performance (geometric)", ("scanner_tests",), "film"
    ),
    Qcr(6, "5", "Table of ground reference data for GCPs and check points", ("gcps",)),
    Qcr(6, "6", "Interior and exterior orientation results", ("aerotriangulation",)),
    Qcr(
        6,
        "6",
        "Interior orientation results of the scanned images",
        ("interior_orientation",),
        "film",
    ),
    Qcr(
        6,
        "7",
        "Number of items rejected/reprocessed at each stage of internal QC",
        ("documents.rejected_items",),
    ),
    Qcr(6, "8", "Visualisation of the DEMs", ("documents.internal_qcr",)),
    Qcr(6, "9", "Comparison of DEMs with vertical checkpoints", ("dem.rmse_z?",), "dem"),
    Qcr(
        6,
        "10",
        "Residuals of block adjustment on control and check points",
        ("aerotriangulation.gcp_rmse_x", "aerotriangulation.gcp_rmse_y"),
    ),
    Qcr(
        6,
        "11",
        "RMSE of finalised block adjustments using contractors' check points",
        ("aerotriangulation.checkpoint_rmse_x", "aerotriangulation.checkpoint_rmse_y"),
    ),
    Qcr(6, "12", "Ortho-image metadata", ("images",)),
    Qcr(6, "13", "Ortho-images (inspection result)", ("documents.internal_qcr",)),
)
SATELLITE = (
    Qcr(10, "1", "Image Check (esp. view angle record)", ("scenes.view_angle",)),
    Qcr(
        10,
        "2",
        "DEM (esp. anomalies and height accuracy)",
        ("scenes.dem_accuracy", "scenes.dem_qc_result"),
    ),
    Qcr(10, "3", "Ground reference data", ("gcps",)),
    Qcr(
        10, "6", "File of GCPs, check points and residuals", ("gcps.residual_x", "gcps.residual_y")
    ),
    Qcr(10, "7", "Adjustment/warp results", ("scenes.residual_rmse",)),
    Qcr(10, "8", "Resampling", ("scenes.resampling_method",)),
    Qcr(10, "9", "Visual accuracy check", ("documents.internal_qcr",)),
    Qcr(
        10,
        "10",
        "Accuracy of the master image",
        ("scenes.checkpoint_rmse?", "scenes.master_check_date?"),
        "master",
    ),
    Qcr(10, "11", "Image metadata", ("scenes",)),
)


def _document(ctx: ProviderContext, key: str) -> tuple[bool, tuple[Evidence, ...]]:
    d = ctx.delivery
    rel = d.manifest.documents.get(key)
    if not rel:
        return False, ()
    try:
        p = d.path(rel, what=f"documents.{key}")
        ok = p.is_file() and p.stat().st_size > 0
    except (OrthospecError, OSError):
        return False, ()
    return ok, ((d.evidence(rel),) if ok else ())


def _record(ctx: ProviderContext, need: str) -> tuple[str | None, tuple[Evidence, ...]]:
    """(why the record is absent or None when present, evidence)."""
    d = ctx.delivery
    if need.startswith("documents."):
        ok, ev = _document(ctx, need.split(".", 1)[1])
        return (None if ok else f"{need} not delivered"), ev
    any_row = need.endswith("?")
    table, _, col = need.rstrip("?").partition(".")
    t = d.table(table)
    if t is None or not len(t.df):
        return f"no {table} table", (d.manifest_evidence("tables"),)
    ev = (t.evidence(t.df["_row"])[0],)
    if not col:
        return None, ev
    if col not in t.df:
        return f"{t.file} has no {col} column", ev
    filled = t.df[col].notna()
    if (any_row and filled.any()) or filled.all():
        return None, ev
    blank = t.df.loc[~filled, "_row"].tolist()
    return (
        f"{t.file} {col} empty in every row"
        if any_row
        else f"{t.file} {col} empty in {len(blank)} row(s) (first: row {blank[0]})"
    ), ev


def _applies(ctx: ProviderContext, when: str) -> bool:
    d = ctx.delivery
    if when == "film":
        return d.manifest.sensor.digital is False
    if when == "dem":
        return d.table("dem") is not None
    if when == "master":
        s = d.table("scenes")
        return (
            s is not None
            and "is_master" in s.df
            and bool(s.df["is_master"].map(lambda v: v is True).any())
        )
    return True


@provider(scope="delivery", measures={NAME: "1"})
def minimum_set(ctx: ProviderContext) -> list[Measured]:
    """QCRs of JRC Table 6 (aerial) or Table 10 (satellite) with no record in the delivery."""
    d = ctx.delivery
    qcrs = SATELLITE if d.manifest.sensor.type == "satellite" else AERIAL
    missing: list[str] = []
    evidence: list[Evidence] = [d.manifest_evidence("tables"), d.manifest_evidence("documents")]
    looked = 0
    for q in qcrs:
        if not _applies(ctx, q.when):
            continue
        looked += 1
        whys = []
        for need in q.needs:
            why, ev = _record(ctx, need)
            evidence += [e for e in ev if e not in evidence]
            if why:
                whys.append(why)
        if whys:
            missing.append(f"Table {q.table} row {q.row} ({q.name}): {'; '.join(whys)}")
    table = qcrs[0].table
    note = (
        f"every one of the {looked} QCRs of Table {table} that apply has its record"
        if not missing
        else f"{len(missing)} of the {looked} QCRs of Table {table} have no record: "
        + " | ".join(missing)
    )
    return [
        Measured(
            NAME,
            "delivery",
            "1",
            pd.Series({d.id: float(len(missing))}, dtype=object),
            pd.Series({d.id: tuple(evidence)}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]
