"""The contractor's internal QC check points (JRC §12.5, §7.2), judged as such and compared with the
external result.

When the checker has measured the check points (delivery/in_force.py), the delivery's own check point
table is the contractor's internal QC: §7.2 "The same quality requirements apply for the check points
used by the contractor for internal QC (see 12.5)". Its statistics are computed here with the same
code as the external ones (providers/checkpoints.py, table ``internal_checkpoints``) and compared
with the checker's, block by block: a finding when the contractor's own points and the independent
ones disagree on whether the block meets the tolerance (§12.8: the contractor is then expected "to
provide adequate and clear internal Quality Audits"). None of these measures reads anything the
external-accuracy rules read, so the contractor's table cannot change an external verdict.

Without the checker's measurements the statistics in force already are the contractor's own: these
measures are then not applicable (nothing independent to compare with).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ...units import convert
from ..registry import Measured, ProviderContext, provider
from .checkpoints import Results, _compute

INTERNAL = "internal_checkpoints"
MEASURES = {
    "internal_qc.n": "1",
    "internal_qc.rmse_x": "m",
    "internal_qc.rmse_y": "m",
    "internal_qc.rmse_z": "m",
    "internal_qc.agrees": "bool",
    "internal_qc.imprecise": "1",
}


def _tolerance(ctx: ProviderContext) -> float | None:
    v = ctx.parameters.get("tolerance_xy")
    if v is None:
        return None
    return float(v.to("m").magnitude) if hasattr(v, "to") else float(v)


def _stat(res: Results, block: str, name: str) -> float | None:
    r = res.blocks.get(block)
    if r is None or r.error is not None or r.blunders is None:
        return None
    v = getattr(r.stats, name)
    return None if v is None or not np.isfinite(v) else float(v)


@provider(scope="block", measures=MEASURES)
def internal_qc(ctx: ProviderContext) -> list[Measured]:
    """The contractor's internal-QC check point statistics per block, and whether they agree with the external."""
    d = ctx.delivery
    blocks = d.block_ids
    t = d.table(INTERNAL)
    if t is None:
        why = d.table_absent_reason(INTERNAL)
        empty = pd.Series({b: None for b in blocks}, dtype=object)
        ev = pd.Series({b: (d.manifest_evidence("tables"),) for b in blocks}, dtype=object)
        return [
            Measured(
                name, "block", unit, empty, ev, na=pd.Series({b: why for b in blocks}, dtype=object)
            )
            for name, unit in MEASURES.items()
        ]
    mine, theirs = _compute(ctx, INTERNAL), _compute(ctx, "checkpoints")
    tol = _tolerance(ctx)
    out = []
    for name, unit in MEASURES.items():
        vals: dict[str, Any] = {}
        evs: dict[str, Any] = {}
        notes: dict[str, str] = {}
        for b in blocks:
            r = mine.blocks.get(b)
            ext = theirs.blocks.get(b)
            evs[b] = (r.evidence if r is not None else ()) + (
                ext.evidence if ext is not None else ()
            )
            if r is None:
                vals[b] = None
                notes[b] = (
                    f"the contractor's internal QC table ({t.file}) has no check points for block {b}"
                )
                continue
            if r.error is not None:
                vals[b], notes[b] = None, r.error
                continue
            if name == "internal_qc.agrees":
                vals[b], notes[b] = _agrees(b, mine, theirs, tol)
            elif name == "internal_qc.imprecise":
                vals[b], imprecise = _imprecise(t, b, tol)
                if imprecise:
                    notes[b] = imprecise
            else:
                stat = name.split(".", 1)[1]
                vals[b] = _stat(mine, b, stat)
                if vals[b] is None:
                    notes[b] = f"block {b}: the contractor's internal QC points give no {stat}"
        out.append(
            Measured(
                name,
                "block",
                unit,
                pd.Series(vals, dtype=object),
                pd.Series(evs, dtype=object),
                notes=pd.Series(notes, dtype=object) if notes else None,
            )
        )
    return out


def _imprecise(t: Any, block: str, tol: float | None) -> tuple[float | None, str | None]:
    """Points of ``block`` whose documented reference accuracy is blank or worse than a third of the
    tolerance (JRC Definitions "Check Point"; §7.2: the same requirements for the contractor's points)."""
    if tol is None:
        return None, "tolerance_xy is not set: no limit for the reference accuracy"
    df = t.df[t.df["block"].astype(str) == block]
    to_m = float(convert([1.0], t.units.get("precision_xy", "m"), "m")[0])
    prec = (
        df["precision_xy"].to_numpy(float) * to_m
        if "precision_xy" in df
        else np.full(len(df), np.nan)
    )
    bad = ~(prec <= tol / 3.0)
    ids = df["point_id"].astype(str).to_numpy()[bad].tolist()
    if not ids:
        return 0.0, None
    return float(len(ids)), (
        f"{len(ids)} of the contractor's {len(df)} internal-QC check points of block {block} "
        f"document a reference accuracy that is blank or worse than tolerance_xy / 3 "
        f"({tol / 3:.3g} m): " + ", ".join(ids[:10]) + (" ..." if len(ids) > 10 else "")
    )


def _agrees(
    block: str, mine: Results, theirs: Results, tol: float | None
) -> tuple[bool | None, str]:
    """(the two tables reach the same pass/fail for RMSEx and RMSEy against the tolerance, the note)."""
    ix, iy = _stat(mine, block, "rmse_x"), _stat(mine, block, "rmse_y")
    ex, ey = _stat(theirs, block, "rmse_x"), _stat(theirs, block, "rmse_y")
    if ex is None or ey is None:
        return None, f"block {block}: no external RMSE to compare the contractor's internal QC with"
    if ix is None or iy is None:
        return None, f"block {block}: the contractor's internal QC points give no RMSE"
    if tol is None:
        return None, "tolerance_xy is not set: nothing to compare the two results against"
    said = (
        f"internal QC (contractor) RMSEx {ix:.3f} m, RMSEy {iy:.3f} m vs external (checker) RMSEx {ex:.3f} m, "
        f"RMSEy {ey:.3f} m; tolerance {tol:g} m"
    )
    inside = [v <= tol for v in (ix, iy, ex, ey)]
    same = inside[0] == inside[2] and inside[1] == inside[3]
    if same:
        return True, f"{said}: both {'pass' if all(inside) else 'fail'} the block"
    word = "passes" if inside[0] and inside[1] else "fails"
    other = "passes" if inside[2] and inside[3] else "fails"
    return (
        False,
        f"{said}: the contractor's internal QC {word} the block, the external check {other} it",
    )
