"""Large-format cameras as published (specs/cameras.yaml: Passini, Jacobsen & Day, Table 1).

* ``derived.camera_agrees`` (camera): the declared format and pixel size of a camera are its model's
  published ones; the photo lay-down (``derived.photo_coverage``, coverage.py) uses the published
  values for a listed model whatever the cameras table declares (issue 25: a format declared 3 x
  larger hid a missing strip).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import pandas as pd

from ...units import convert
from ..registry import Measured, ProviderContext, RowEvidence, provider
from .cells import filled as _filled

#: camera format columns (pixels across and along track) the photo lay-down needs
FORMAT_COLUMNS = ("format_across_px", "format_along_px")
CAMERA = {"derived.camera_agrees": "bool"}


def _camera_key(model: Any) -> str:
    import re

    text = str(model or "").lower().replace("ultracam", "uc")
    return re.sub(r"[^a-z0-9]", "", text)


@dataclass(frozen=True)
class PublishedCamera:
    """One row of specs/cameras.yaml."""

    id: str
    #: format in pixels (x, y) as published
    pixels: tuple[int, int]
    pixel_size_um: float
    focal_length_mm: tuple[float, ...]


@lru_cache(maxsize=1)
def _published() -> dict[str, PublishedCamera]:
    import yaml

    from ...resources import specs_dir

    raw = yaml.safe_load((specs_dir() / "cameras.yaml").read_text(encoding="utf-8"))
    return {
        _camera_key(c["id"]): PublishedCamera(
            id=c["id"],
            pixels=(int(c["pixels_x"]), int(c["pixels_y"])),
            pixel_size_um=float(c["pixel_size_um"]),
            focal_length_mm=tuple(float(f) for f in c["focal_length_mm"]),
        )
        for c in raw["cameras"]
    }


def known_camera(model: Any) -> PublishedCamera | None:
    """The published format of a large-format camera model (specs/cameras.yaml: Passini, Jacobsen &
    Day, Table 1), or None for a model the table does not list. Names match without case, spaces or
    punctuation, "UltraCam" read as "UC" (``UltraCam Eagle`` is ``UC Eagle``)."""
    if not model or not str(model).strip():
        return None
    return _published().get(_camera_key(model))


@provider(scope="camera", measures=CAMERA)
def camera_agrees(ctx: ProviderContext) -> list[Measured]:
    """The declared format and pixel size of a camera are its model's published ones (specs/cameras.yaml,
    Passini, Jacobsen & Day Table 1). The photo lay-down (derived.photo_coverage) uses the published
    values for a listed model whatever the table declares (issue 25: a format declared 3 x larger
    hid a missing strip); this measure reports the declaration the table contradicts. Not applicable
    to a model the table does not list."""
    t = ctx.delivery.table("cameras")
    if t is None:
        empty = pd.Series(dtype=object)
        return [Measured("derived.camera_agrees", "camera", "bool", empty, empty.copy())]
    ids = t.ids.astype(str).tolist()
    values: dict[str, bool | None] = {}
    notes: dict[str, str] = {}
    na: dict[str, str] = {}
    for k, i in enumerate(ids):
        row = t.df.iloc[k]
        model = row.get("model") if "model" in t.df else None
        known = known_camera(model)
        if known is None:
            values[i] = None
            na[i] = f"camera model {model!r} is not in the published table (specs/cameras.yaml)"
            continue
        problems = []
        declared = sorted(float(row[c]) for c in FORMAT_COLUMNS if c in t.df and _filled(row[c]))
        if len(declared) == 2 and declared != sorted(float(v) for v in known.pixels):
            problems.append(
                f"format {declared[1]:.0f} x {declared[0]:.0f} px declared, the {known.id}'s is "
                f"{max(known.pixels)} x {min(known.pixels)} px"
            )
        if "pixel_size" in t.df and _filled(row["pixel_size"]):
            px = float(
                convert(
                    np.array([float(row["pixel_size"])]), t.units.get("pixel_size", "µm"), "µm"
                )[0]
            )
            if abs(px - known.pixel_size_um) > 0.01 * known.pixel_size_um:
                problems.append(
                    f"pixel {px:g} µm declared, the {known.id}'s is {known.pixel_size_um:g} µm"
                )
        values[i] = not problems
        notes[i] = (
            (
                "; ".join(problems)
                + " (Passini, Jacobsen & Day Table 1): the photo lay-down uses the "
                "published values"
            )
            if problems
            else f"declared format and pixel are the {known.id}'s"
        )
    rows = pd.Series(t.df["_row"].to_numpy(), index=ids)
    return [
        Measured(
            "derived.camera_agrees",
            "camera",
            "bool",
            pd.Series(values, dtype=object),
            RowEvidence(t.file, t.sha256, rows),
            notes=pd.Series(notes, dtype=object),
            na=pd.Series(na, dtype=object) if na else None,
        )
    ]
