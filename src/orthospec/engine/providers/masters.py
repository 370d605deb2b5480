"""Which scenes are master images (JRC Table 9 "identify as master image", §9.4), computed from the
scenes' records and the checker's knowledge rather than trusting the ``is_master`` flag alone.

* ``derived.master_images`` (delivery): number of scenes declared master image
  (``scenes.is_master``), so that un-declaring a master that the scenes still record (its check
  date, or another scene's ``master_image_id``) cannot switch the Table 9 master-image rules off
  unseen (red team R8); not applicable when no scene shows a master-image workflow (§9.4).
* ``derived.is_master`` (image) and ``derived.master_images_agree`` (delivery): which scenes are
  master images is the checker's knowledge (parameter ``master_images``, scene ids); when stated,
  the Table 9 master-image rules judge those scenes whatever ``scenes.is_master`` says, and the
  flags are compared with it (red team R8: a master un-flagged with every trace erased escaped
  them). Without the parameter ``derived.is_master`` is the contractor's ``scenes.is_master``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ..registry import Measured, ProviderContext, RowEvidence, provider
from .cells import filled as _filled

MASTER = {"derived.master_images": "1"}
MASTER_FLAG = {"derived.is_master": "bool"}
MASTER_AGREE = {"derived.master_images_agree": "bool"}
#: scenes columns that show a master-image workflow (JRC Table 9 "Accuracy of the master image")
MASTER_EVIDENCE = ("master_image_id", "master_pixel_size", "master_check_date")


def _flagged_master(t: Any) -> pd.Series:
    """Per scenes row: the contractor flags it ``is_master`` (true or 1)."""
    if "is_master" not in t.df:
        return pd.Series(False, index=t.df.index)
    return t.df["is_master"].map(
        lambda v: v is True or (isinstance(v, (int, float, np.bool_)) and v == 1)
    )


def named_masters(ctx: ProviderContext) -> list[str] | None:
    """The master images the checker names (parameter ``master_images``: scene ids separated by ';'
    or ','), or None when nobody on the checker's side names them."""
    raw = ctx.parameters.get("master_images")
    if raw is None:
        return None
    names = sorted({p.strip() for p in str(raw).replace(",", ";").split(";") if p.strip()})
    return names or None


@provider(scope="image", measures=MASTER_FLAG)
def is_master(ctx: ProviderContext) -> list[Measured]:
    """Per scene: it is a master image (JRC Table 9). The checker's ``master_images`` when stated,
    else the contractor's ``scenes.is_master`` (red team R8: un-flagging a master switched its rules
    off)."""
    t = ctx.delivery.table("scenes")
    if t is None:
        empty = pd.Series(dtype=object)
        return [Measured("derived.is_master", "image", "bool", empty, empty.copy())]
    ids = t.ids.astype(str).to_numpy()
    rows = pd.Series(t.df["_row"].to_numpy(), index=ids)
    rows = rows[~rows.index.duplicated()]
    named = named_masters(ctx)
    if named is None:
        raw = (
            t.df["is_master"].to_numpy(dtype=object)
            if "is_master" in t.df
            else np.full(len(ids), None)
        )
        values = pd.Series(
            [None if v is None or (isinstance(v, float) and np.isnan(v)) else bool(v) for v in raw],
            index=ids,
            dtype=object,
        )
        notes = pd.Series(
            f"declared in {t.file} is_master (the checker names no master_images)",
            index=rows.index,
            dtype=object,
        )
    else:
        values = pd.Series([i in named for i in ids], index=ids, dtype=object)
        notes = pd.Series(
            {
                i: (
                    "a master image named by the checker (master_images)"
                    if i in named
                    else "not among the master images the checker names (master_images)"
                )
                for i in rows.index
            },
            dtype=object,
        )
    values = values[~values.index.duplicated()]
    return [
        Measured(
            "derived.is_master",
            "image",
            "bool",
            values,
            RowEvidence(t.file, t.sha256, rows),
            notes=notes,
        )
    ]


@provider(scope="delivery", measures=MASTER_AGREE)
def master_images_agree(ctx: ProviderContext) -> list[Measured]:
    """The scenes the contractor flags master are the ones the checker names (JRC Table 9 "identify as
    master image"); not applicable when the checker names none."""
    d = ctx.delivery
    t = d.table("scenes")
    named = named_masters(ctx)
    if named is None:
        why = "the checker names no master image (parameter master_images)"
        return [
            Measured(
                "derived.master_images_agree",
                "delivery",
                "bool",
                pd.Series({d.id: None}, dtype=object),
                pd.Series({d.id: ()}, dtype=object),
                notes=pd.Series({d.id: why}, dtype=object),
                na=pd.Series({d.id: why}, dtype=object),
            )
        ]
    ids = t.ids.astype(str) if t is not None else pd.Series(dtype=str)
    flagged = sorted(ids[_flagged_master(t).to_numpy(bool)].tolist()) if t is not None else []
    unknown = [n for n in named if n not in set(ids.tolist())]
    problems = []
    if unknown:
        problems.append(
            f"named by the checker but no row of the scenes table: {', '.join(unknown)}"
        )
    if not_flagged := [n for n in named if n not in flagged and n not in unknown]:
        problems.append(f"named by the checker but not flagged is_master: {', '.join(not_flagged)}")
    if extra := [f for f in flagged if f not in named]:
        problems.append(f"flagged is_master but not named by the checker: {', '.join(extra)}")
    where = t.file if t is not None else "the delivery (no scenes table)"
    note = (
        f"{where}: " + "; ".join(problems)
        if problems
        else f"{where} flags is_master exactly the checker's master images ({', '.join(named)})"
    )
    ev = t.evidence(t.df["_row"]) if t is not None else (d.manifest_evidence("tables"),)
    return [
        Measured(
            "derived.master_images_agree",
            "delivery",
            "bool",
            pd.Series({d.id: not problems}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
        )
    ]


@provider(scope="delivery", measures=MASTER)
def master_images(ctx: ProviderContext) -> list[Measured]:
    """Number of scenes declared master image (JRC Table 9 "identify as master image").

    Not applicable when no scene shows a master-image workflow: §9.4 "only in rare cases will images
    be corrected to a "master image"", so a delivery corrected to absolute positions needs none. Any
    trace of one (a scene flagged ``is_master``, or ``master_image_id``, ``master_pixel_size`` or
    ``master_check_date`` filled) makes the declaration required, so clearing ``is_master`` on a
    checked master (red team R8) gives 0, not "not applicable"."""
    d = ctx.delivery
    t = d.table("scenes")
    na = None
    ev: tuple[Any, ...]
    if t is None:
        value, ev, note = (
            None,
            (d.manifest_evidence("tables"),),
            "the manifest declares no 'scenes' table",
        )
        na = pd.Series(
            {d.id: "no scenes table: no satellite master image to identify"}, dtype=object
        )
    else:
        flag = _flagged_master(t)
        masters = t.ids.astype(str)[flag.to_numpy(bool)].tolist()
        traces = pd.Series(False, index=t.df.index)
        for col in MASTER_EVIDENCE:
            if col in t.df:
                traces |= t.df[col].map(_filled).astype(bool)
        traced = t.ids.astype(str)[traces.to_numpy(bool)].tolist()
        value = float(len(masters))
        ev = t.evidence(t.df["_row"][flag | traces] if masters or traced else t.df["_row"])
        if masters:
            note = f"master image(s) {', '.join(masters[:5])} ({t.file} is_master)"
        elif traced:
            note = (
                f"no row of {t.file} has is_master true, but scene(s) {', '.join(traced[:5])} "
                "record a master "
                f"image ({'/'.join(MASTER_EVIDENCE)})"
            )
        else:
            note = f"no scene of {t.file} is or refers to a master image"
            na = pd.Series(
                {
                    d.id: "no master-image workflow: no scene has is_master, master_image_id, "
                    "master_pixel_size or master_check_date (JRC §9.4: absolute correction)"
                },
                dtype=object,
            )
    return [
        Measured(
            "derived.master_images",
            "delivery",
            "1",
            pd.Series({d.id: value}, dtype=object),
            pd.Series({d.id: ev}, dtype=object),
            notes=pd.Series({d.id: note}, dtype=object),
            na=na,
        )
    ]
