"""Whether the product is pan-sharpened, computed from its bands and pixel sizes (JRC §10.5).

* ``derived.pansharpened`` (delivery): the product is pan-sharpened, computed from the bands and
  pixel sizes (a multispectral product finer than the scenes' native multispectral pixel, by
  ``PAN_MARGIN``: measures/pansharpening.py), so a declared ``product.pansharpened: false`` cannot
  switch off JRC §10.5 ("Pan-sharpening of satellite data"); ``derived.pansharpened_agrees``
  compares it with the declaration.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ...measures.pansharpening import PAN_MARGIN
from ...measures.pansharpening import image_pansharpened as _image_pansharpened
from ..registry import Measured, ProviderContext, provider
from .cells import table_metres as _table_metres

__all__ = ["PAN_MARGIN", "pansharpened"]

PANSHARPENED = {"derived.pansharpened": "bool", "derived.pansharpened_agrees": "bool"}


def _file_band_counts(ctx: ProviderContext, ids: list[str]) -> tuple[dict[str, int], list[Any]]:
    """Colour bands (alpha excluded) of the delivered image files of ``ids``: the file, not the
    declared ``images.bands``, decides whether the product is multispectral. Unreadable files are
    left to the declared bands (their own rules report them)."""
    from .rasters import scanned

    d = ctx.delivery
    imgs = d.table("images")
    if imgs is None or "file" not in imgs.df or not ids:
        return {}, []
    got = scanned(ctx)
    if "missing" in got:
        return {}, []
    out: dict[str, int] = {}
    ev: list[Any] = []
    for i in ids:
        f = got["facts"].get(i)
        if f is None or not f.readable or i in got["errors"]:
            continue
        out[i] = sum(1 for c in f.colorinterp if c != "alpha")
        ev.append(d.evidence(f.path))
    return out, ev


def _image_inputs(
    ctx: ProviderContext, ids: list[str]
) -> tuple[pd.Series, dict[str, int | None], pd.Series, list[Any]]:
    """Per image of ``ids``: delivered pixel size in m, colour band count (the file's, else
    ``images.bands``, else ``product.bands``), native multispectral pixel in m, and the evidence of
    the files read."""
    d = ctx.delivery
    m = d.manifest
    imgs, scenes = d.table("images"), d.table("scenes")
    product_bands = len(m.product.bands) if m.product.bands else None
    gsd_default = d.gsd_m if d.gsd_m is not None else np.nan
    gsd = pd.Series(gsd_default, index=ids, dtype=float)
    bands: dict[str, int | None] = {i: product_bands for i in ids}
    if imgs is not None and "gsd" in imgs.df:
        g = _table_metres(imgs, "gsd").reindex(ids)
        gsd[g.notna()] = g[g.notna()]
    if imgs is not None and "bands" in imgs.df:
        col = pd.Series(imgs.df["bands"].to_numpy(), index=imgs.ids.astype(str).to_numpy())
        for i, v in col[~col.index.duplicated()].items():
            parts = [b for b in str(v).split(";") if b.strip()] if isinstance(v, str) else []
            if parts:
                bands[str(i)] = len(parts)
    ms = (
        _table_metres(scenes, "ms_pixel_size").reindex(ids)
        if scenes is not None and "ms_pixel_size" in scenes.df
        else pd.Series(np.nan, index=ids, dtype=float)
    )
    file_bands, file_ev = _file_band_counts(ctx, [i for i in ids if np.isfinite(ms[i])])
    bands.update(file_bands)
    return gsd, bands, ms, file_ev


def _delivery_verdict(
    ids: list[str], per: dict[str, tuple[bool | None, str]]
) -> tuple[bool | None, str]:
    """The delivery is pan-sharpened when any image is; false when every image is decided false."""
    yes = [i for i, (v, _) in per.items() if v is True]
    undecided = [i for i, (v, _) in per.items() if v is None]
    if not ids:
        value: bool | None = None
        note = "the delivery has no images or scenes table: pan-sharpening cannot be computed"
    elif yes:
        value, note = (
            True,
            f"{len(yes)} of {len(ids)} image(s) pan-sharpened, e.g. {yes[0]}: {per[yes[0]][1]}",
        )
    elif undecided:
        value, note = (
            None,
            f"{len(undecided)} image(s) undecided, e.g. {undecided[0]}: {per[undecided[0]][1]}",
        )
    else:
        value, note = False, f"no image pan-sharpened, e.g. {ids[0]}: {per[ids[0]][1]}"
    return value, note


@provider(scope="delivery", measures=PANSHARPENED)
def pansharpened(ctx: ProviderContext) -> list[Measured]:
    """The delivered product is pan-sharpened (JRC §10.5), computed from bands and pixel sizes.

    Per image: true when the product is multispectral (>= 2 colour bands: in the delivered file,
    else ``images.bands``, else ``product.bands``) at a pixel size (``images.gsd``, else
    ``product.gsd``) at most the native multispectral pixel of its scene (``scenes.ms_pixel_size``)
    divided by 1.5. Resampling the MS bands alone to a grid a little finer than their own pixel
    (1.24 m -> 1.0 m for a round output pixel) is ordinary resampling, not fusion; but a product 1.5
    x finer than the MS bands carries detail they do not have, and every VHR/HR pan/MS pair has a
    ratio of at least 2 (WorldView-3 0.31/1.24 m, Pleiades 0.7/2.8 m, SPOT 6/7 1.5/6 m, Landsat
    15/30 m), so a true pan-sharpened product is always on the true side of the margin. (A product
    merely upsampled 1.5 x from its MS bands also counts: §10.3 "preservation of the spatial
    resolution of the panchromatic image" is then exactly what the inspector must look at.) False
    for a single-band product or one not finer than the MS pixel; between the two the data do not
    decide and the declared ``product.pansharpened`` is used (with a note), else missing. The
    delivery is pan-sharpened when any image is; false when every image is decided false; else
    missing with the column to deliver.
    """
    d = ctx.delivery
    m = d.manifest
    imgs, scenes = d.table("images"), d.table("scenes")
    declared = getattr(m.product, "pansharpened", None)
    ev: list[Any] = [
        d.manifest_evidence("product.bands"),
        d.manifest_evidence("product.gsd"),
        d.manifest_evidence("product.pansharpened"),
    ]
    ev += [e for t in (imgs, scenes) if t is not None for e in t.evidence(t.df["_row"])]
    ids: list[str] = sorted(set(imgs.ids.astype(str)) if imgs is not None else set())
    if scenes is not None:
        ids = sorted(set(ids) | set(scenes.ids.astype(str)))
    gsd, bands, ms, file_ev = _image_inputs(ctx, ids)
    ev += file_ev
    per = {i: _image_pansharpened(bands[i], float(gsd[i]), float(ms[i]), declared) for i in ids}
    value, note = _delivery_verdict(ids, per)
    agrees: bool | None = None if declared is None or value is None else bool(declared) == value
    if agrees is False:
        note += (
            f"; the manifest declares product.pansharpened: {str(declared).lower()}, which the "
            "data contradict"
        )
    agree_note = (
        f"declared {str(declared).lower()}, computed {str(value).lower()}"
        if agrees is not None
        else "product.pansharpened not declared"
        if declared is None
        else "the computed value is missing"
    )
    na = (
        pd.Series({d.id: "the contractor declares no product.pansharpened"}, dtype=object)
        if declared is None
        else None
    )
    evidence = pd.Series({d.id: tuple(ev)}, dtype=object)
    return [
        Measured(
            "derived.pansharpened",
            "delivery",
            "bool",
            pd.Series({d.id: value}, dtype=object),
            evidence,
            notes=pd.Series({d.id: note}, dtype=object),
        ),
        Measured(
            "derived.pansharpened_agrees",
            "delivery",
            "bool",
            pd.Series({d.id: agrees}, dtype=object),
            evidence,
            notes=pd.Series({d.id: agree_note}, dtype=object),
            na=na,
        ),
    ]
