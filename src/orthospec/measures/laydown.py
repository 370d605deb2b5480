"""The photo lay-down's arithmetic (JRC §5.2.1 "predefined GSD", §5.2.2 "all the surveyed area will
be covered with imagery"): the ground scale of a frame photo, a listed camera's published format,
which photos can be laid down and which have a flying height their GSD contradicts. Pure: arrays in,
arrays out; no I/O. The footprints themselves are
:func:`orthospec.measures.mosaic.photo_footprints`.

Used by ``derived.photo_coverage`` (engine/providers/coverage.py).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: A photo counts toward coverage only when its lay-down GSD (H/f x pixel size, the scale of its
#: footprint) is at most this factor times its reference GSD (the finest of
#: ``images.acquisition_gsd``, ``images.gsd``, ``product.gsd`` and its delivered raster's measured
#: pixel size). 20 %: the ground-pixel size of one photo varies with the terrain under it (H is
#: above mean ground) and §5.2.1 only asks for the "predefined GSD" (should, no tolerance);
#: aerial-pass agrees within 0.1 %, the red team's inflated heights were 150 % too coarse. Only a
#: coarser (larger) footprint is refused: a smaller one can only lower the coverage, never hide a
#: gap.
GSD_TOLERANCE = 1.2
#: stations closer than this share of a footprint's length are one station recorded twice (a copied
#: row)
SAME_STATION = 0.05


def ground_scale(height_m: np.ndarray, pixel_um: np.ndarray, focal_mm: np.ndarray) -> np.ndarray:
    """Ground metres per pixel of a vertical frame photo: H/f x pixel size."""
    return height_m * (pixel_um * 1e-6) / (focal_mm * 1e-3)


def published_format(
    across_px: float, along_px: float, pixels: Sequence[int]
) -> tuple[float, float]:
    """(across, along) pixels of a camera whose published format is ``pixels``: the longer side
    across track unless the declared format puts it along track."""
    big, small = max(pixels), min(pixels)
    wide = not (np.isfinite(along_px) and np.isfinite(across_px) and along_px > across_px)
    return (big, small) if wide else (small, big)


def placeable(x: np.ndarray, y: np.ndarray, across: np.ndarray, along: np.ndarray) -> np.ndarray:
    """Per photo: it has a station and a footprint of positive size (all finite)."""
    return (
        np.isfinite(np.column_stack([x, y, across, along])).all(axis=1) & (across > 0) & (along > 0)
    )


def inflated(
    scale: np.ndarray, reference: np.ndarray, placed: np.ndarray, tolerance: float = GSD_TOLERANCE
) -> np.ndarray:
    """Per photo: placed, with a known reference GSD, and a ground scale more than ``tolerance``
    times it (a flying height the delivery contradicts; red team R7/R18)."""
    return placed & np.isfinite(reference) & (scale > tolerance * reference)


def same_station_distance(across: np.ndarray, along: np.ndarray) -> float:
    """Distance under which two stations are one: ``SAME_STATION`` of the median footprint's shorter
    side."""
    return SAME_STATION * float(np.nanmedian(np.minimum(across, along)))
