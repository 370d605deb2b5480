"""Whether a delivered product is pan-sharpened, from its band count and pixel sizes (JRC §10.5
"Pan-sharpening of satellite data"). Pure: numbers in, a verdict and its reason out; no I/O.

Used by ``derived.pansharpened`` (engine/providers/pansharpening.py), whose docstring gives the
reading of the margin.
"""

from __future__ import annotations

import numpy as np

#: a product at most 1/1.5 of the native multispectral pixel is read as fused with the PAN band
PAN_MARGIN = 1.5


def image_pansharpened(
    n_bands: int | None, gsd: float, ms: float, declared: bool | None
) -> tuple[bool | None, str]:
    """One image: pan-sharpened or not, and why (see ``derived.pansharpened``)."""
    if n_bands is None:
        return None, "band count unknown (image file, images.bands or product.bands)"
    if n_bands < 2:
        return False, f"{n_bands} band: not a multispectral product"
    if not np.isfinite(gsd):
        return None, "no delivered pixel size (images.gsd or product.gsd)"
    if not np.isfinite(ms):
        return None, "no native multispectral pixel size: deliver scenes.ms_pixel_size"
    if gsd <= ms / PAN_MARGIN:
        return True, (
            f"{n_bands} bands at {gsd:.4g} m, finer than the {ms:.4g} m multispectral pixel / "
            f"{PAN_MARGIN:g}: the detail comes from the PAN band"
        )
    if gsd >= ms:
        return (
            False,
            f"{n_bands} bands at {gsd:.4g} m, not finer than the {ms:.4g} m multispectral pixel",
        )
    if declared is not None:
        return declared, (
            f"{n_bands} bands at {gsd:.4g} m, between the {ms:.4g} m multispectral pixel and "
            f"{ms / PAN_MARGIN:.4g} m (plain resampling possible): the declared "
            f"product.pansharpened decides"
        )
    return None, (
        f"{n_bands} bands at {gsd:.4g} m, between the {ms:.4g} m multispectral pixel and "
        f"{ms / PAN_MARGIN:.4g} m: the data do not decide and product.pansharpened is not declared"
    )
