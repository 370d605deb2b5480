"""The checker's own evidence as measures: whose check points the accuracy rests on, and whether the
checker's measurements are bound to the images delivered now (issue 29 items 1 and 4).

* ``checker.external_checkpoints`` (delivery, bool): the check point statistics rest on the checker's
  measurements (the checker folder's tables/checkpoints.csv), not on the contractor's own points.
  JRC §12.4: check points "should be provided from a different source than the contractor";
  contractor data "is not recommended". False: the checker must measure (JRC-12.4-EXTERNAL-CHECKPOINTS).
* ``checker.points_unbound`` (block, count): the checker's points whose recorded image SHA-256 is
  not that of the image delivered now (changed, swapped, gone): left out of the statistics, each
  named with why (delivery/in_force.py).
* ``checker.points_unhashed`` (block, count): the checker's points that record no image SHA-256,
  so nothing tells whether they were measured on the pixels delivered.

The block provider also cuts the report's image chips (issue 29 item 6, inspection/chips.py) for
the flagged (blunder candidates, exclusions) and hand-measured points of the checker's table, at
most :data:`CHIPS_PER_BLOCK` per block, into ``details.checker_chips``.
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from ...provenance import Evidence
from ..registry import Measured, ProviderContext, provider

MEASURES = {"checker.external_checkpoints": "bool"}
BLOCK = {"checker.points_unbound": "1", "checker.points_unhashed": "1"}
#: points named in a note before "and N more"
SHOWN = 10
#: image chips per block in the report: every flagged point first, then hand-measured ones by residual
CHIPS_PER_BLOCK = 6


def _view(ctx: ProviderContext) -> Any:
    """The evaluation's view of the delivery (delivery/in_force.py), or None outside an evaluation."""
    d = ctx.delivery
    return d if hasattr(d, "external_absent_reason") else None


@provider(scope="delivery", measures=MEASURES)
def external_checkpoints(ctx: ProviderContext) -> list[Measured]:
    """Whether the check point statistics rest on the checker's own measurements (JRC §12.4)."""
    d = ctx.delivery
    view = _view(ctx)
    t = d.table("checkpoints")
    ev: tuple[Evidence, ...] = (
        (Evidence(t.file, t.sha256),) if t is not None else (d.manifest_evidence("tables"),)
    )
    if view is None:
        value, note = None, "outside an evaluation: whose check points these are is not known"
    elif view.external:
        value = True
        note = (
            f"the checker's measurements ({t.file if t is not None else 'none'}, {len(t.df) if t is not None else 0} "
            "points bound to the delivered images); the delivery's own table is the contractor's internal QC"
        )
    else:
        value, note = False, view.external_absent_reason()
    return [
        Measured(
            "checker.external_checkpoints",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]


@provider(scope="block", measures=BLOCK)
def points_bound(ctx: ProviderContext) -> list[Measured]:
    """The checker's points per block left out (image changed since) or not bound (no image hash)."""
    d = ctx.delivery
    view = _view(ctx)
    blocks = d.block_ids
    if view is None or not view.external:
        why = (
            "the check points are the contractor's own (no checker's measurements to bind)"
            if view is not None
            else "outside an evaluation"
        )
        na = pd.Series({b: why for b in blocks}, dtype=object)
        empty = pd.Series({b: None for b in blocks}, dtype=object)
        ev = pd.Series({b: (d.manifest_evidence("blocks"),) for b in blocks}, dtype=object)
        return [Measured(name, "block", unit, empty, ev, na=na) for name, unit in BLOCK.items()]
    t = d.require_table("checkpoints")  # resolves the binding
    unbound = view.unbound_frame()
    ids = t.df.set_index(t.df["point_id"].astype(str))
    unhashed = set(view.unhashed)
    out = []
    for name in BLOCK:
        vals: dict[str, Any] = {}
        evs: dict[str, Any] = {}
        notes: dict[str, str] = {}
        for b in blocks:
            if name == "checker.points_unbound":
                mine = unbound[unbound["block"] == b]
                rows = mine["row"].tolist()
                vals[b] = float(len(mine))
                if len(mine):
                    said = [
                        f"{p} ({r})" for p, r in zip(mine["point_id"], mine["reason"], strict=True)
                    ]
                    notes[b] = (
                        f"{len(mine)} of the checker's check points of block {b} are left out, their image is "
                        "not the one measured: "
                        + "; ".join(said[:SHOWN])
                        + (f"; and {len(said) - SHOWN} more" if len(said) > SHOWN else "")
                    )
            else:
                in_block = ids[ids["block"].astype(str) == b]
                mine = [p for p in in_block.index if p in unhashed]
                rows = in_block.loc[mine, "_row"].tolist() if mine else []
                vals[b] = float(len(mine))
                if mine:
                    notes[b] = (
                        f"{len(mine)} of the checker's check points of block {b} record no image_sha256: "
                        "nothing binds them to the image content measured: "
                        + ", ".join(mine[:SHOWN])
                        + (f" and {len(mine) - SHOWN} more" if len(mine) > SHOWN else "")
                    )
            evs[b] = (Evidence(t.file, t.sha256, tuple(int(r) for r in rows)),)
        out.append(
            Measured(
                name,
                "block",
                "1",
                pd.Series(vals, dtype=object),
                pd.Series(evs, dtype=object),
                notes=pd.Series(notes, dtype=object) if notes else None,
            )
        )
    chips = _chips(ctx, t)
    if chips:
        out[0].detail = {"checker_chips": chips}
    return out


def _chips(ctx: ProviderContext, t: Any) -> dict[str, Any]:
    """Per block, the chips of its flagged and hand-measured points (delivered and reference), bounded."""
    from ...inspection.chips import read_chip
    from .checkpoints import _compute

    d, chk = ctx.delivery, ctx.checker
    res = _compute(ctx)
    df = t.df
    by_hand = (
        set(df.loc[df["decision"] == "by_hand", "point_id"].astype(str))
        if "decision" in df
        else set()
    )
    rows = df.set_index(df["point_id"].astype(str))
    images = d.table("images")
    files = (
        {}
        if images is None or "file" not in images.df
        else dict(zip(images.ids.tolist(), images.df["file"].astype(str).tolist(), strict=True))
    )
    out: dict[str, Any] = {}
    for block, detail in sorted(res.detail.items()):
        pts = detail["points"]
        flagged = pts[(pts["status"] == "fail") | (pts["decision"] != "kept")]
        hand = pts[pts["point_id"].astype(str).isin(by_hand) & ~pts.index.isin(flagged.index)]
        hand = hand.sort_values("dr", ascending=False, kind="stable")
        pick = pd.concat([flagged, hand])
        if not len(pick):
            continue
        chosen = []
        flagged_ids = set(flagged["point_id"].astype(str))
        for p in pick.head(CHIPS_PER_BLOCK).itertuples(index=False):
            pid = str(p.point_id)
            r = rows.loc[pid]
            entry: dict[str, Any] = {
                "point_id": pid,
                "x": float(r["x"]),
                "y": float(r["y"]),
                "x_ref": float(r["x_ref"]),
                "y_ref": float(r["y_ref"]),
                "flagged": pid in flagged_ids,
                "decision": None if pd.isna(r.get("decision")) else str(r.get("decision")),
                "method": None if pd.isna(r.get("method")) else str(r.get("method")),
            }
            image = None if pd.isna(r.get("image_id")) else str(r.get("image_id"))
            entry["image_id"] = image
            rel = files.get(image) if image is not None else None
            if rel is None:
                entry["delivered_note"] = "the point names no delivered image"
            else:
                got = read_chip(d.path(rel, what="image file"), entry["x"], entry["y"], name=rel)
                entry["delivered" if not isinstance(got, str) else "delivered_note"] = (
                    got if isinstance(got, str) else got.to_dict()
                )
            ref = None if pd.isna(r.get("reference_file")) else str(r.get("reference_file"))
            rp = chk.folder / ref if ref and chk is not None and chk.folder is not None else None
            # only a file of the checker folder (never one named outside it, never the delivery's)
            if (
                rp is None
                or not rp.is_file()
                or not rp.resolve().is_relative_to(chk.folder.resolve())
                or rp.resolve().is_relative_to(d.root.resolve())
            ):
                entry["reference_note"] = (
                    f"reference file {ref} is not in the checker folder"
                    if ref
                    else "the measurement names no reference file"
                )
            else:
                got = read_chip(rp, entry["x_ref"], entry["y_ref"], name=ref or rp.name)
                entry["reference" if not isinstance(got, str) else "reference_note"] = (
                    got if isinstance(got, str) else got.to_dict()
                )
            chosen.append(entry)
        out[block] = {"points": chosen, "eligible": len(pick)}
    return out
