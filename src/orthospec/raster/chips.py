"""Reference chips and image windows for check point matching, read in windows only.

The checker's reference is either a *chip library* (a folder of small GeoTIFFs around the
points, as the Landsat and Sentinel-2 geometric QA keep them) or one reference orthoimage. For a
point, :func:`read_pair` reads

* the reference around the point, only the window of the reference that covers the template:
  taken as it is when its grid is the image's up to a translation (the fraction of a pixel is
  added to the measured position instead), else resampled (``rasterio.warp.reproject``: Lanczos
  when the reference is as coarse as the image or
  coarser, area average when it is finer) onto the delivered image's own pixel grid, in
  the image's CRS: after that the two differ by the delivery's error only;
* the delivered image's search window around the point (template plus the search range).

Both become one luminance band (:func:`orthospec.measures.matching.luminance` of the red, green
and blue bands when the file tags them, else of its first band), so an RGB image matches a
panchromatic or differently weighted reference. Memory per point is a few windows of
``chip_px + 2 * search_px`` pixels square, whatever the size of the files; files are opened
strictly read-only (:func:`orthospec.raster.reading.open_read_only`) and nothing is written next
to them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rasterio
from rasterio.crs import CRS
from rasterio.enums import ColorInterp, Resampling
from rasterio.transform import Affine
from rasterio.windows import Window

from ..errors import MeasureError, OrthospecError
from ..measures.matching import luminance
from ..provenance import sha256_file
from .reading import gdal_errors, open_read_only, read_only_env

if TYPE_CHECKING:
    from pyproj import Transformer

__all__ = [
    "CHIP_SUFFIXES",
    "Pair",
    "RasterHeader",
    "Reference",
    "open_reference",
    "read_header",
    "read_pair",
]

CHIP_SUFFIXES: tuple[str, ...] = (".tif", ".tiff")
#: pixels read beyond the template on the reference side, in reference pixels (Lanczos kernel).
#: Lanczos, not cubic convolution: on a grid offset of (0.37, 0.21) px cubic convolution moved
#: Landsat texture by 0.03-0.05 px, Lanczos by less than 0.005 px (tests/test_matching.py)
_KERNEL_PAD = 4


@dataclass(frozen=True)
class RasterHeader:
    """What matching needs to know of a raster before reading any pixel."""

    path: Path
    name: str  # as messages and records show it
    crs: CRS
    transform: Affine
    width: int
    height: int
    bands: tuple[int, ...]  # the bands whose mean is the luminance
    pixel: float  # mean pixel size in CRS units

    def contains(self, col: float, row: float, margin: float = 0.0) -> bool:
        return margin <= col <= self.width - margin and margin <= row <= self.height - margin

    def edge_distance(self, col: np.ndarray, row: np.ndarray) -> np.ndarray:
        """Distance in pixels to the nearest edge (negative outside)."""
        return np.minimum.reduce([col, row, self.width - col, self.height - row])


def _luminance_bands(ds: rasterio.io.DatasetReader) -> tuple[int, ...]:
    ci = list(ds.colorinterp)
    rgb = [
        ci.index(c) + 1 for c in (ColorInterp.red, ColorInterp.green, ColorInterp.blue) if c in ci
    ]
    if len(rgb) == 3:
        return tuple(rgb)
    first = next((i + 1 for i, c in enumerate(ci) if c != ColorInterp.alpha), 1)
    return (first,)


def read_header(path: str | Path, *, name: str | None = None) -> RasterHeader:
    """The header of one raster (GeoTIFF or JPEG 2000); MeasureError naming ``name`` when the file
    cannot be opened or has no CRS or no georeference."""
    label = name or str(path)
    with (
        read_only_env(),
        open_read_only(path, name=label) as ds,
        gdal_errors(file=label, path=path),
    ):
        if ds.crs is None:
            raise MeasureError(f"{label}: has no coordinate reference system; cannot place it")
        t = ds.transform
        if t.is_identity or t.determinant == 0:
            raise MeasureError(f"{label}: has no georeference (geotransform)")
        return RasterHeader(
            Path(path),
            label,
            ds.crs,
            t,
            ds.width,
            ds.height,
            _luminance_bands(ds),
            math.sqrt(abs(t.determinant)),
        )


@dataclass
class Reference:
    """The checker's reference: chips of a library, or one orthoimage (``library`` False).

    ``problems`` lists the files that could not be used and why (each message names the file).
    """

    root: Path
    library: bool
    chips: list[RasterHeader]
    problems: list[str] = field(default_factory=list)
    _sha: dict[Path, str] = field(default_factory=dict, repr=False)
    _bounds: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def sha256(self, chip: RasterHeader) -> str:
        if chip.path not in self._sha:
            try:
                self._sha[chip.path] = sha256_file(chip.path)
            except OSError as exc:
                raise MeasureError(
                    f"{chip.name}: cannot read file: {exc.strerror or exc}"
                ) from None
        return self._sha[chip.path]

    def by_name(self, name: str) -> RasterHeader | None:
        want = name.replace("\\", "/")
        for c in self.chips:
            rel = c.path.relative_to(self.root).as_posix() if self.library else c.path.name
            if rel == want or c.path.name == want:
                return c
        return None

    def chip_for(
        self, point_id: str, x: float, y: float, crs: CRS, *, chip: str | None = None
    ) -> RasterHeader | None:
        """The chip of a point: the one the survey names, else ``<point_id>.tif``, else the chip
        that holds the point farthest from its edges (the reference image itself when it holds it)."""
        if chip:
            return self.by_name(chip)
        if self.library:
            for suffix in CHIP_SUFFIXES:
                named = self.by_name(f"{point_id}{suffix}")
                if named is not None:
                    return named
        best, best_d = None, 0.0
        for c in self.chips:
            col, row = _to_pixel(c, x, y, crs)
            d = float(c.edge_distance(np.array([col]), np.array([row]))[0])
            if d > best_d:
                best, best_d = c, d
        return best


def open_reference(path: str | Path) -> Reference:
    """Open the reference (a folder of GeoTIFF chips, or one raster) header by header.

    Raises
    ------
    MeasureError
        when the path does not exist, or holds no raster that can be used (each file's problem named).
    """
    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.rglob("*") if f.suffix.lower() in CHIP_SUFFIXES and f.is_file())
        ref = Reference(p, True, [])
        for f in files:
            label = f"{path}/{f.relative_to(p).as_posix()}"
            try:
                ref.chips.append(read_header(f, name=label))
            except OrthospecError as exc:
                ref.problems.append(str(exc))
        if not ref.chips:
            why = "; ".join(ref.problems) if ref.problems else "no .tif/.tiff file in it"
            raise MeasureError(f"{path}: no usable reference chip: {why}")
        return ref
    if not p.exists():
        raise MeasureError(f"{path}: reference not found")
    return Reference(p.parent, False, [read_header(p, name=str(path))])


_TRANSFORMERS: dict[tuple[str, str], Transformer] = {}


def transform_xy(
    x: np.ndarray | float, y: np.ndarray | float, src: CRS, dst: CRS
) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates from ``src`` to ``dst`` (pyproj, always x/y order); identity when equal."""
    xa, ya = (
        np.atleast_1d(np.asarray(x, dtype=np.float64)),
        np.atleast_1d(np.asarray(y, dtype=np.float64)),
    )
    if src == dst:
        return xa, ya
    from pyproj import Transformer

    key = (src.to_wkt(), dst.to_wkt())
    tr = _TRANSFORMERS.get(key)
    if tr is None:
        tr = _TRANSFORMERS[key] = Transformer.from_crs(src, dst, always_xy=True)
    ox, oy = tr.transform(xa, ya)
    return np.asarray(ox, dtype=np.float64), np.asarray(oy, dtype=np.float64)


def _to_pixel(h: RasterHeader, x: float, y: float, crs: CRS) -> tuple[float, float]:
    tx, ty = transform_xy(x, y, crs, h.crs)
    col, row = ~h.transform * (float(tx[0]), float(ty[0]))
    return float(col), float(row)


@dataclass(frozen=True)
class Pair:
    """A template (the reference on the image grid) and the image's search window around it.

    ``template_origin`` is the image pixel (col, row) of the template's top-left corner; the search
    window starts ``margin`` pixels further up and left. ``problem`` says why no pair could be read
    (then the arrays are None): ``edge`` (the window leaves the image), ``reference`` (the chip
    does not cover enough of the template, with the reason).
    """

    template: np.ndarray | None
    search: np.ndarray | None
    search_valid: np.ndarray | None
    template_origin: tuple[int, int]
    margin: int
    chip_px: int
    #: add to a position measured with the template (columns, rows): the chip's own grid offset
    offset: tuple[float, float] = (0.0, 0.0)
    problem: str = ""
    detail: str = ""


def _same_grid(chip: RasterHeader, image: RasterHeader) -> bool:
    """The chip's pixels are the image's up to a translation (same CRS, size and orientation)."""
    a, b = chip.transform, image.transform
    return (
        chip.crs == image.crs
        and a.b == b.b == a.d == b.d == 0
        and math.isclose(a.a, b.a, rel_tol=1e-9)
        and math.isclose(a.e, b.e, rel_tol=1e-9)
    )


def _reference_on_grid(
    ds: rasterio.io.DatasetReader,
    chip: RasterHeader,
    image: RasterHeader,
    origin: tuple[int, int],
    size: int,
) -> tuple[np.ndarray, tuple[float, float]]:
    """The chip's luminance on ``size`` x ``size`` image pixels from ``origin`` (NaN where the chip
    has no valid pixel to give), and the offset (columns, rows) to add to a position measured
    with it.

    On the image's own grid up to a translation (a chip cut from a reference at the same pixel
    size, the common case), the chip's pixels are taken as they are, at the nearest whole pixel,
    and the fraction is the offset: no interpolation of the reference at all. Otherwise the chip
    is resampled onto the image's grid (offset 0)."""
    from rasterio.warp import reproject, transform_bounds

    dst_transform = image.transform * Affine.translation(*origin)
    out = np.full((len(chip.bands), size, size), np.nan, dtype=np.float64)
    if _same_grid(chip, image):
        u, v = ~chip.transform * (dst_transform.c, dst_transform.f)
        cu, rv = round(u), round(v)
        c0, r0, c1, r1 = max(cu, 0), max(rv, 0), min(cu + size, ds.width), min(rv + size, ds.height)
        if c1 > c0 and r1 > r0:
            src = ds.read(list(chip.bands), window=Window(c0, r0, c1 - c0, r1 - r0), masked=True)
            out[:, r0 - rv : r1 - rv, c0 - cu : c1 - cu] = np.ma.filled(
                src.astype(np.float64), np.nan
            )
        return luminance(out), (float(u - cu), float(v - rv))
    left, top = dst_transform * (0, 0)
    right, bottom = dst_transform * (size, size)
    bounds = (min(left, right), min(top, bottom), max(left, right), max(top, bottom))
    if chip.crs != image.crs:
        bounds = transform_bounds(image.crs, chip.crs, *bounds, densify_pts=21)
    win = ds.window(*bounds)
    pad = _KERNEL_PAD + 1
    c0, r0 = math.floor(win.col_off) - pad, math.floor(win.row_off) - pad
    c1, r1 = math.ceil(win.col_off + win.width) + pad, math.ceil(win.row_off + win.height) + pad
    c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, ds.width), min(r1, ds.height)
    if c1 - c0 < 2 or r1 - r0 < 2:
        return luminance(out), (0.0, 0.0)
    w = Window(c0, r0, c1 - c0, r1 - r0)
    src = ds.read(list(chip.bands), window=w, masked=True)
    arr = np.ma.filled(src.astype(np.float64), np.nan)
    finer = chip.pixel < 0.75 * image.pixel if chip.crs == image.crs else False
    reproject(
        arr,
        out,
        src_transform=ds.window_transform(w),
        src_crs=chip.crs,
        src_nodata=np.nan,
        dst_transform=dst_transform,
        dst_crs=image.crs,
        dst_nodata=np.nan,
        resampling=Resampling.average if finer else Resampling.lanczos,
    )
    return luminance(out), (0.0, 0.0)


def _centred_square(
    valid: np.ndarray, centre: tuple[float, float], largest: int, smallest: int
) -> int:
    """Side of the largest even square of valid pixels centred on ``centre`` (0 when below ``smallest``)."""
    cr, cc = centre
    for side in range(largest - largest % 2, smallest - 1, -2):
        r0, c0 = round(cr - side / 2), round(cc - side / 2)
        if (
            r0 >= 0
            and c0 >= 0
            and r0 + side <= valid.shape[0]
            and c0 + side <= valid.shape[1]
            and bool(valid[r0 : r0 + side, c0 : c0 + side].all())
        ):
            return side
    return 0


def read_pair(
    image_ds: rasterio.io.DatasetReader,
    image: RasterHeader,
    chip_ds: rasterio.io.DatasetReader,
    chip: RasterHeader,
    col: float,
    row: float,
    *,
    chip_px: int,
    search_px: int,
    min_template_px: int,
) -> Pair:
    """Read the template and search window of the point at image pixel (``col``, ``row``).

    The template is ``chip_px`` square around the point, smaller (down to ``min_template_px``)
    when the chip covers less; the search window adds ``search_px`` (plus one pixel for the
    subpixel resampling) on every side. Call inside :func:`orthospec.raster.reading.read_only_env`.
    """
    margin = search_px + 1
    # the reference first: it decides the template's size
    big = chip_px
    origin = (round(col - big / 2), round(row - big / 2))
    with gdal_errors(file=chip.name, path=chip.path):
        ref, offset = _reference_on_grid(chip_ds, chip, image, origin, big)
    valid = np.isfinite(ref)
    side = _centred_square(valid, (row - origin[1], col - origin[0]), big, min_template_px)
    if side == 0:
        got = int(valid.sum())
        what = (
            "does not cover the point"
            if got == 0
            else (f"covers too little around the point (a {min_template_px} px square is needed)")
        )
        return Pair(
            None, None, None, origin, margin, 0, problem="reference", detail=f"{chip.name} {what}"
        )
    t0 = (round(col - side / 2), round(row - side / 2))
    template = ref[
        t0[1] - origin[1] : t0[1] - origin[1] + side, t0[0] - origin[0] : t0[0] - origin[0] + side
    ]
    s0c, s0r, size = t0[0] - margin, t0[1] - margin, side + 2 * margin
    if s0c < 0 or s0r < 0 or s0c + size > image.width or s0r + size > image.height:
        return Pair(template, None, None, t0, margin, side, offset, "edge")
    with gdal_errors(file=image.name, path=image.path):
        data = image_ds.read(list(image.bands), window=Window(s0c, s0r, size, size), masked=True)
    valid = ~np.any(np.ma.getmaskarray(data), axis=0)
    search = luminance(np.ma.getdata(data))
    return Pair(template, search, valid, t0, margin, side, offset)
