"""One reader for a region of a delivered raster: edge-target ROIs, footprints, positions.

Why one reader (issue 15 item 2): `orthospec measure edge` and the edge provider of `check` read
the same edge target, and must read it the same way, or the two report different RER and FWHM
for one ROI. Everything here goes through :func:`~orthospec.raster.reading.open_read_only`
(driver allow-list, declared-size limits, no ``.aux.xml`` written) and the one error boundary
:func:`~orthospec.raster.reading.gdal_errors`, so a file GDAL cannot read becomes a
:class:`~orthospec.errors.MeasureError` naming it, never a traceback nor a silent default.

* window: a :class:`PixelWindow` (x0, y0, x1, y1 in pixels, x1/y1 exclusive: the manifest's
  ``edge_targets[].roi`` and ``measure edge --roi``) or a :class:`MapWindow` (xmin, ymin, xmax,
  ymax in the raster's CRS, widened to whole pixels); none: the whole band;
* validity: GDAL's, through rasterio's masked read: the band's nodata value (and NaN for
  floats), else the per-dataset mask (internal ``.msk``) or alpha band; an explicit ``nodata``
  (``measure edge --nodata``) replaces it (that DN and NaN are invalid, nothing else);
* the pixels keep the band's data type (the edge chain's saturation and quantisation checks
  depend on it); invalid pixels are masked;
* GSD: the pixel size from the affine transform when the pixels are square and unrotated and
  the CRS is projected with a linear unit convertible to metres (``linear_units_factor``:
  a US-foot CRS gives metres too); else None with the reason in ``gsd_note``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rasterio.errors import CRSError, NotGeoreferencedWarning
from rasterio.windows import Window, from_bounds

from ..errors import MeasureError
from .reading import gdal_errors, open_read_only, read_only_env

Bounds = tuple[float, float, float, float]  # left, bottom, right, top in the raster's CRS


@dataclass(frozen=True)
class PixelWindow:
    """x0, y0, x1, y1 in pixels of the raster, x1 and y1 exclusive."""

    x0: int
    y0: int
    x1: int
    y1: int

    def __post_init__(self) -> None:
        vals = (self.x0, self.y0, self.x1, self.y1)
        if not all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in vals):
            raise MeasureError(
                f"ROI {list(vals)}: expected four whole numbers of pixels x0, y0, x1, y1"
            )
        if not (0 <= self.x0 < self.x1 and 0 <= self.y0 < self.y1):
            raise MeasureError(
                f"ROI {list(vals)}: expected 0 <= x0 < x1 and 0 <= y0 < y1 (pixels, "
                "x1/y1 exclusive)"
            )

    def as_tuple(self) -> tuple[int, int, int, int]:
        return int(self.x0), int(self.y0), int(self.x1), int(self.y1)


@dataclass(frozen=True)
class MapWindow:
    """xmin, ymin, xmax, ymax in the raster's CRS; read as the pixels it touches."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float

    def __post_init__(self) -> None:
        vals = (self.xmin, self.ymin, self.xmax, self.ymax)
        if not all(math.isfinite(float(v)) for v in vals) or not (
            self.xmin < self.xmax and self.ymin < self.ymax
        ):
            raise MeasureError(f"map ROI {list(vals)}: expected finite xmin < xmax and ymin < ymax")


@dataclass(frozen=True, eq=False)
class RasterRoi:
    """The pixels of one band in one window, their validity and the GSD of the raster."""

    file: str  # as messages name it (relative to the delivery when known)
    band: int
    window: tuple[int, int, int, int]  # pixels x0, y0, x1, y1 (exclusive) actually read
    data: np.ma.MaskedArray  # the band's dtype; masked = not valid
    nodata: float | None  # the value that marked invalid pixels (declared or given), if any
    gsd_m: float | None
    gsd_note: str  # where the GSD came from, or why there is none
    crs: str | None

    @property
    def masked(self) -> bool:
        """At least one pixel of the window is invalid."""
        return bool(np.ma.getmaskarray(self.data).any())

    @property
    def values(self) -> np.ndarray:
        """The pixels as stored (invalid ones keep their stored value), the band's dtype."""
        return np.ma.getdata(self.data)

    def filled(self) -> np.ndarray:
        """Float64 copy with invalid pixels as NaN."""
        return np.ma.filled(self.data.astype(float), np.nan)


def read_roi(
    path: str | Path,
    *,
    window: PixelWindow | MapWindow | None = None,
    band: int = 1,
    nodata: float | None = None,
    name: str | None = None,
    max_pixels: int | None = None,
    too_large: str = "give an ROI",
) -> RasterRoi:
    """Read ``band`` of the raster at ``path`` in ``window`` (see the module docstring).

    ``max_pixels`` bounds the read (a whole band for an automatic edge search), checked before
    any pixel is read; ``too_large`` ends the message when it is exceeded (what to do).

    Raises
    ------
    MeasureError
        naming ``name`` (default the path) when the file is refused or unreadable, the band does
        not exist, the window is not inside the image, or the read is too large.
    """
    label = name or str(path)
    with (
        _not_georeferenced_is_fine(),
        read_only_env(),
        open_read_only(path, name=label) as ds,
        gdal_errors(file=label, path=path),
    ):
        return roi_of(
            ds,
            label,
            window=window,
            band=band,
            nodata=nodata,
            max_pixels=max_pixels,
            too_large=too_large,
        )


def roi_of(
    ds: Any,
    label: str,
    *,
    window: PixelWindow | MapWindow | None = None,
    band: int = 1,
    nodata: float | None = None,
    max_pixels: int | None = None,
    too_large: str = "give an ROI",
) -> RasterRoi:
    """:func:`read_roi` on an open dataset (call inside ``read_only_env`` and ``gdal_errors``)."""
    if not 1 <= band <= ds.count:
        raise MeasureError(
            f"{label}: band {band} does not exist; the file has {ds.count} band(s) (1..{ds.count})"
        )
    px = _pixel_window(ds, window, label)
    x0, y0, x1, y1 = px
    if max_pixels is not None and (x1 - x0) * (y1 - y0) > max_pixels:
        raise MeasureError(
            f"{label}: band {band} is to be read as {x1 - x0} x {y1 - y0} px, more than "
            f"the limit of {max_pixels} px; {too_large}"
        )
    win = Window(x0, y0, x1 - x0, y1 - y0)
    if nodata is None:
        data = ds.read(band, window=win, masked=True)
        declared = ds.nodatavals[band - 1]
        used = None if declared is None else float(declared)
    else:
        raw = ds.read(band, window=win)
        bad = raw == nodata
        if np.issubdtype(raw.dtype, np.floating):
            bad |= np.isnan(raw)
        data = np.ma.MaskedArray(raw, mask=bad)
        used = float(nodata)
    gsd, note = pixel_size_m(ds)
    crs = ds.crs.to_string() if ds.crs is not None else None
    return RasterRoi(label, band, px, data, used, gsd, note, crs)


def _pixel_window(
    ds: Any, window: PixelWindow | MapWindow | None, label: str
) -> tuple[int, int, int, int]:
    """The pixel window to read, checked to lie inside the image."""
    if window is None:
        return 0, 0, int(ds.width), int(ds.height)
    if isinstance(window, MapWindow):
        if ds.crs is None and ds.transform.is_identity:
            raise MeasureError(
                f"{label}: a map ROI needs a georeferenced raster; this one has no "
                "transform (give the ROI in pixels)"
            )
        w = from_bounds(window.xmin, window.ymin, window.xmax, window.ymax, transform=ds.transform)
        eps = 1e-6  # px: a bound on a pixel edge does not take in the next pixel
        x0, y0 = max(math.floor(w.col_off + eps), 0), max(math.floor(w.row_off + eps), 0)
        x1 = min(math.ceil(w.col_off + w.width - eps), ds.width)
        y1 = min(math.ceil(w.row_off + w.height - eps), ds.height)
        if x1 <= x0 or y1 <= y0:
            raise MeasureError(
                f"{label}: map ROI {window.xmin:g},{window.ymin:g},{window.xmax:g},"
                f"{window.ymax:g} does not overlap the image"
            )
        return x0, y0, x1, y1
    x0, y0, x1, y1 = window.as_tuple()
    if x1 > ds.width or y1 > ds.height:
        raise MeasureError(
            f"{label}: ROI {x0},{y0},{x1},{y1} exceeds the image ({ds.width} x {ds.height} px)"
        )
    return x0, y0, x1, y1


def pixel_size_m(ds: Any) -> tuple[float | None, str]:
    """GSD in metres from the affine transform, and where it came from (or why there is none)."""
    t = ds.transform
    if ds.crs is None:
        return None, "no CRS: the pixel size is not known in metres"
    if not ds.crs.is_projected:
        return None, f"CRS {ds.crs.to_string()} is not projected: the pixel size is not a length"
    if t.b != 0 or t.d != 0:
        return None, "the transform is rotated or sheared: no single pixel size"
    if not math.isclose(abs(t.a), abs(t.e), rel_tol=1e-6):
        return None, f"pixels are not square ({abs(t.a):g} x {abs(t.e):g} CRS units)"
    try:
        unit, factor = ds.crs.linear_units_factor
    except CRSError as exc:  # a CRS without a linear unit
        return None, f"the CRS has no linear unit convertible to metres ({exc})"
    return abs(t.a) * float(factor), f"affine transform: {abs(t.a):g} {unit} per pixel"


def raster_bounds(path: str | Path, *, name: str | None = None) -> Bounds:
    """Footprint (left, bottom, right, top) of a raster in its CRS; MeasureError naming the file."""
    label = name or str(path)
    with (
        _not_georeferenced_is_fine(),
        read_only_env(),
        open_read_only(path, name=label) as ds,
        gdal_errors(file=label, path=path),
    ):
        b = ds.bounds
        return float(b.left), float(b.bottom), float(b.right), float(b.top)


@contextmanager
def _not_georeferenced_is_fine() -> Iterator[None]:
    """A chip without georeferencing is a valid edge target (its GSD is then None, with the
    reason in ``gsd_note``): no rasterio warning on stderr for it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        yield
