"""Opening delivered rasters strictly read-only, and the one boundary for the libraries' errors.

Why this shape:

* a file is opened only by the GDAL driver its first bytes allow (GeoTIFF, JPEG 2000): a GDAL
  VRT (XML that can point at any file or URL) or any other format is refused, and a FIFO, device
  or folder is refused without blocking;
* the header's declared size is checked against :class:`RasterLimits` before a pixel is read;
* GDAL / rasterio / pyogrio / pyproj errors become MeasureError naming the file in one place,
  :func:`gdal_errors` (the table :data:`LIBRARY_ERRORS`);
* the delivery is never written: datasets are opened read-only inside ``rasterio.Env`` with
  ``GDAL_PAM_ENABLED=NO`` so GDAL creates no ``.aux.xml`` next to the file, and
  ``GDAL_CACHEMAX`` is kept small because each block is read once anyway;
* windows are unions of whole internal blocks (``ds.block_shapes``: tiles or strips), so GDAL
  decodes every block once and memory stays bounded whatever the image size.

Validity follows GDAL's ``ComputeStatistics`` (:func:`validity`): a band's nodata value when it
has one (plus NaN for floats); else the per-dataset mask (internal ``.msk``) or alpha band when
the band has one (the alpha band itself is never masked); else every pixel.
"""

from __future__ import annotations

import math
import os
import stat
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import rasterio
from rasterio.enums import ColorInterp, MaskFlags
from rasterio.windows import Window

from ..errors import MeasureError, OrthospecError
from ..limits import env_limit
from ..measures.histogram import GreyRange, grey_range

#: GDAL configuration for the whole process (environment, so worker processes inherit it and
#: every GDAL in the process, rasterio's and pyogrio's, reads it): no network file systems, no
#: raw VRT bands (they open any file of the machine, even read-write).
_SAFE_GDAL = {
    "GDAL_VRT_ENABLE_RAWRASTERBAND": "NO",
    "CPL_VSIL_CURL_ALLOWED_EXTENSIONS": ".orthospec-network-disabled",
    "GDAL_HTTP_MAX_RETRY": "0",
    "GDAL_HTTP_TIMEOUT": "1",
    "GDAL_HTTP_CONNECTTIMEOUT": "1",
    "CPL_VSIL_CURL_USE_HEAD": "NO",
}
os.environ.update(_SAFE_GDAL)

#: First bytes -> the only GDAL driver allowed to open the file.
_MAGIC = (
    (b"II*\x00", "GTiff"),
    (b"MM\x00*", "GTiff"),  # TIFF, COG
    (b"II+\x00", "GTiff"),
    (b"MM\x00+", "GTiff"),  # BigTIFF
    (b"\x00\x00\x00\x0cjP  \r\n\x87\n", "JP2OpenJPEG"),  # JPEG 2000 (JP2)
    (b"\xff\x4f\xff\x51", "JP2OpenJPEG"),  # JPEG 2000 codestream (J2K)
)


@dataclass(frozen=True)
class RasterLimits:
    """Largest raster header accepted, checked before any pixel is read.

    Defaults far above a real orthophoto tile (a 20,000 x 20,000 px, 4-band tile is 0.4 gigapixels):
    ``ORTHOSPEC_MAX_RASTER_PIXELS`` (width x height, default 2**32) and
    ``ORTHOSPEC_MAX_RASTER_BANDS`` (default 64).
    """

    pixels: int = 2**32
    bands: int = 64

    @classmethod
    def from_env(cls) -> RasterLimits:
        d = cls()
        return cls(
            pixels=env_limit("ORTHOSPEC_MAX_RASTER_PIXELS", d.pixels),
            bands=env_limit("ORTHOSPEC_MAX_RASTER_BANDS", d.bands),
        )


def _clean(exc: BaseException, path: str, name: str) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.replace(f"{path}: ", "").replace(path, name)


#: What the raster and vector libraries raise when a file cannot be read (httpx's
#: ``map_exceptions`` is the model): one table, mapped to MeasureError in one place,
#: :func:`gdal_errors`. A module not imported yet cannot have raised, so it is not imported.
LIBRARY_ERRORS: tuple[tuple[str, str], ...] = (
    ("rasterio.errors", "RasterioError"),  # RasterioIOError, WindowError, ...
    ("rasterio.errors", "CRSError"),  # a ValueError in rasterio
    ("rasterio.errors", "DriverRegistrationError"),  # a ValueError in rasterio
    ("rasterio._err", "CPLE_BaseError"),  # GDAL's CPLE_* errors, raised by rasterio
    ("pyogrio.errors", "DataSourceError"),
    ("pyogrio.errors", "DataLayerError"),  # CRSError, FeatureError, FieldError, GeometryError
    ("pyproj.exceptions", "ProjError"),  # CRSError
)


def library_errors() -> tuple[type[BaseException], ...]:
    """The exception classes of :data:`LIBRARY_ERRORS` whose modules are loaded."""
    out = []
    for module, name in LIBRARY_ERRORS:
        cls = getattr(sys.modules.get(module), name, None)
        if isinstance(cls, type) and issubclass(cls, BaseException):
            out.append(cls)
    return tuple(out)


@contextmanager
def gdal_errors(
    *, file: str | Path, path: str | Path | None = None, what: str = "raster"
) -> Iterator[None]:
    """The one boundary where rasterio / GDAL / pyogrio / pyproj errors become MeasureError
    naming the file.

    ``file`` is what the message shows (relative to the delivery when known); ``path`` the path
    GDAL was given, removed from GDAL's text so messages do not depend on the working folder.
    Anything else (our own errors, bugs) passes through unchanged.
    """
    try:
        yield
    except OrthospecError:
        raise
    except library_errors() as exc:
        raise MeasureError(
            f"{file}: not a readable {what}: {_clean(exc, str(path or file), str(file))}"
        ) from exc


def _nonblocking(path: str, flags: int) -> int:
    return os.open(path, flags | getattr(os, "O_NONBLOCK", 0))


def _head(path: str | Path, name: str, n: int = 16) -> bytes:
    """First bytes of a regular file; a FIFO, device or folder is refused without blocking."""
    try:
        with open(path, "rb", opener=_nonblocking) as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise MeasureError(f"{name}: not a regular file")
            return fh.read(n)
    except FileNotFoundError:
        raise MeasureError(f"{name}: file not found") from None
    except OSError as exc:
        raise MeasureError(f"{name}: cannot read file: {exc.strerror or exc}") from None


def raster_driver(path: str | Path, name: str | None = None) -> str:
    """The GDAL driver allowed for this file by its first bytes (GTiff or JP2OpenJPEG).

    Raises
    ------
    MeasureError
        for anything else: a GDAL VRT (XML that can point at any file or URL), PNG, JPEG...
    """
    label = name or str(path)
    head = _head(path, label)
    for magic, driver in _MAGIC:
        if head.startswith(magic):
            return driver
    kind = " (XML: a GDAL VRT?)" if head.lstrip().startswith(b"<") else ""
    raise MeasureError(
        f"{label}: not a readable raster: not a GeoTIFF or JPEG 2000 file{kind}; other "
        "formats and VRTs are not read"
    )


def check_declared_size(
    ds: rasterio.io.DatasetReader, name: str, limits: RasterLimits | None = None
) -> None:
    """Refuse a raster whose header declares more pixels or bands than the limits (before
    reading)."""
    lim = limits or RasterLimits.from_env()
    if ds.count > lim.bands:
        raise MeasureError(
            f"{name}: declares {ds.count:,} bands, more than the limit of {lim.bands} "
            "(ORTHOSPEC_MAX_RASTER_BANDS); not read"
        )
    if ds.width * ds.height > lim.pixels:
        raise MeasureError(
            f"{name}: declares {ds.width:,} x {ds.height:,} = {ds.width * ds.height:,} pixels, "
            f"more than the limit of {lim.pixels:,} (ORTHOSPEC_MAX_RASTER_PIXELS); not read"
        )


#: GDAL's block cache while a raster is read (MB): each block is decoded once anyway.
GDAL_CACHEMAX_MB = 32


class CacheSetting(Protocol):
    """Settings that size GDAL's block cache (raster/stats.py ScanSettings is one)."""

    @property
    def gdal_cachemax_mb(self) -> int: ...


@contextmanager
def read_only_env(settings: CacheSetting | None = None) -> Iterator[None]:
    """GDAL configuration that writes nothing next to the input and caches little.

    ``GTIFF_DIRECT_IO`` and ``GTIFF_VIRTUAL_MEM_IO`` are forced off, even when the user's
    environment sets them: direct I/O saves about 15 % of a scan's read CPU on uncompressed
    files, but GDAL 3.10 then returns zeros, without an error, for the missing strips of a
    truncated striped file (``test_truncated_file_raises_measure_error``).
    """
    with rasterio.Env(
        GDAL_PAM_ENABLED="NO",
        GDAL_CACHEMAX=GDAL_CACHEMAX_MB if settings is None else settings.gdal_cachemax_mb,
        GDAL_DISABLE_READDIR_ON_OPEN="EMPTY_DIR",
        GTIFF_DIRECT_IO="NO",
        GTIFF_VIRTUAL_MEM_IO="NO",
        **_SAFE_GDAL,
    ):
        yield


def open_read_only(
    path: str | Path, *, name: str | None = None, limits: RasterLimits | None = None
) -> rasterio.io.DatasetReader:
    """Open a delivered raster strictly read-only (call inside :func:`read_only_env`).

    Only a regular TIFF/BigTIFF or JPEG 2000 file, with that driver alone; the declared size is
    checked against ``limits`` before anything else reads it.

    Raises
    ------
    MeasureError
        naming ``name`` (default the path) when the file is refused or GDAL cannot open it.
    """
    label = name or str(path)
    driver = raster_driver(path, label)
    with gdal_errors(file=label, path=path):
        ds = rasterio.open(path, "r", driver=driver)
    try:
        check_declared_size(ds, label, limits)
    except MeasureError:
        ds.close()
        raise
    return ds


def chunk_windows(ds: rasterio.io.DatasetReader, chunk_bytes: int) -> Iterator[Window]:
    """Windows made of whole internal blocks, each about ``chunk_bytes`` of all bands."""
    bh, bw = ds.block_shapes[0]
    height, width = ds.height, ds.width
    bpp = ds.count * max(np.dtype(dt).itemsize for dt in ds.dtypes)
    row_bytes = width * bpp
    if bh * bw * bpp > 4 * chunk_bytes:
        # one internal block is huge (untiled JPEG2000, single-strip TIFF): memory first,
        # read full-width bands of rows instead (the driver decodes sub-windows)
        step = max(1, chunk_bytes // max(row_bytes, 1))
        for row in range(0, height, step):
            yield Window(0, row, width, min(step, height - row))
        return
    if bw >= width or row_bytes * bh <= chunk_bytes:
        per = max(1, chunk_bytes // max(row_bytes * bh, 1))  # whole rows of blocks
        step = per * bh
        for row in range(0, height, step):
            yield Window(0, row, width, min(step, height - row))
        return
    tiles = max(1, chunk_bytes // max(bh * bw * bpp, 1))  # part of one row of tiles
    step_c = tiles * bw
    for row in range(0, height, bh):
        h = min(bh, height - row)
        for col in range(0, width, step_c):
            yield Window(col, row, min(step_c, width - col), h)


@dataclass(frozen=True)
class BandInfo:
    """How one band's pixels are validated and which grey range applies."""

    index: int
    dtype: str
    nodata: float | None
    use_mask: bool
    colour: str
    grey: GreyRange


def band_infos(ds: rasterio.io.DatasetReader, bit_depth: int | None) -> list[BandInfo]:
    """Per-band validity rule (GDAL's) and bit depth (argument > NBITS > dtype)."""
    out = []
    for i in range(1, ds.count + 1):
        dtype = ds.dtypes[i - 1]
        nodata = ds.nodatavals[i - 1]
        flags = ds.mask_flag_enums[i - 1]
        colour = ds.colorinterp[i - 1]
        use_mask = (
            nodata is None
            and colour != ColorInterp.alpha
            and (MaskFlags.per_dataset in flags or MaskFlags.alpha in flags)
            and (MaskFlags.all_valid not in flags)
        )
        nbits_tag = ds.tags(i, ns="IMAGE_STRUCTURE").get("NBITS") or ds.tags(
            ns="IMAGE_STRUCTURE"
        ).get("NBITS")
        nbits = int(nbits_tag) if nbits_tag else None
        if nodata is not None and np.dtype(dtype).kind in "ui":
            nodata = float(nodata)
        out.append(
            BandInfo(
                index=i,
                dtype=dtype,
                nodata=nodata,
                use_mask=use_mask,
                colour=colour.name,
                grey=grey_range(dtype, declared=bit_depth, nbits=nbits),
            )
        )
    return out


def validity(data: np.ndarray, info: BandInfo, mask: np.ndarray | None) -> np.ndarray | None:
    """Validity of one band's block: None means all pixels are valid."""
    valid = None
    if info.use_mask and mask is not None:
        valid = mask != 0
    if np.dtype(info.dtype).kind == "f":
        finite = np.isfinite(data)  # NaN and +/-Inf: never a value (counted by _nonfinite)
        valid = finite if valid is None else valid & finite
    if info.nodata is not None and not (isinstance(info.nodata, float) and math.isnan(info.nodata)):
        if data.dtype.kind in "ui":
            lim = np.iinfo(data.dtype)
            if not (lim.min <= info.nodata <= lim.max and info.nodata == int(info.nodata)):
                return valid  # a nodata value the band cannot hold excludes nothing
        nd = np.asarray(info.nodata).astype(data.dtype)
        v = data != nd
        valid = v if valid is None else valid & v
    return valid
