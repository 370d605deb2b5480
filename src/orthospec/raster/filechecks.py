"""File-level checks of delivered images (JRC EUR 23638 EN §3.1-3.2, §6.4-6.5, §9.2).

Everything here judges the header facts of :mod:`orthospec.raster.facts` (the one reader), never
pixels (except the nodata share, which comes from the radiometry scan). A file that cannot be
opened, has no georeference or an unparseable CRS yields a :class:`FileChecks` with ``error`` set,
never an exception, so a national batch never stops on one bad file.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path, PurePath
from typing import Any

import rasterio

from ..errors import MeasureError
from .facts import RasterFacts, opened_facts
from .reading import ScanSettings, gdal_errors, readable_vector

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
    #: what the file says about itself (the one reader); not part of :meth:`to_dict`
    facts: RasterFacts | None = field(default=None, compare=False, repr=False)

    def to_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "facts"}
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = list(v)
        return d


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
    A missing georeference is reported in ``error``, never printed as a warning. The facts
    come from the one reader, :func:`orthospec.raster.facts.opened_facts`; ``FileChecks.facts``
    keeps them.
    """
    with opened_facts(path, settings=settings) as (facts, ds):
        yield (
            checks_of(
                facts,
                expect_epsg=expect_epsg,
                expect_gsd=expect_gsd,
                gsd_tolerance=gsd_tolerance,
                min_bits=min_bits,
                recommended_bits=recommended_bits,
            ),
            ds,
        )


def checks_of(
    facts: RasterFacts,
    *,
    expect_epsg: int | None = None,
    expect_gsd: float | None = None,
    gsd_tolerance: float = 0.01,
    min_bits: int = 8,
    recommended_bits: int = 11,
) -> FileChecks:
    """The file checks (§3.2 bit depth, §6.4 name, CRS and pixel size against what is expected)
    judged on one image's :class:`RasterFacts`."""
    p = facts.path
    name = check_name(Path(p).name)
    base: dict[str, Any] = {
        "path": p,
        "name_ok": name.ok,
        "name_problems": name.problems,
        "bytes": facts.bytes,
        "facts": facts,
    }
    if facts.error is not None:
        return FileChecks(error=facts.error, **base)
    depth = facts.bit_depth
    values: dict[str, Any] = dict(
        driver=facts.driver,
        compression=facts.compression,
        lossless=facts.lossless,
        layout=facts.layout,
        block_width=None if facts.block_shape is None else facts.block_shape[1],
        block_height=None if facts.block_shape is None else facts.block_shape[0],
        width=facts.width,
        height=facts.height,
        band_count=facts.count,
        dtypes=facts.dtypes,
        bit_depth_container=facts.bit_depth_container,
        nbits=facts.nbits,
        bit_depth_ok=None if depth is None else depth >= min_bits,
        bit_depth_recommended=None if depth is None else depth >= recommended_bits,
        colour_interpretation=facts.colorinterp,
        nodata=facts.nodata,
        nodata_declared=any(v is not None for v in facts.nodata),
        has_internal_mask=facts.internal_mask,
        has_overviews=bool(facts.overviews),
        stored_statistics=any(s is not None for s in facts.stats),
    )
    if facts.georeference is not None:
        return FileChecks(error=f"{p}: {facts.georeference}", **base, **values)
    crs_ok = None
    if expect_epsg is not None and facts.crs_wkt is not None:
        try:
            with gdal_errors(file=p, what="CRS"):
                crs_ok = _crs_equals(facts.crs_wkt, int(expect_epsg))
        except MeasureError as exc:  # pyproj's CRSError, mapped by the one boundary
            return FileChecks(error=f"{p}: unparseable CRS: {exc}", **base, **values)
    assert facts.pixel_size is not None
    px, py = facts.pixel_size
    gsd_ok = None
    if expect_gsd is not None:
        gsd_ok = all(abs(v - expect_gsd) <= gsd_tolerance * expect_gsd for v in (px, py))
    return FileChecks(
        crs=facts.crs_name,
        epsg=facts.epsg,
        crs_ok=crs_ok,
        pixel_size_x=px,
        pixel_size_y=py,
        pixel_size_unit=facts.pixel_unit,
        gsd_ok=gsd_ok,
        rotated=facts.rotated,
        **base,
        **values,
    )


@lru_cache(maxsize=64)
def _crs_equals(wkt: str, epsg: int) -> bool:
    """The CRS equals the expected EPSG code, axis order ignored (as GIS software does); pyproj,
    whose import alone costs about 0.1 s of ``measure radiometry``, only when a code is expected."""
    from pyproj import CRS

    return bool(CRS.from_user_input(wkt).equals(CRS.from_epsg(epsg), ignore_axis_order=True))


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
        with (
            readable_vector(p) as (local, _driver),
            gdal_errors(file=p, path=local, what="vector file"),
        ):
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
                    crs_ok = CRS.from_user_input(crs_text).equals(
                        CRS.from_epsg(int(expect_epsg)), ignore_axis_order=True
                    )
            except MeasureError:  # pyproj's CRSError, mapped by the one boundary: not equal
                crs_ok = False
    return VectorCheck(
        path=str(p),
        features=int(info.get("features", 0)),
        geometry_type=info.get("geometry_type"),
        crs=crs_text,
        crs_ok=crs_ok,
        fields=tuple(str(f) for f in info.get("fields", ())),
    )
