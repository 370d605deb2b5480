"""Mosaic and image-fusion measures (JRC EUR 23638 EN §10.3 and §11, Table 11). Pure: no I/O.

* Seamline coverage (Table 11, "Visual check for full coverage at the AOI with seamlines
  polygons"): the union of the seamline polygons must cover the area of interest with no gap;
  seamline polygons of a mosaic partition it, so any two overlapping by a positive area is an
  error too.
* Radiometric balance across seamlines (Table 11, "Similar types of objects not varying more
  than 10% in DN value (average)"): over the overlap strip of two adjacent orthos the mean DN
  of each band is compared; the difference is given as a percentage of the mean of the two
  averages (the "10 % in DN value" reading) and, when a bit depth is known, of the available
  grey levels too.
* Pan-sharpening keeps the PAN resolution (§10.3). The point-spread-function analysis of the
  text needs edge targets (see the edge measure); as an image-wide proxy we compare the
  *normalised gradient energy* GE = mean(|Sobel gradient|^2) / var(image) of the fused
  product's intensity (mean of its bands) with that of the PAN image over the same ground:
  dividing by the variance removes contrast differences, so the ratio tests only how much
  high-frequency content survived (1 = as sharp as PAN; an up-sampled MS image scores far
  lower). The correlation of the two Laplacian-filtered images (Zhou et al. 1998 spatial
  correlation index) is reported alongside.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import MeasureError

if TYPE_CHECKING:  # shapely ships no type information: Any to mypy, but it names what is meant
    from shapely import Geometry


@dataclass(frozen=True)
class SeamlineCoverage:
    """Gaps and overlaps of seamline polygons over the area of interest (CRS units)."""

    aoi_area: float
    covered_area: float
    gap_area: float
    gap_pct: float
    overlap_area: float
    overlap_pct: float
    overlapping_pairs: tuple[tuple[int, int], ...]
    invalid_polygons: tuple[int, ...]

    @property
    def ok(self) -> bool:
        return self.gap_area == 0.0 and self.overlap_area == 0.0 and not self.invalid_polygons


def seamline_coverage(seamlines: Sequence[Geometry], aoi: Geometry, *,
                      area_tolerance: float = 1e-9) -> SeamlineCoverage:
    """Gap area/share of the AOI not covered by seamline polygons, and pairwise overlaps.

    ``area_tolerance`` is relative to the AOI area: slivers smaller than that (floating-point
    noise of shared boundaries) count as zero.
    """
    import shapely
    from shapely.strtree import STRtree

    geoms = [shapely.make_valid(g) if not g.is_valid else g for g in seamlines]
    invalid = tuple(i for i, g in enumerate(seamlines) if not g.is_valid)
    aoi_g = aoi if aoi.is_valid else shapely.make_valid(aoi)
    a_area = float(aoi_g.area)
    if a_area <= 0:
        raise MeasureError("area of interest has no area")
    tol = area_tolerance * a_area
    arr = np.asarray(geoms, dtype=object)
    try:
        coverage = bool(arr.size) and bool(shapely.coverage_is_valid(arr))
    except (
        shapely.errors.GEOSException,
        TypeError,
        ValueError,
    ):  # lines or collections in the layer
        coverage = False
    pairs = []
    overlap = 0.0
    if coverage:
        # polygons that meet only along shared edges, vertex for vertex (the usual seamline
        # mosaic; GEOS CoverageValidator): no two overlap, and GEOS's coverage union is exact and
        # several times faster than a general union
        union = shapely.coverage_union_all(arr)
    else:
        union = shapely.union_all(geoms) if geoms else shapely.Polygon()
        tree = STRtree(geoms)
        left, right = tree.query(geoms, predicate="intersects")
        keep = left < right
        left, right = left[keep], right[keep]
        try:
            # neighbours that only touch have no interior in common, so no overlap area: one
            # vectorised DE-9IM test instead of an intersection each
            inner = shapely.relate_pattern(arr[left], arr[right], "T********")
            left, right = left[inner], right[inner]
        except shapely.errors.GEOSException:  # a GEOS without relate on collections: intersect all
            pass
        for i, j in zip(left.tolist(), right.tolist(), strict=True):
            area = float(geoms[i].intersection(geoms[j]).area)
            if area > tol:
                pairs.append((i, j))
                overlap += area
    gap = float(aoi_g.difference(union).area)
    gap = 0.0 if gap <= tol else gap
    return SeamlineCoverage(
        aoi_area=a_area,
        covered_area=a_area - gap,
        gap_area=gap,
        gap_pct=100.0 * gap / a_area,
        overlap_area=overlap,
        overlap_pct=100.0 * overlap / a_area,
        overlapping_pairs=tuple(pairs),
        invalid_polygons=invalid,
    )


@dataclass(frozen=True)
class RadiometricDifference:
    """Mean DN of each band on both sides of a seamline and their difference."""

    mean_a: tuple[float, ...]
    mean_b: tuple[float, ...]
    difference_dn: tuple[float, ...]
    difference_pct: tuple[float, ...]  # of the mean of the two averages
    difference_range_pct: tuple[float, ...] | None  # of 2^bit_depth grey levels

    @property
    def max_pct(self) -> float:
        return max(self.difference_pct)


def radiometric_difference(
    mean_a: Sequence[float], mean_b: Sequence[float], *, bit_depth: int | None = None
) -> RadiometricDifference:
    """|mean_a - mean_b| per band as % of their average DN (Table 11 "10% in DN value")."""
    a = np.asarray(mean_a, dtype=np.float64)
    b = np.asarray(mean_b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1 or a.size == 0:
        raise MeasureError(f"need two equal lists of band means, got {a.shape} and {b.shape}")
    diff = np.abs(a - b)
    level = (a + b) / 2.0
    if np.any(level <= 0):
        raise MeasureError("mean DN of an overlap is zero or negative: no relative difference")
    rng = None
    if bit_depth is not None:
        rng = tuple(float(v) for v in 100.0 * diff / float(1 << bit_depth))
    return RadiometricDifference(
        mean_a=tuple(float(v) for v in a),
        mean_b=tuple(float(v) for v in b),
        difference_dn=tuple(float(v) for v in diff),
        difference_pct=tuple(float(v) for v in 100.0 * diff / level),
        difference_range_pct=rng,
    )


def gradient_energy(image: np.ndarray) -> float:
    """Normalised gradient energy mean(|Sobel|^2) / var(image) of a 2-D array (interior)."""
    from scipy import ndimage

    a = np.asarray(image, dtype=np.float64)
    if a.ndim != 2 or min(a.shape) < 5:
        raise MeasureError(f"gradient energy needs a 2-D image of at least 5x5, got {a.shape}")
    var = float(a.var())
    if var == 0.0:
        raise MeasureError("image is flat: no gradient energy")
    gx = ndimage.sobel(a, axis=1)[1:-1, 1:-1] / 8.0
    gy = ndimage.sobel(a, axis=0)[1:-1, 1:-1] / 8.0
    return float(np.mean(gx * gx + gy * gy)) / var


@dataclass(frozen=True)
class Sharpness:
    """PAN resolution kept in a fused product (§10.3 proxy)."""

    ge_pan: float
    ge_fused: float
    ratio: float  # ge_fused / ge_pan (1 = as sharp as PAN)
    highpass_correlation: float  # correlation of the Laplacians of PAN and fused intensity


def pan_sharpness(pan: np.ndarray, fused: np.ndarray) -> Sharpness:
    """Compare a PAN window with the same window of a fused product (bands, rows, cols)."""
    from scipy import ndimage

    p = np.asarray(pan, dtype=np.float64)
    f = np.asarray(fused, dtype=np.float64)
    if f.ndim == 3:
        f = f.mean(axis=0)
    if p.ndim == 3:
        p = p[0]
    if p.shape != f.shape:
        raise MeasureError(f"PAN window {p.shape} and fused window {f.shape} differ in shape")
    ge_p, ge_f = gradient_energy(p), gradient_energy(f)
    lp = ndimage.laplace(p)[1:-1, 1:-1].ravel()
    lf = ndimage.laplace(f)[1:-1, 1:-1].ravel()
    corr = float(np.corrcoef(lp, lf)[0, 1]) if lp.std() > 0 and lf.std() > 0 else 0.0
    return Sharpness(ge_pan=ge_p, ge_fused=ge_f, ratio=ge_f / ge_p, highpass_correlation=corr)


def photo_footprints(
    cx: Sequence[float],
    cy: Sequence[float],
    across: Sequence[float],
    along: Sequence[float],
    heading: Sequence[float],
) -> list[object]:
    """Ground footprints of vertical frame photos as rectangles (JRC §5.2.2 photo lay-down).

    Each photo covers ``across`` × ``along`` metres (format in pixels × H/f × pixel size) centred
    on its exposure station, the ``along`` side in the flight direction ``heading`` (radians from
    +x). Tilt and relief are ignored: a vertical-photo approximation, the one the flight plan uses.
    """
    from shapely.geometry import Polygon

    x, y = np.asarray(cx, dtype=float), np.asarray(cy, dtype=float)
    a, b, h = (np.asarray(v, dtype=float) for v in (across, along, heading))
    if not (x.size == y.size == a.size == b.size == h.size):
        raise MeasureError("photo footprints need one centre, size and heading per photo")
    if not np.isfinite(np.concatenate([x, y, a, b, h])).all() or (a <= 0).any() or (b <= 0).any():
        raise MeasureError("photo footprints need finite centres and positive sizes")
    ux, uy = np.cos(h), np.sin(h)  # along track
    vx, vy = -uy, ux  # across track
    out = []
    for i in range(x.size):
        da, dc = b[i] / 2.0, a[i] / 2.0
        corners = [
            (x[i] + sa * da * ux[i] + sc * dc * vx[i], y[i] + sa * da * uy[i] + sc * dc * vy[i])
            for sa, sc in ((1, 1), (1, -1), (-1, -1), (-1, 1))
        ]
        out.append(Polygon(corners))
    return out


def strip_headings(
    cx: Sequence[float], cy: Sequence[float], groups: Sequence[str], *, min_distance: float = 0.0
) -> np.ndarray:
    """Flight direction per photo: towards its nearest neighbour of the same flight (radians).

    Along-track photo spacing is shorter than the strip spacing, so the nearest exposure of the
    same flight lies on the same strip; a photo alone in its flight gets heading 0 (x axis). A
    station recorded twice, or within ``min_distance`` (a row copied, with or without a nudge), is
    the same station, not a neighbour: the next farther one is (a copied row otherwise turned both
    footprints across the strip).
    """
    x, y = np.asarray(cx, dtype=float), np.asarray(cy, dtype=float)
    g = np.asarray([str(v) for v in groups], dtype=object)
    out = np.zeros(x.size, dtype=float)
    for key in np.unique(g):
        idx = np.flatnonzero(g == key)
        if idx.size < 2:
            continue
        px, py = x[idx], y[idx]
        d2 = (px[:, None] - px[None, :]) ** 2 + (py[:, None] - py[None, :]) ** 2
        d2[d2 <= min_distance * min_distance] = np.inf  # itself, and any copy of its station
        j = np.argmin(d2, axis=1)
        out[idx] = np.arctan2(py[j] - py, px[j] - px)
    return out
