"""File-level checks of delivered images (JRC EUR 23638 EN §3.1-3.2, §6.4-6.5, §9.2).

Everything here reads only headers and tags, never pixels (except the nodata share, which
comes from the radiometry scan). A file that cannot be opened, has no georeference or an
unparseable CRS yields a :class:`FileChecks` with ``error`` set, never an exception, so a
national batch never stops on one bad file.
"""

from __future__ import annotations

import math
import re
import stat
import warnings
from collections import Counter
from collections.abc import Iterable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path, PurePath
from typing import Any

import numpy as np
import rasterio

from ..errors import MeasureError
from .reading import ScanSettings, gdal_errors, open_read_only, read_only_env, readable_vector

#: Compression names (GDAL ``COMPRESSION`` tag / driver) that are always lossless.
LOSSLESS = {"NONE", "LZW", "DEFLATE", "ZSTD", "PACKBITS", "LZMA", "CCITTRLE", "CCITTFAX3",
            "CCITTFAX4", "ADOBE_DEFLATE", "LERC_ZERO"}
#: Compression names that are always lossy (unless GDAL reports COMPRESSION_REVERSIBILITY).
LOSSY = {"JPEG", "OJPEG", "JXL_LOSSY", "ECW", "MRSID"}

_WINDOWS_FORBIDDEN = re.compile(r'[<>:"/\\|?*\x00-\x1f]')
_WINDOWS_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)),
                     *(f"LPT{i}" for i in range(1, 10))}


@dataclass(frozen=True)
class NameCheck:
    """JRC §6.4 file naming: Windows convention, no spaces, a name plus an extension."""

    name: str
    ok: bool
    problems: tuple[str, ...]


def check_name(name: str) -> NameCheck:
    """Check one file name (not a path) against the Windows naming convention of §6.4."""
    problems = []
    if " " in name:
        problems.append("contains spaces")
    bad = sorted(set(_WINDOWS_FORBIDDEN.findall(name)))
    if bad:
        problems.append("characters not allowed on Windows: " + " ".join(repr(c) for c in bad))
    stem, dot, ext = name.rpartition(".")
    if not dot or not stem or not ext:
        problems.append("no name plus extension (e.g. photo_nr.tif)")
    if name.endswith((".", " ")):
        problems.append("ends with a dot or space")
    if (stem or name).split(".")[0].upper() in _WINDOWS_RESERVED:
        problems.append("reserved Windows device name")
    if len(name) > 255:
        problems.append("longer than 255 characters")
    return NameCheck(name=name, ok=not problems, problems=tuple(problems))


@dataclass(frozen=True)
class ListingCheck:
    """Listing consistency: the images table's files vs the files on disk, both ways."""

    listed_missing: tuple[str, ...]   # listed in the table, not on disk
    unlisted: tuple[str, ...]         # on disk, not in the table
    duplicates: tuple[str, ...]       # listed more than once
    case_mismatch: tuple[tuple[str, str], ...]  # same name up to case (Windows would merge them)

    @property
    def ok(self) -> bool:
        return not (self.listed_missing or self.unlisted or self.duplicates or self.case_mismatch)


def listing_consistency(listed: Iterable[str], on_disk: Iterable[str]) -> ListingCheck:
    """Compare the file names of an images table with the files found (pure, names only)."""
    listed_l = [PurePath(str(n).replace("\\", "/")).as_posix() for n in listed]
    disk_l = [PurePath(str(n).replace("\\", "/")).as_posix() for n in on_disk]
    counts = Counter(listed_l)
    dup = tuple(sorted(n for n, c in counts.items() if c > 1))
    ls, ds = set(listed_l), set(disk_l)
    missing = ls - ds
    unlisted = ds - ls
    lower_disk = {n.lower(): n for n in unlisted}
    case = tuple(sorted((n, lower_disk[n.lower()]) for n in missing if n.lower() in lower_disk))
    case_names = {a for a, _ in case} | {b for _, b in case}
    return ListingCheck(listed_missing=tuple(sorted(missing - case_names)),
                        unlisted=tuple(sorted(unlisted - case_names)), duplicates=dup,
                        case_mismatch=case)


@dataclass(frozen=True)
class FileChecks:
    """Header-level facts and checks of one image file; ``error`` set when it is unusable."""

    path: str
    bytes: int | None = None
    error: str | None = None
    driver: str | None = None
    compression: str | None = None
    lossless: bool | None = None
    layout: str | None = None          # "tiled" | "striped"
    block_width: int | None = None
    block_height: int | None = None
    width: int | None = None
    height: int | None = None
    band_count: int | None = None
    dtypes: tuple[str, ...] = ()
    bit_depth_container: int | None = None
    nbits: int | None = None
    bit_depth_ok: bool | None = None         # >= 8 bits (§3.2)
    bit_depth_recommended: bool | None = None  # >= 11 bits (§3.2: "11-12 bits highly recommended")
    colour_interpretation: tuple[str, ...] = ()
    crs: str | None = None
    epsg: int | None = None
    crs_ok: bool | None = None
    pixel_size_x: float | None = None
    pixel_size_y: float | None = None
    pixel_size_unit: str | None = None
    gsd_ok: bool | None = None
    rotated: bool | None = None
    nodata: tuple[float | None, ...] = ()
    nodata_declared: bool | None = None
    has_internal_mask: bool | None = None
    has_overviews: bool | None = None
    name_ok: bool | None = None
    name_problems: tuple[str, ...] = field(default=())
    stored_statistics: bool | None = None  # STATISTICS_* tags present (never trusted)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d


def _nbits(ds: rasterio.io.DatasetReader) -> int | None:
    tag = ds.tags(1, ns="IMAGE_STRUCTURE").get("NBITS") or ds.tags(ns="IMAGE_STRUCTURE").get(
        "NBITS")
    return int(tag) if tag else None


def _compression(ds: rasterio.io.DatasetReader) -> tuple[str, bool | None]:
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
        return name, None if err is None else float(err) == 0.0
    return name, None


def check_file(path: str | Path, *, expect_epsg: int | None = None,
               expect_gsd: float | None = None, gsd_tolerance: float = 0.01,
               min_bits: int = 8, recommended_bits: int = 11) -> FileChecks:
    """Header checks of one image; never raises for a bad file (``error`` says why).

    ``expect_gsd`` is in the CRS's linear unit (metres for projected EPSG codes);
    ``gsd_tolerance`` is relative (0.01 = pixel size within 1 % of the specified GSD).
    """
    with checked_file(path, expect_epsg=expect_epsg, expect_gsd=expect_gsd,
                      gsd_tolerance=gsd_tolerance, min_bits=min_bits,
                      recommended_bits=recommended_bits) as (checks, _ds):
        return checks


@contextmanager
def checked_file(path: str | Path, *, expect_epsg: int | None = None,
                 expect_gsd: float | None = None, gsd_tolerance: float = 0.01,
                 min_bits: int = 8, recommended_bits: int = 11,
                 settings: ScanSettings | None = None,
                 ) -> Iterator[tuple[FileChecks, rasterio.io.DatasetReader | None]]:
    """:func:`check_file`, keeping the dataset open (read-only) for a pixel scan.

    Yields the checks and the open dataset, or None when it could not be opened: one open and
    one GDAL environment per image instead of two (about 3 ms of a tiny image's budget).
    A missing georeference is reported in ``error``, never printed as a warning.
    """
    p = Path(path)
    name = check_name(p.name)
    base: dict[str, Any] = {"path": str(p), "name_ok": name.ok, "name_problems": name.problems}
    try:
        st = p.stat()
    except OSError as exc:
        yield FileChecks(error=f"{p}: cannot stat file: {exc.strerror or exc}", **base), None
        return
    if not stat.S_ISREG(st.st_mode):  # a FIFO or device would block or never end
        yield FileChecks(error=f"{p}: not a regular file", **base), None
        return
    base["bytes"] = st.st_size
    if st.st_size == 0:
        yield FileChecks(error=f"{p}: zero-size file", **base), None
        return
    with ExitStack() as stack, warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        ds = None
        try:
            stack.enter_context(read_only_env(settings))
            ds = stack.enter_context(open_read_only(p))
            with gdal_errors(file=p, what="raster header"):
                checks = _check_open(ds, base, expect_epsg=expect_epsg, expect_gsd=expect_gsd,
                                     gsd_tolerance=gsd_tolerance, min_bits=min_bits,
                                     recommended_bits=recommended_bits)
        except MeasureError as exc:  # refused (format, declared size) or GDAL could not read it
            checks = FileChecks(error=str(exc), **base)
        yield checks, ds


def _check_open(ds: rasterio.io.DatasetReader, base: dict[str, Any], *, expect_epsg: int | None,
                expect_gsd: float | None, gsd_tolerance: float, min_bits: int,
                recommended_bits: int) -> FileChecks:
    p = base["path"]
    comp, lossless = _compression(ds)
    bh, bw = ds.block_shapes[0]
    layout = "striped" if bw >= ds.width and ds.driver == "GTiff" else (
        "tiled" if bw < ds.width or bh < ds.height else "single-block")
    dtypes = tuple(ds.dtypes)
    dt = np.dtype(dtypes[0])
    container = 8 * dt.itemsize if dt.kind in "uib" else None
    nbits = _nbits(ds)
    depth = nbits or container
    facts: dict[str, Any] = dict(
        driver=ds.driver, compression=comp, lossless=lossless, layout=layout,
        block_width=int(bw), block_height=int(bh), width=ds.width, height=ds.height,
        band_count=ds.count, dtypes=dtypes, bit_depth_container=container, nbits=nbits,
        bit_depth_ok=None if depth is None else depth >= min_bits,
        bit_depth_recommended=None if depth is None else depth >= recommended_bits,
        colour_interpretation=tuple(c.name for c in ds.colorinterp),
        nodata=tuple(None if v is None else float(v) for v in ds.nodatavals),
        nodata_declared=any(v is not None for v in ds.nodatavals),
        has_internal_mask=any(f.name == "per_dataset" for f in ds.mask_flag_enums[0]),
        has_overviews=bool(ds.overviews(1)),
        stored_statistics=any(k.startswith("STATISTICS_") for k in ds.tags(1)),
    )
    if ds.crs is None:
        return FileChecks(error=f"{p}: no georeference (no CRS)", **base, **facts)
    if ds.transform.is_identity and not ds.gcps[0] and ds.driver != "JP2OpenJPEG":
        return FileChecks(error=f"{p}: no georeference (identity geotransform)", **base,
                          **facts)
    try:
        with gdal_errors(file=p, what="CRS"):
            crs_text, epsg, unit, crs_ok = _crs_facts(ds.crs.to_wkt(), expect_epsg)
    except MeasureError as exc:  # rasterio's or pyproj's CRSError, mapped by the one boundary
        return FileChecks(error=f"{p}: unparseable CRS: {exc}", **base, **facts)
    t = ds.transform
    px, py = math.hypot(t.a, t.d), math.hypot(t.b, t.e)
    gsd_ok = None
    if expect_gsd is not None:
        gsd_ok = all(abs(v - expect_gsd) <= gsd_tolerance * expect_gsd for v in (px, py))
    return FileChecks(crs=crs_text, epsg=epsg, crs_ok=crs_ok, pixel_size_x=px,
                      pixel_size_y=py, pixel_size_unit=unit, gsd_ok=gsd_ok,
                      rotated=bool(t.b or t.d), **base, **facts)


@lru_cache(maxsize=64)
def _crs_facts(wkt: str, expect_epsg: int | None) -> tuple[str, int | None, str | None, bool | None]:
    """(name, EPSG code, axis unit, equals the expected EPSG) of a CRS; parsed once per WKT, since
    every image of a delivery shares one CRS.

    Name, code and unit come from GDAL (rasterio, already loaded); pyproj, whose import alone
    costs about 0.1 s of ``measure radiometry``, is imported only to compare with an expected
    EPSG code (axis order ignored, as GIS software does).
    """
    crs = rasterio.crs.CRS.from_wkt(wkt)
    ok = None
    if expect_epsg is not None:
        from pyproj import CRS

        ok = CRS.from_user_input(wkt).equals(CRS.from_epsg(int(expect_epsg)), ignore_axis_order=True)
    try:
        unit: str | None = crs.units_factor[0]
    except rasterio.errors.CRSError:  # no unit GDAL can name (e.g. an engineering CRS)
        unit = None
    return crs.to_string(), crs.to_epsg(), unit, ok


@dataclass(frozen=True)
class VectorCheck:
    """A delivered vector file (seamlines, tiles; JRC §11): present, readable, what it holds."""

    path: str
    error: str | None = None
    features: int | None = None
    geometry_type: str | None = None
    crs: str | None = None
    crs_ok: bool | None = None
    fields: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["fields"] = list(self.fields)
        return d


def check_vector(path: str | Path, *, expect_epsg: int | None = None) -> VectorCheck:
    """Open a seamline/tile vector file with pyogrio; ``error`` set when absent or unreadable."""
    import pyogrio

    p = Path(path)
    if not p.exists():
        return VectorCheck(path=str(p), error=f"{p}: file not found")
    try:
        with readable_vector(p) as (local, _driver), gdal_errors(file=p, path=local, what="vector file"):
            info = pyogrio.read_info(local)
    except MeasureError as exc:
        return VectorCheck(path=str(p), error=str(exc))
    crs_text = info.get("crs")
    crs_ok = None
    if expect_epsg is not None:
        if crs_text is None:
            crs_ok = False
        else:
            from pyproj import CRS

            try:
                with gdal_errors(file=p, what="CRS"):
                    crs_ok = CRS.from_user_input(crs_text).equals(CRS.from_epsg(int(expect_epsg)),
                                                                  ignore_axis_order=True)
            except MeasureError:  # pyproj's CRSError, mapped by the one boundary: not equal
                crs_ok = False
    return VectorCheck(path=str(p), features=int(info.get("features", 0)),
                       geometry_type=info.get("geometry_type"), crs=crs_text, crs_ok=crs_ok,
                       fields=tuple(str(f) for f in info.get("fields", ())))
