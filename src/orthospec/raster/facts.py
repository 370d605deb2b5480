"""The one reading of an image's facts from its file (issue 25: measured, not declared).

A delivery's tables *declare* pixel size, bands, bit depth, location; the file *is* those facts.
:func:`read_facts` reads them once, from the header, with rasterio (through
:func:`~orthospec.raster.reading.open_read_only`: driver allow-list, declared-size limits, no
``.aux.xml`` written, network off) and returns a frozen :class:`RasterFacts`. Two callers, one
function: the checks (``raster/filechecks.py`` builds its :class:`FileChecks` from these facts,
and the scan keeps them per image) and ``orthospec init --from`` (the tables written from a folder
of files).

It never raises for a bad file: ``error`` says why the file could not be read (absent, not a
regular file, empty, refused format, GDAL error). A readable file without a usable georeference
keeps every other fact; ``georeference`` then says what is wrong (no CRS, identity geotransform,
unparseable CRS) and the footprint facts (``transform``, ``pixel_size``, ``bounds``) are None.

Facts of the pixels themselves (the decoded-pixel content hash, the thumbnail signature) come from
the one pixel scan (``raster/reading.py``), not from here: reading the header is cheap, reading
the pixels is done once per check.
"""

from __future__ import annotations

import math
import stat
import warnings
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import rasterio

from ..errors import MeasureError
from .reading import gdal_errors, open_read_only, read_only_env

if TYPE_CHECKING:
    from .reading import ScanSettings

#: Compression names (GDAL ``COMPRESSION`` tag / driver) that are always lossless.
LOSSLESS = {"NONE", "LZW", "DEFLATE", "ZSTD", "PACKBITS", "LZMA", "CCITTRLE", "CCITTFAX3",
            "CCITTFAX4", "ADOBE_DEFLATE", "LERC_ZERO"}
#: Compression names that are always lossy (unless GDAL reports COMPRESSION_REVERSIBILITY).
LOSSY = {"JPEG", "OJPEG", "JXL_LOSSY", "ECW", "MRSID"}

#: GDAL's stored statistics tags (``gdalinfo -stats`` writes them), per band, under our names
STAT_TAGS = {"STATISTICS_MINIMUM": "min", "STATISTICS_MAXIMUM": "max", "STATISTICS_MEAN": "mean",
             "STATISTICS_STDDEV": "std"}

Bounds = tuple[float, float, float, float]


@dataclass(frozen=True)
class RasterFacts:
    """What one image file says about itself, from its header (nothing declared, nothing judged).

    Fields are never renamed (``init --from`` and the checks read them); new ones may be added.
    Lengths are in the unit of the file's CRS (``pixel_unit``; ``unit_metres`` converts to metres).
    """

    path: str
    bytes: int | None = None
    #: why the file could not be read at all (None: readable)
    error: str | None = None
    driver: str | None = None
    width: int | None = None
    height: int | None = None
    count: int | None = None
    dtypes: tuple[str, ...] = ()
    #: bits per sample: NBITS when the file states it, else the integer container (8, 16, 32);
    #: None for floating-point samples
    bit_depth: int | None = None
    #: the NBITS tag alone (None when absent)
    nbits: int | None = None
    #: bits of the integer sample type (None for floats)
    bit_depth_container: int | None = None
    colorinterp: tuple[str, ...] = ()
    nodata: tuple[float | None, ...] = ()
    #: a per-dataset mask (internal ``.msk``) marks the valid pixels
    internal_mask: bool | None = None
    #: why the file has no usable georeference (None: it has one)
    georeference: str | None = None
    crs_wkt: str | None = None
    #: GDAL's short name of the CRS (``EPSG:25832``) or its WKT when it has none
    crs_name: str | None = None
    epsg: int | None = None
    #: the affine geotransform a, b, c, d, e, f (x = a*col + b*row + c, y = d*col + e*row + f)
    transform: tuple[float, float, float, float, float, float] | None = None
    #: pixel size (x, y) in CRS units, positive, from the transform (rotation included)
    pixel_size: tuple[float, float] | None = None
    pixel_unit: str | None = None
    #: metres per CRS unit (None when the CRS is not projected in a length unit)
    unit_metres: float | None = None
    rotated: bool | None = None
    #: left, bottom, right, top in the file's CRS (the envelope when rotated)
    bounds: Bounds | None = None
    compression: str | None = None
    lossless: bool | None = None
    tiled: bool | None = None
    #: "tiled" | "striped" | "single-block"
    layout: str | None = None
    #: internal block (rows, cols) of band 1
    block_shape: tuple[int, int] | None = None
    #: overview decimation factors of band 1
    overviews: tuple[int, ...] = ()
    #: per band, the statistics the file stores (GDAL ``STATISTICS_*`` tags: min, max, mean, std)
    #: or None; never trusted, compared with the scan's
    stats: tuple[dict[str, float] | None, ...] = ()
    sha256: str | None = None

    @property
    def readable(self) -> bool:
        return self.error is None

    @property
    def georeferenced(self) -> bool:
        return self.error is None and self.georeference is None and self.transform is not None

    @property
    def pixel_size_m(self) -> tuple[float, float] | None:
        """Pixel size in metres, when the CRS has a length unit."""
        if self.pixel_size is None or self.unit_metres is None:
            return None
        return (self.pixel_size[0] * self.unit_metres, self.pixel_size[1] * self.unit_metres)

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly: tuples become lists (shallow: one per image of a national scan)."""
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = [list(x) if isinstance(x, tuple) else (dict(x) if isinstance(x, dict) else x) for x in v]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> RasterFacts:
        """Inverse of :meth:`to_dict` (facts that crossed a process or the result cache)."""
        kw: dict[str, Any] = {}
        for k in cls.__dataclass_fields__:
            if k not in d:
                continue
            v = d[k]
            if isinstance(v, list):
                v = tuple(tuple(x) if isinstance(x, list) else x for x in v)
            kw[k] = v
        return cls(**kw)


def _nbits(ds: rasterio.io.DatasetReader) -> int | None:
    tag = ds.tags(1, ns="IMAGE_STRUCTURE").get("NBITS") or ds.tags(ns="IMAGE_STRUCTURE").get(
        "NBITS"
    )
    try:
        return int(tag) if tag else None
    except ValueError:  # a malformed tag states nothing
        return None


def compression_of(ds: rasterio.io.DatasetReader) -> tuple[str, bool | None]:
    """(compression name, lossless) of an open dataset; lossless None when the file does not tell."""
    ims = ds.tags(ns="IMAGE_STRUCTURE")
    name = ims.get("COMPRESSION")
    if name is None:
        if ds.driver.startswith("JP2"):
            name = "JPEG2000"
        elif ds.driver in ("ECW", "MrSID", "JPEG", "WEBP"):
            name = ds.driver.upper()
        else:
            name = "NONE"
    name = name.upper()
    rev = ims.get("COMPRESSION_REVERSIBILITY", "").upper()
    if rev in ("LOSSLESS", "LOSSY"):
        return name, rev == "LOSSLESS"
    if name in LOSSLESS:
        return name, True
    if name in LOSSY:
        return name, False
    if name == "JPEG2000":
        return name, None  # reversibility not reported by the driver
    if name == "LERC":
        err = ims.get("MAX_Z_ERROR")
        try:
            return name, None if err is None else float(err) == 0.0
        except ValueError:
            return name, None
    return name, None


def _stats(ds: rasterio.io.DatasetReader) -> tuple[dict[str, float] | None, ...]:
    out: list[dict[str, float] | None] = []
    first = ds.tags(1) if ds.count else {}
    if not any(k in first for k in STAT_TAGS):  # GDAL writes them for every band or for none
        return (None,) * ds.count
    for i in range(1, ds.count + 1):
        tags = first if i == 1 else ds.tags(i)
        got = {}
        for tag, key in STAT_TAGS.items():
            if tag in tags:
                try:
                    got[key] = float(tags[tag])
                except ValueError:
                    continue
        out.append(got or None)
    return tuple(out)


@lru_cache(maxsize=64)
def crs_facts(wkt: str) -> tuple[str, int | None, str | None, float | None]:
    """(name, EPSG code, linear unit name, metres per unit) of a CRS; parsed once per WKT, since
    every image of a delivery shares one CRS. From GDAL (rasterio, already loaded), not pyproj."""
    crs = rasterio.crs.CRS.from_wkt(wkt)
    unit: str | None
    try:
        unit = crs.units_factor[0]
    except rasterio.errors.CRSError:  # no unit GDAL can name (e.g. an engineering CRS)
        unit = None
    metres = None
    if crs.is_projected:
        try:
            metres = float(crs.linear_units_factor[1])
        except rasterio.errors.CRSError:
            metres = None
    return crs.to_string(), crs.to_epsg(), unit, metres


def facts_of_dataset(
    ds: rasterio.io.DatasetReader, *, path: str, size: int | None = None
) -> RasterFacts:
    """The facts of a dataset opened with :func:`~orthospec.raster.reading.open_read_only`.

    Raises
    ------
    MeasureError
        when GDAL cannot read the header (mapped by :func:`gdal_errors`); callers keep it as
        ``error``.
    """
    with gdal_errors(file=path, what="raster header"):
        comp, lossless = compression_of(ds)
        bh, bw = ds.block_shapes[0]
        layout = (
            "striped"
            if bw >= ds.width and ds.driver == "GTiff"
            else ("tiled" if bw < ds.width or bh < ds.height else "single-block")
        )
        dtypes = tuple(ds.dtypes)
        dt = np.dtype(dtypes[0])
        container = 8 * dt.itemsize if dt.kind in "uib" else None
        nbits = _nbits(ds)
        base: dict[str, Any] = dict(
            path=path,
            bytes=size,
            driver=ds.driver,
            width=ds.width,
            height=ds.height,
            count=ds.count,
            dtypes=dtypes,
            bit_depth=nbits or container,
            nbits=nbits,
            bit_depth_container=container,
            colorinterp=tuple(c.name for c in ds.colorinterp),
            nodata=tuple(None if v is None else float(v) for v in ds.nodatavals),
            internal_mask=any(f.name == "per_dataset" for f in ds.mask_flag_enums[0]),
            compression=comp,
            lossless=lossless,
            tiled=layout == "tiled",
            layout=layout,
            block_shape=(int(bh), int(bw)),
            overviews=tuple(int(f) for f in ds.overviews(1)),
            stats=_stats(ds),
        )
        if ds.crs is None:
            return RasterFacts(georeference="no georeference (no CRS)", **base)
        if ds.transform.is_identity and not ds.gcps[0] and ds.driver != "JP2OpenJPEG":
            return RasterFacts(georeference="no georeference (identity geotransform)", **base)
        wkt = ds.crs.to_wkt()
    try:
        with gdal_errors(file=path, what="CRS"):
            name, epsg, unit, metres = crs_facts(wkt)
    except MeasureError as exc:  # rasterio's or pyproj's CRSError, mapped by the one boundary
        return RasterFacts(georeference=f"unparseable CRS: {exc}", **base)
    t = ds.transform
    b = ds.bounds
    return RasterFacts(
        crs_wkt=wkt,
        crs_name=name,
        epsg=epsg,
        pixel_unit=unit,
        unit_metres=metres,
        transform=(t.a, t.b, t.c, t.d, t.e, t.f),
        pixel_size=(math.hypot(t.a, t.d), math.hypot(t.b, t.e)),
        rotated=bool(t.b or t.d),
        bounds=(float(b.left), float(b.bottom), float(b.right), float(b.top)),
        **base,
    )


@contextmanager
def opened_facts(
    path: str | Path,
    *,
    settings: ScanSettings | None = None,
    name: str | None = None,
) -> Iterator[tuple[RasterFacts, rasterio.io.DatasetReader | None]]:
    """:func:`read_facts` without the hash, keeping the dataset open (read-only) for a pixel scan.

    Yields the facts and the open dataset, or None when it could not be opened: one open and one
    GDAL environment per image (the checks and the scan share it). ``name`` is what messages call
    the file (default the path).
    """
    p = Path(path)
    label = name or str(p)
    try:
        st = p.stat()
    except OSError as exc:
        yield (
            RasterFacts(path=label, error=f"{label}: cannot stat file: {exc.strerror or exc}"),
            None,
        )
        return
    if not stat.S_ISREG(st.st_mode):  # a FIFO or device would block or never end
        yield RasterFacts(path=label, error=f"{label}: not a regular file"), None
        return
    if st.st_size == 0:
        yield RasterFacts(path=label, bytes=0, error=f"{label}: zero-size file"), None
        return
    with ExitStack() as stack, warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        ds = None
        try:
            stack.enter_context(read_only_env(settings))
            ds = stack.enter_context(open_read_only(p, name=label))
            facts = facts_of_dataset(ds, path=label, size=st.st_size)
        except MeasureError as exc:  # refused (format, declared size) or GDAL could not read it
            facts = RasterFacts(path=label, bytes=st.st_size, error=str(exc))
        yield facts, ds


def read_facts(path: str | Path, *, sha256: bool = True, name: str | None = None) -> RasterFacts:
    """Read one image's facts from its header (and its SHA-256 unless ``sha256=False``).

    Never raises for a bad file: ``error`` says why it could not be read; ``georeference`` why a
    readable file has no usable georeference.

    Parameters
    ----------
    path
        the image file (GeoTIFF/COG or JPEG 2000; anything else is refused as ``error``).
    sha256
        also hash the file's bytes (a full read of the file; off for header-only listings).
    name
        what messages and ``path`` call the file (e.g. relative to a delivery); default the path.

    Returns
    -------
    RasterFacts
    """
    with opened_facts(path, name=name) as (facts, _ds):
        pass
    if sha256 and facts.bytes:
        from ..provenance import sha256_file

        try:
            facts = replace(facts, sha256=sha256_file(path))
        except OSError as exc:
            facts = replace(
                facts, error=facts.error or f"{facts.path}: cannot read file: {exc.strerror or exc}"
            )
    return facts
