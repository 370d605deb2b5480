"""Stream rasters block by block into the pure radiometry accumulators.

Why this shape:

* windows are unions of whole internal blocks (``ds.block_shapes``: tiles or strips), so GDAL
  decodes every block once and memory stays bounded by ``ScanSettings.chunk_bytes`` (8 MB) whatever
  the image size;
* every pixel is read once: statistics, histograms, noise, luminosity and the misregistration
  windows are all fed from the same chunks (floats add one pass for their binned histogram), and
  the chunks are counted in two threads while a third decodes the next one into a recycled
  buffer; a side thread takes the slow, rare work (the noise of the sampled chunks' integer
  bands, the phase correlation of completed misregistration windows) so that it never holds
  up the counting of the next chunks;
* overviews are never used for statistics (plain full-resolution ``read``);
* GDAL / rasterio / pyogrio / pyproj errors become MeasureError naming the file in one place,
  :func:`gdal_errors` (the table :data:`LIBRARY_ERRORS`);
* the delivery is never written: datasets are opened read-only inside ``rasterio.Env`` with
  ``GDAL_PAM_ENABLED=NO`` so GDAL creates no ``.aux.xml`` next to the file, and
  ``GDAL_CACHEMAX`` is kept small because each block is read once anyway.

Validity follows GDAL's ``ComputeStatistics``: a band's nodata value when it has one (plus
NaN for floats); else the per-dataset mask (internal ``.msk``) or alpha band when the band has
one (the alpha band itself is never masked); else every pixel.
"""

from __future__ import annotations

import math
import os
import shutil
import stat
import sys
import tempfile
import threading
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import ExitStack, contextmanager, nullcontext
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import rasterio
from rasterio.enums import ColorInterp, MaskFlags
from rasterio.windows import Window

from ..errors import MeasureError, OrthospecError
from ..limits import env_limit
from ..measures import radiometry as rad
from ..measures import signature as sig

#: Counter of full raster scans in this process (tests use it to check the cache).
SCAN_COUNT = {"scans": 0}

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
    (b"II*\x00", "GTiff"), (b"MM\x00*", "GTiff"),          # TIFF, COG
    (b"II+\x00", "GTiff"), (b"MM\x00+", "GTiff"),          # BigTIFF
    (b"\x00\x00\x00\x0cjP  \r\n\x87\n", "JP2OpenJPEG"),   # JPEG 2000 (JP2)
    (b"\xff\x4f\xff\x51", "JP2OpenJPEG"),                  # JPEG 2000 codestream (J2K)
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
        return cls(pixels=env_limit("ORTHOSPEC_MAX_RASTER_PIXELS", d.pixels),
                   bands=env_limit("ORTHOSPEC_MAX_RASTER_BANDS", d.bands))


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
    """The one boundary where rasterio / GDAL / pyogrio / pyproj errors become MeasureError naming the file.

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
    """Refuse a raster whose header declares more pixels or bands than the limits (before reading)."""
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


@dataclass(frozen=True)
class ScanSettings:
    """What a scan computes; part of the cache key."""

    bit_depth: int | None = None
    noise: bool = True
    luminosity: bool = True
    misregistration: bool = True
    #: the pixel facts of issue 25 (measures/signature.py): content hash of the decoded pixels,
    #: thumbnail for near copies, measured cloud cover
    signature: bool = True
    #: noise estimators look at whole chunks spread evenly over the image, at most this many
    #: pixels per band (4 Mpx estimate sigma to better than 1 %); 0 = every chunk
    noise_max_pixels: int = 4 * 2**20
    chunk_bytes: int = 8 * 2**20
    gdal_cachemax_mb: int = 32
    #: threads counting the chunks of one image (besides the reader thread); the results do not
    #: depend on it (chunks always go to the same two accumulator sets, merged in one order)
    threads: int = 2

    def key(self) -> str:
        """Stable text key of the settings that change results (not of performance knobs)."""
        d = asdict(self)
        d.pop("chunk_bytes")
        d.pop("gdal_cachemax_mb")
        d.pop("threads")
        return ";".join(f"{k}={d[k]}" for k in sorted(d))


@contextmanager
def read_only_env(settings: ScanSettings | None = None) -> Iterator[None]:
    """GDAL configuration that writes nothing next to the input and caches little.

    ``GTIFF_DIRECT_IO`` and ``GTIFF_VIRTUAL_MEM_IO`` are forced off, even when the user's
    environment sets them: direct I/O saves about 15 % of a scan's read CPU on uncompressed
    files, but GDAL 3.10 then returns zeros, without an error, for the missing strips of a
    truncated striped file (``test_truncated_file_raises_measure_error``).
    """
    s = settings or ScanSettings()
    with rasterio.Env(
        GDAL_PAM_ENABLED="NO",
        GDAL_CACHEMAX=s.gdal_cachemax_mb,
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
    grey: rad.GreyRange


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
                grey=rad.grey_range(dtype, declared=bit_depth, nbits=nbits),
            )
        )
    return out


@dataclass
class RasterStats:
    """Everything a scan of one raster measured (no file checks)."""

    bands: list[rad.BandStats]
    luminosity: rad.BandStats | None
    misregistration: dict[int, rad.Shift] = field(default_factory=dict)
    misregistration_spread: dict[int, float] = field(default_factory=dict)
    reference_band: int | None = None
    chunks: int = 0
    #: facts of the decoded pixels (measures/signature.py): content hash, thumbnail cell means,
    #: measured cloud cover (None: no colour bands), DN-0 saturation under a nodata value of 0
    pixels_hash: str | None = None
    thumbnail: list[list[float | None]] | None = None
    thumbnail_cell_px: int | None = None
    cloud_pct: float | None = None
    cloud_samples: int | None = None
    low_nodata: dict[str, Any] | None = None

    def to_dict(self, *, histogram: bool = True) -> dict[str, Any]:
        return {
            "statistics": "exact, population std, nodata excluded per band, as GDAL",
            "bands": [b.to_dict(histogram=histogram) for b in self.bands],
            "luminosity": None
            if self.luminosity is None
            else self.luminosity.to_dict(histogram=histogram),
            "luminosity_weights": list(rad.LUMA_WEIGHTS),
            "misregistration": {
                str(k): {
                    "dy_px": v.dy,
                    "dx_px": v.dx,
                    "magnitude_px": v.magnitude,
                    "peak": v.peak,
                    "spread_px": self.misregistration_spread.get(k),
                    "reliable": misregistration_reliable(
                        v.peak, self.misregistration_spread.get(k)
                    ),
                }
                for k, v in sorted(self.misregistration.items())
            },
            "misregistration_reference_band": self.reference_band,
            "pixels_hash": self.pixels_hash,
            "thumbnail": self.thumbnail,
            "thumbnail_cell_px": self.thumbnail_cell_px,
            "cloud_pct": self.cloud_pct,
            "cloud_samples": self.cloud_samples,
            "low_nodata": self.low_nodata,
        }


def _rgb_bands(infos: Sequence[BandInfo]) -> tuple[int, int, int] | None:
    """1-based R, G, B band indexes by colour interpretation, else bands 1-3 of a 3/4-band image."""
    by = {b.colour: b.index for b in infos}
    if {"red", "green", "blue"} <= by.keys():
        return by["red"], by["green"], by["blue"]
    if len(infos) in (3, 4) and all(b.colour in ("undefined", "gray") for b in infos[:3]):
        return 1, 2, 3
    return None


def _valid(data: np.ndarray, info: BandInfo, mask: np.ndarray | None) -> np.ndarray | None:
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


def _nonfinite(data: np.ndarray, info: BandInfo, mask: np.ndarray | None) -> int:
    """Pixels of a float band's block that are NaN or +/-Inf and not no-data (a NaN nodata value
    makes NaN no-data; a GDAL mask's zeros are no-data): excluded from every statistic, counted."""
    if data.dtype.kind != "f":
        return 0
    bad = ~np.isfinite(data)
    if not bad.any():
        return 0
    nd = info.nodata
    if nd is not None and not info.use_mask:
        bad &= ~np.isnan(data) if math.isnan(nd) else data != np.asarray(nd).astype(data.dtype)
    if info.use_mask and mask is not None:
        bad &= mask
    return int(np.count_nonzero(bad))


def scan_raster(path: str | Path, settings: ScanSettings | None = None) -> RasterStats:
    """Exact per-band statistics, histograms and §6.3 measures of one raster, streamed.

    Raises
    ------
    MeasureError
        when the raster cannot be read to the end (truncated or corrupt blocks).
    """
    s = settings or ScanSettings()
    with read_only_env(s), open_read_only(path) as ds:
        return scan_dataset(ds, s, file=path)


def scan_dataset(
    ds: rasterio.io.DatasetReader,
    settings: ScanSettings | None = None,
    *,
    file: str | Path | None = None,
) -> RasterStats:
    """:func:`scan_raster` of a dataset already opened with :func:`open_read_only`.

    Raises
    ------
    MeasureError
        naming ``file`` (default the dataset's name) when the pixels cannot be read to the end.
    """
    SCAN_COUNT["scans"] += 1
    with gdal_errors(file=file or ds.name, what="raster (pixels)"):
        return _scan(ds, settings or ScanSettings())


def _scan(ds: rasterio.io.DatasetReader, s: ScanSettings) -> RasterStats:
    infos = band_infos(ds, s.bit_depth)
    acc = _Accumulators.for_bands(infos, s, ds)
    capture = (
        _MisregistrationWindows.plan(ds, infos) if s.misregistration and ds.count >= 2 else None
    )
    chunks = _stream(ds, infos, s, acc, capture)
    binned = _binned_histograms(ds, infos, acc, s)  # floats / 32-bit only
    bands: list[rad.BandStats] = []
    for b in infos:
        nz = acc.noise.get(b.index)
        if b.index in acc.hists:
            h = acc.hists[b.index]
            if not b.use_mask:
                h.exclude_value(b.nodata)
            bands.append(
                rad.band_stats_from_histogram(
                    str(b.index), b.dtype, h, b.grey, noise=nz, nodata=b.nodata
                )
            )
        else:
            ec = acc.edge_counts[b.index]
            bands.append(
                rad.band_stats_from_moments(
                    str(b.index),
                    b.dtype,
                    ds.width * ds.height,
                    acc.moms[b.index],
                    b.grey,
                    histogram=binned.get(b.index),
                    noise=nz,
                    count_low=ec[0],
                    count_high=ec[1],
                    above_range=ec[2],
                    nodata=b.nodata,
                )
            )
        if b.index in acc.nonfinite:
            bands[-1] = replace(bands[-1], nonfinite=acc.nonfinite[b.index])
    lum_stats = None
    if acc.lum is not None and acc.rgb is not None:
        first = infos[acc.rgb[0] - 1]
        lum_stats = rad.band_stats_from_histogram("luminosity", first.dtype, acc.lum, first.grey)
    out = RasterStats(bands=bands, luminosity=lum_stats, chunks=chunks)
    acc.finish(out, ds)
    if capture is not None:
        out.reference_band, out.misregistration, out.misregistration_spread = capture.result()
    return out


#: Chunks read but not yet counted, at most (memory: this many x ``ScanSettings.chunk_bytes``).
#: More than one per counting thread, so that a slow chunk (the noise estimators' sample, a
#: completed misregistration window, Pillow's first import) delays only its own thread: the
#: reader and the other thread go on with the next chunks meanwhile.
CHUNKS_IN_FLIGHT = 6


def _stream(
    ds: rasterio.io.DatasetReader,
    infos: Sequence[BandInfo],
    s: ScanSettings,
    acc: _Accumulators,
    capture: _MisregistrationWindows | None,
) -> int:
    """The one read of the pixels: feed every chunk to ``acc`` and ``capture``; the chunk count.

    A reader thread decodes the next chunks (GDAL releases the GIL) while up to ``s.threads``
    threads count the previous ones (numpy and Pillow release it too); only the reader touches
    the dataset. At most :data:`CHUNKS_IN_FLIGHT` chunks are in memory at once.
    """
    wins = list(chunk_windows(ds, s.chunk_bytes))
    stride = 1
    if acc.noise and s.noise_max_pixels:
        stride = max(1, math.ceil(ds.width * ds.height / s.noise_max_pixels))
    mask_band = next((b.index for b in infos if b.use_mask), None)
    # Chunk arrays are recycled: a counted chunk's buffer receives a later chunk. A fresh array
    # per chunk is fresh memory that the kernel zeroes and maps page by page, and takes back
    # when it is freed: about 5 % of the CPU of a full scan. The values are the same (GDAL
    # writes every element of the window into ``out``, in the dtype ``read`` chose before).
    largest = max((ds.count * int(w.height) * int(w.width) for w in wins), default=0)
    free: list[np.ndarray] = []  # flat buffers of ``largest`` elements, their chunk counted
    free_lock = threading.Lock()
    dtype: list[np.dtype] = []  # the dtype read() picks, from the first chunk

    def fetch(win: Window) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """(chunk, shared mask, the chunk's recyclable flat buffer or None)."""
        # GDAL masks of one dataset (per-dataset mask or alpha) are shared by its bands
        mask = ds.read_masks(mask_band, window=win) if mask_band is not None else None
        with free_lock:
            buf = free.pop() if free else None
        if buf is None:
            if not dtype or len(wins) <= 1:  # the first chunk: read() allocates, picks the dtype
                data = ds.read(window=win)
                dtype.append(data.dtype)
                flat = (
                    data.reshape(-1) if data.size == largest and data.flags.c_contiguous else None
                )
                return data, mask, flat
            buf = np.empty(largest, dtype=dtype[0])  # none free yet: the pool grows by one
        shape = (ds.count, int(win.height), int(win.width))
        out = buf[: shape[0] * shape[1] * shape[2]].reshape(shape)
        return ds.read(window=win, out=out), mask, buf

    # chunk k goes to accumulator set k % 2 and is counted by thread k % threads, in chunk
    # order within each set, whatever the number of threads: the floating-point sums (noise,
    # float moments) do not depend on the machine's cores or on timing
    accs = (acc, _Accumulators.for_bands(infos, s, ds)) if len(wins) > 1 else (acc,)
    threads = max(1, min(s.threads, os.cpu_count() or 1, len(accs), len(wins)))
    slots = threading.Semaphore(max(CHUNKS_IN_FLIGHT, threads + 1))

    def done(buf: np.ndarray | None) -> None:
        """A chunk is counted: its buffer may take another chunk (nothing keeps a view of it:
        the misregistration capture copies), its slot another read."""
        if buf is not None:
            with free_lock:
                free.append(buf)
        slots.release()

    # The noise estimators of a sampled chunk take several times a chunk's counting: in the
    # counting thread they would hold up its next chunks and, through the chunks in flight,
    # the reader and the other thread. Integer bands' noise (exact integer sums) goes to a
    # side thread instead, into one accumulator per chunk merged at the end.
    side: list[ThreadPoolExecutor] = []  # the side thread of a threaded scan
    noise_jobs: list[Future[list[tuple[int, rad.NoiseAccumulator]]]] = []

    def noise_of(
        work: list[tuple[int, np.ndarray, np.ndarray | None]], buf: np.ndarray | None
    ) -> list[tuple[int, rad.NoiseAccumulator]]:
        try:
            out = []
            for idx, band, valid in work:
                part = rad.NoiseAccumulator()
                part.add(band, valid)
                out.append((idx, part))
            return out
        finally:
            done(buf)

    def feed(
        k: int, win: Window, data: np.ndarray, mask: np.ndarray | None, buf: np.ndarray | None
    ) -> None:
        later: list[tuple[int, np.ndarray, np.ndarray | None]] | None = [] if side else None
        handed = False
        try:
            with rad.serial_counting() if threads > 1 else nullcontext():
                accs[k % len(accs)].add(data, mask, noise=k % stride == 0, later=later, win=win)
            if capture is not None:
                capture.take(win, data, mask)  # disjoint parts of the windows: safe in threads
            if later:
                with free_lock:
                    noise_jobs.append(side[0].submit(noise_of, later, buf))
                handed = True  # the side thread releases the chunk
        finally:
            if not handed:
                done(buf)

    if len(wins) <= 1:  # one chunk (a small image): no thread to start and hand off to
        for k, win in enumerate(wins):
            slots.acquire()
            feed(k, win, *fetch(win))
    else:
        with ThreadPoolExecutor(max_workers=1) as reader, ExitStack() as stack:
            # the side thread (noise, misregistration windows): shut down after the counting
            # threads that feed it
            side.append(stack.enter_context(ThreadPoolExecutor(max_workers=1)))
            if capture is not None:
                capture.correlator = side[0]
            counters = [
                stack.enter_context(ThreadPoolExecutor(max_workers=1)) for _ in range(threads)
            ]
            queued: deque[Future[None]] = deque()
            slots.acquire()
            pending = reader.submit(fetch, wins[0])
            for k, win in enumerate(wins):
                data, shared_mask, buf = pending.result()
                if k + 1 < len(wins):
                    slots.acquire()  # waits while CHUNKS_IN_FLIGHT chunks are not counted yet
                    pending = reader.submit(fetch, wins[k + 1])
                queued.append(counters[k % threads].submit(feed, k, win, data, shared_mask, buf))
                while queued and queued[0].done():
                    queued.popleft().result()  # a counting error stops the scan early
            for fut in queued:
                fut.result()
            for job in noise_jobs:  # exact integer sums: any order gives the same bits
                for idx, part in job.result():
                    acc.noise[idx].merge(part)
    for other in accs[1:]:
        acc.merge(other)
    return len(wins)


def _binned_histograms(
    ds: rasterio.io.DatasetReader, infos: Sequence[BandInfo], acc: _Accumulators, s: ScanSettings
) -> dict[int, rad.BinnedHistogramAccumulator]:
    """Float and 32-bit bands: a second pass for the equal-bin histogram between the exact
    min and max (only known after the first); integer bands up to 16 bits need none."""
    binned = {
        idx: rad.BinnedHistogramAccumulator(m.vmin, m.vmax) for idx, m in acc.moms.items() if m.n
    }
    if not binned:
        return binned
    idxs = sorted(binned)
    for win in chunk_windows(ds, s.chunk_bytes):
        data = ds.read(indexes=idxs, window=win)
        for k, idx in enumerate(idxs):
            b = infos[idx - 1]
            mask = ds.read_masks(idx, window=win) if b.use_mask else None
            binned[idx].add(data[k], _valid(data[k], b, mask))
    return binned


def _nodata_bin(info: BandInfo, hist: rad.HistogramAccumulator) -> int | None:
    """Histogram bin of the band's nodata value, None when the value excludes no pixel."""
    nd = info.nodata
    if info.use_mask or nd is None or not math.isfinite(nd) or nd != int(nd):
        return None
    i = int(nd) - hist.offset
    return i if 0 <= i < hist.counts.size else None


@dataclass
class _Accumulators:
    """Every per-band accumulator of one scan, fed chunk by chunk by :meth:`add`."""

    infos: Sequence[BandInfo]
    hists: dict[int, rad.HistogramAccumulator]
    moms: dict[int, rad.Moments]
    edge_counts: dict[int, list[int]]  # low, high, outside the grey range (moments bands)
    noise: dict[int, rad.NoiseAccumulator]
    rgb: tuple[int, int, int] | None
    lum: rad.HistogramAccumulator | None
    #: pixel facts (measures/signature.py), None when ScanSettings.signature is off
    pixel_hash: sig.PixelHash | None = None
    thumb: sig.Thumbnail | None = None
    cloud: sig.CloudCounter | None = None
    #: bands whose nodata value is their lowest grey level (DN-0 saturation hidden by nodata), and
    #: per such band the pixels at that value while another band is valid (told apart), and the
    #: pixels at nodata in every band (cannot be told apart)
    hidden: tuple[int, ...] = ()
    low_told: dict[int, int] = field(default_factory=dict)
    all_nodata: int = 0
    #: per float band, its NaN / +/-Inf pixels that are not no-data (:func:`_nonfinite`)
    nonfinite: dict[int, int] = field(default_factory=dict)

    @classmethod
    def for_bands(
        cls, infos: Sequence[BandInfo], s: ScanSettings, ds: rasterio.io.DatasetReader | None = None
    ) -> _Accumulators:
        exact = [rad.histogram_layout(b.dtype) is not None for b in infos]
        rgb = _rgb_bands(infos) if s.luminosity else None
        if rgb is not None and not all(exact[i - 1] for i in rgb):
            rgb = None
        hidden = tuple(
            b.index
            for b in infos
            if not b.use_mask
            and b.nodata is not None
            and b.grey.low is not None
            and b.nodata == b.grey.low
        )
        extra: dict[str, Any] = {
            "hidden": hidden,
            "low_told": dict.fromkeys(hidden, 0),
            "nonfinite": {b.index: 0 for b in infos if np.dtype(b.dtype).kind == "f"},
        }
        if s.signature and ds is not None:
            dtype = str(np.result_type(*ds.dtypes))
            extra["pixel_hash"] = sig.PixelHash(
                width=ds.width, height=ds.height, count=ds.count, dtype=dtype
            )
            extra["thumb"] = sig.Thumbnail(width=ds.width, height=ds.height, dtype=dtype)
            colour = _rgb_bands(infos)
            if colour is not None and all(infos[i - 1].grey.high for i in colour):
                extra["cloud"] = sig.CloudCounter.for_image(
                    width=ds.width,
                    height=ds.height,
                    rgb=tuple(i - 1 for i in colour),  # type: ignore[arg-type]
                    tops=tuple(float(infos[i - 1].grey.high) for i in colour),  # type: ignore[arg-type]
                    nodata=tuple(
                        None if infos[i - 1].use_mask else infos[i - 1].nodata  # type: ignore[arg-type]
                        for i in colour
                    ),
                )
        return cls(
            **extra,
            infos=infos,
            hists={
                b.index: rad.HistogramAccumulator.for_dtype(b.dtype)
                for b, ex in zip(infos, exact, strict=True)
                if ex
            },
            moms={b.index: rad.Moments() for b, ex in zip(infos, exact, strict=True) if not ex},
            edge_counts={b.index: [0, 0, 0] for b, ex in zip(infos, exact, strict=True) if not ex},
            noise={b.index: rad.NoiseAccumulator() for b in infos} if s.noise else {},
            rgb=rgb,
            lum=rad.HistogramAccumulator.for_dtype(infos[rgb[0] - 1].dtype) if rgb else None,
        )

    def add(
        self,
        data: np.ndarray,
        shared_mask: np.ndarray | None,
        *,
        noise: bool,
        later: list[tuple[int, np.ndarray, np.ndarray | None]] | None = None,
        win: Window | None = None,
    ) -> None:
        """Feed one chunk (bands, rows, cols); ``noise`` False skips the noise estimators.

        Validity masks cost as much as a histogram: they are built only where a pixel can be
        invalid (a GDAL mask with zeros, or a chunk whose histogram counted the nodata value)
        and only for the accumulators that need them (moments, noise, luminosity).
        ``later`` (a list) receives (band index, band, validity) of the integer bands' noise
        instead of adding it here: their sums are exact integers, the same in any order, so
        another thread may add them (:func:`_stream`); float bands are added here, in order.
        """
        mask_valid = None
        if shared_mask is not None:
            mask_valid = shared_mask != 0
            if np.count_nonzero(mask_valid) == mask_valid.size:
                mask_valid = None
        need = set(self.moms) | (set(self.noise) if noise else set())
        valids: dict[int, np.ndarray | None] = {}
        with_nodata: dict[int, int] = {}  # bands whose nodata value occurs in this chunk: how often
        for b in self.infos:
            band = data[b.index - 1]
            hist = self.hists.get(b.index)
            if hist is None:
                valid = _valid(band, b, mask_valid if b.use_mask else None)
                self._add_moments(band, b, valid)
                if b.index in self.nonfinite:
                    self.nonfinite[b.index] += _nonfinite(
                        band, b, mask_valid if b.use_mask else None
                    )
            elif b.use_mask:
                hist.add(band, mask_valid)
                valid = mask_valid
            else:
                nd = _nodata_bin(b, hist)
                before = int(hist.counts[nd]) if nd is not None else 0
                hist.add(band)  # the nodata bin is dropped once at the end (exclude_value)
                if nd is not None and int(hist.counts[nd]) != before:
                    with_nodata[b.index] = int(hist.counts[nd]) - before
                valid = (
                    _valid(band, b, None) if b.index in with_nodata and b.index in need else None
                )
            valids[b.index] = valid
            if noise and b.index in self.noise:
                if later is not None and band.dtype.kind in "uib" and band.dtype.itemsize <= 2:
                    later.append((b.index, band, valid))
                else:
                    self.noise[b.index].add(band, valid)
        if self.rgb is not None and self.lum is not None:
            self._add_luminosity(data, mask_valid, valids, with_nodata)
        if with_nodata and self.hidden:
            self._add_low_nodata(data, with_nodata, valids)
        if win is not None:
            c0, r0 = int(win.col_off), int(win.row_off)
            if self.pixel_hash is not None:
                self.pixel_hash.add(data, c0, r0)
            if self.thumb is not None:
                self.thumb.add(data, c0, r0)
            if self.cloud is not None:
                self.cloud.add(data, c0, r0, shared_mask)

    def _add_low_nodata(
        self, data: np.ndarray, with_nodata: dict[int, int], valids: dict[int, np.ndarray | None]
    ) -> None:
        """DN-0 saturation under a nodata value of 0 (issue 26): a band at its nodata value where
        another band of the pixel is valid is saturated, not no-data; a pixel at nodata in every
        band cannot be told apart. Only for chunks where a band's nodata value occurs. A band's
        count at nodata is its histogram's (``with_nodata``), and a validity mask built for the
        moments is reused. The pixels at nodata in every band are found by position: the band with
        the fewest nodata pixels in the chunk is compared once, the others only at those positions
        (a chunk has few such pixels, except at an image's no-data rim); no comparison at all when a
        band has no nodata pixel in the chunk (then no pixel is at nodata in every band)."""
        bands: list[BandInfo] = []
        for b in self.infos:
            if (
                b.use_mask
                or b.nodata is None
                or (isinstance(b.nodata, float) and math.isnan(b.nodata))
                or (b.index in self.hists and b.index not in with_nodata)
            ):
                bands = []  # a band without nodata here: no pixel is nodata in every band
                break
            bands.append(b)
        # fewest first: histogram bands by their count at nodata, the others (no count) last
        bands.sort(key=lambda b: with_nodata.get(b.index, data[0].size + 1))
        where: np.ndarray | None = None
        for b in bands:
            band = data[b.index - 1].reshape(-1)
            nd = np.asarray(b.nodata).astype(data.dtype)
            if where is None:
                valid = valids.get(b.index)
                at = (
                    ~valid.reshape(-1)
                    if valid is not None and data.dtype.kind in "uib"
                    else band == nd
                )
                where = np.flatnonzero(at)
            else:
                where = where[band[where] == nd]
            if not where.size:
                break
        ambiguous = int(where.size) if where is not None else 0
        self.all_nodata += ambiguous
        for idx in self.hidden:
            if idx in with_nodata:
                self.low_told[idx] += (
                    with_nodata[idx] - ambiguous
                )  # every-band pixels are not told apart

    def finish(self, out: RasterStats, ds: rasterio.io.DatasetReader) -> None:
        """Put the pixel facts into ``out`` (after every chunk was added and the sets merged)."""
        if self.pixel_hash is not None:
            out.pixels_hash = self.pixel_hash.hexdigest()
        if self.thumb is not None:
            out.thumbnail, out.thumbnail_cell_px = self.thumb.result(), self.thumb.cell
        if self.cloud is not None:
            out.cloud_pct, out.cloud_samples = self.cloud.percent, self.cloud.valid
        if self.hidden:
            total = ds.width * ds.height
            rest = total - self.all_nodata
            out.low_nodata = {
                "bands": [str(i) for i in self.hidden],
                "pixels_nodata_in_every_band": self.all_nodata,
                "pixels_nodata_in_every_band_pct": 100.0 * self.all_nodata / total
                if total
                else None,
                "saturation_low_told_pct": {
                    str(i): (100.0 * self.low_told[i] / rest if rest else None) for i in self.hidden
                },
            }

    def _add_luminosity(
        self,
        data: np.ndarray,
        mask_valid: np.ndarray | None,
        valids: dict[int, np.ndarray | None],
        with_nodata: dict[int, int],
    ) -> None:
        """Luminosity of the pixels valid in all three colour bands."""
        assert self.rgb is not None and self.lum is not None
        rgb = [self.infos[i - 1] for i in self.rgb]
        r, g, bl = (data[i - 1] for i in self.rgb)
        first = self.rgb[0] - 1
        planes = data[first : first + 3] if self.rgb == (first + 1, first + 2, first + 3) else None
        y = rad.luminosity_block(
            r, g, bl, data.dtype, planes=planes, out=rad.scratch("luminosity", r.shape, data.dtype)
        )
        nodata = {b.nodata for b in rgb}
        if not with_nodata.keys() & set(self.rgb) and not any(
            b.use_mask and mask_valid is not None for b in rgb
        ):
            self.lum.add(y)  # every pixel of the chunk is valid in all three bands
            return
        low = np.iinfo(data.dtype).min if data.dtype.kind in "ui" else None
        if (
            len(nodata) == 1
            and low is not None
            and nodata == {float(low)}
            and not any(b.use_mask for b in rgb)
        ):
            # the usual case (nodata 0 in every band): a pixel is invalid where the darkest of its
            # three values is the nodata value; two np.minimum beat three masks by about 3x
            darkest = np.minimum(r, g, out=rad.scratch("darkest", r.shape, r.dtype))
            np.minimum(darkest, bl, out=darkest)
            if low == 0:  # darkest != 0 exactly where the pixel is valid: the mask as it is
                self.lum.add_where(y, darkest)
            else:
                self.lum.add_excluding(y, np.flatnonzero(darkest == low))
            return
        v = None
        for b in rgb:
            part = valids.get(b.index)
            if part is None and (b.index in with_nodata or (b.use_mask and mask_valid is not None)):
                part = _valid(data[b.index - 1], b, mask_valid if b.use_mask else None)
            if part is not None:
                v = part if v is None else v & part
        self.lum.add(y, v)

    def merge(self, other: _Accumulators) -> _Accumulators:
        """Add another set's counts and sums (same bands); integer counts merge exactly."""
        for idx, h in self.hists.items():
            h.merge(other.hists[idx])
        for idx, m in self.moms.items():
            m.merge(other.moms[idx])
            self.edge_counts[idx] = [
                a + b for a, b in zip(self.edge_counts[idx], other.edge_counts[idx], strict=True)
            ]
        for idx, nz in self.noise.items():
            nz.merge(other.noise[idx])
        if self.lum is not None and other.lum is not None:
            self.lum.merge(other.lum)
        for mine, theirs in (
            (self.pixel_hash, other.pixel_hash),
            (self.thumb, other.thumb),
            (self.cloud, other.cloud),
        ):
            if mine is not None and theirs is not None:
                mine.merge(theirs)  # type: ignore[arg-type]
        for idx in self.hidden:
            self.low_told[idx] += other.low_told.get(idx, 0)
        self.all_nodata += other.all_nodata
        for idx in self.nonfinite:
            self.nonfinite[idx] += other.nonfinite.get(idx, 0)
        return self

    def _add_moments(self, band: np.ndarray, b: BandInfo, valid: np.ndarray | None) -> None:
        self.moms[b.index].add(band, valid)
        g = b.grey
        if g.bit_depth is not None:
            vals = band if valid is None else band[valid]
            ec = self.edge_counts[b.index]
            ec[0] += int(np.count_nonzero(vals == g.low))
            ec[1] += int(np.count_nonzero(vals == g.high))
            ec[2] += int(np.count_nonzero((vals < g.low) | (vals > g.high)))


#: Sub-pixel resolution of the band misregistration, 1/20 px (1/10 px was 0.1 px off
#: on the synthetic 1.5 px test shift).
MISREGISTRATION_UPSAMPLE = 20


@dataclass
class _MisregistrationWindows:
    """Band-to-band shift vs the green (else first) band: median over up to 5 square windows.

    The windows are copied out of the chunks of the one streaming read as they pass (no second
    read of the file); a window is phase-correlated by the counting thread that completes it,
    so that work overlaps the rest of the scan (the results are the same in any thread).
    """

    infos: Sequence[BandInfo]
    ref: int
    others: list[BandInfo]
    windows: list[Window]
    data: list[np.ndarray]
    masks: list[np.ndarray | None]
    filled: list[int] = field(default_factory=list)
    shifts: list[dict[int, rad.Shift] | None] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    #: where completed windows are correlated (a thread of their own during a threaded scan);
    #: None: by the thread that completes them
    correlator: ThreadPoolExecutor | None = None
    pending: dict[int, Future[dict[int, rad.Shift]]] = field(default_factory=dict)

    @classmethod
    def plan(
        cls, ds: rasterio.io.DatasetReader, infos: Sequence[BandInfo], *, size: int = 256
    ) -> _MisregistrationWindows:
        colour = {b.colour: b.index for b in infos}
        ref = colour.get("green", 1)
        others = [b for b in infos if b.index != ref and b.colour != "alpha"]
        n = min(size, ds.height, ds.width)
        wins: list[Window] = []
        if n >= 32 and others:
            for fy, fx in ((0.5, 0.5), (0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)):
                row = int(min(max(fy * ds.height - n / 2, 0), ds.height - n))
                col = int(min(max(fx * ds.width - n / 2, 0), ds.width - n))
                w = Window(col, row, n, n)
                if w not in wins:
                    wins.append(w)
        use_mask = any(b.use_mask for b in infos)
        dtype = np.result_type(*ds.dtypes)
        return cls(
            infos=infos,
            ref=ref,
            others=others,
            windows=wins,
            data=[np.zeros((ds.count, n, n), dtype=dtype) for _ in wins],
            masks=[np.zeros((n, n), dtype=np.uint8) if use_mask else None for _ in wins],
            filled=[0] * len(wins),
            shifts=[None] * len(wins),
        )

    def take(self, win: Window, data: np.ndarray, mask: np.ndarray | None) -> None:
        """Copy the part of each window that this chunk (at ``win``) holds; correlate the
        windows this chunk completes (chunks are disjoint and cover the image)."""
        c0, r0 = int(win.col_off), int(win.row_off)
        c1, r1 = c0 + int(win.width), r0 + int(win.height)
        for i, (w, buf, mbuf) in enumerate(zip(self.windows, self.data, self.masks, strict=True)):
            wc0, wr0 = int(w.col_off), int(w.row_off)
            ic0, ic1 = max(c0, wc0), min(c1, wc0 + int(w.width))
            ir0, ir1 = max(r0, wr0), min(r1, wr0 + int(w.height))
            if ic0 >= ic1 or ir0 >= ir1:
                continue
            dst = (slice(ir0 - wr0, ir1 - wr0), slice(ic0 - wc0, ic1 - wc0))
            src = (slice(ir0 - r0, ir1 - r0), slice(ic0 - c0, ic1 - c0))
            buf[(slice(None), *dst)] = data[(slice(None), *src)]
            if mbuf is not None and mask is not None:
                mbuf[dst] = mask[src]
            with self.lock:
                self.filled[i] += (ir1 - ir0) * (ic1 - ic0)
                complete = self.filled[i] == int(w.width) * int(w.height)
            if complete:
                if self.correlator is not None:
                    # not in the counting thread: its next chunks (and, through the chunks in
                    # flight, the reader and the other counting thread) would wait ~16 ms
                    self.pending[i] = self.correlator.submit(self._correlate, i)
                else:
                    self.shifts[i] = self._correlate(i)

    def _correlate(self, i: int) -> dict[int, rad.Shift]:
        """Shift of every other band vs the reference band in window ``i`` (none if too few
        valid pixels or a flat band)."""
        data, mask = self.data[i], self.masks[i]
        ref_info = self.infos[self.ref - 1]
        a = _filled(
            data[self.ref - 1],
            _valid(data[self.ref - 1], ref_info, mask if ref_info.use_mask else None),
        )
        if a is None:
            return {}
        f_ref = rad.tapered_spectrum(a)
        out = {}
        for b in self.others:
            m = _filled(
                data[b.index - 1], _valid(data[b.index - 1], b, mask if b.use_mask else None)
            )
            if m is not None:
                out[b.index] = rad.phase_correlation_spectra(
                    f_ref, rad.tapered_spectrum(m), upsample=MISREGISTRATION_UPSAMPLE
                )
        return out

    def result(self) -> tuple[int, dict[int, rad.Shift], dict[int, float]]:
        found: dict[int, list[rad.Shift]] = {b.index: [] for b in self.others}
        for i in range(len(self.windows)):  # window order: the same medians in any thread
            if i in self.pending:
                self.shifts[i] = self.pending.pop(i).result()
            got = self.shifts[i]
            if got is None:  # not completed by the chunks (cannot happen; stay exact anyway)
                got = self.shifts[i] = self._correlate(i)
            for idx, shift in got.items():
                found[idx].append(shift)
        result, spreads = {}, {}
        for idx, shifts in found.items():
            if shifts:
                dy = float(np.median([s.dy for s in shifts]))
                dx = float(np.median([s.dx for s in shifts]))
                spreads[idx] = max(float(np.hypot(s.dy - dy, s.dx - dx)) for s in shifts)
                result[idx] = rad.Shift(
                    dy=dy, dx=dx, peak=float(np.median([s.peak for s in shifts]))
                )
        return self.ref, result, spreads


#: A band shift is trusted only when the phase-correlation peak stands out and the windows agree:
#: bands that share little texture (NIR vs green over vegetation) give weak, wandering peaks.
MISREGISTRATION_MIN_PEAK = 0.2
MISREGISTRATION_MAX_SPREAD_PX = 1.0


def misregistration_reliable(peak: float, spread_px: float | None) -> bool:
    return peak >= MISREGISTRATION_MIN_PEAK and (
        spread_px is None or spread_px <= MISREGISTRATION_MAX_SPREAD_PX
    )


def _mask(ds: rasterio.io.DatasetReader, info: BandInfo, win: Window) -> np.ndarray | None:
    return ds.read_masks(info.index, window=win) if info.use_mask else None


def _filled(
    band: np.ndarray, valid: np.ndarray | None, min_valid: float = 0.9
) -> np.ndarray | None:
    """Band as float with invalid pixels set to the valid mean; None if too few or flat."""
    a = band.astype(np.float64)
    if valid is not None:
        if valid.mean() < min_valid:
            return None
        a[~valid] = a[valid].mean()
    if float(a.std()) == 0.0:
        return None
    return a


# --------------------------------------------------------------------------- cloud mask


def mask_share(
    path: str | Path, *, settings: ScanSettings | None = None
) -> rad.MaskShareAccumulator:
    """Share of non-zero pixels of band 1 of a delivered mask raster (nodata excluded)."""
    s = settings or ScanSettings()
    acc = rad.MaskShareAccumulator()
    with read_only_env(s), open_read_only(path) as ds, gdal_errors(file=path, what="mask raster"):
        info = band_infos(ds, None)[0]
        for win in chunk_windows(ds, s.chunk_bytes):
            band = ds.read(1, window=win)
            acc.add(band, _valid(band, info, _mask(ds, info, win)))
    return acc


# --------------------------------------------------------------------------- mosaics


#: GeoPackage (SQLite) and shapefile magic; any other vector format (an OGR VRT can point at
#: any file or URL) is refused.
_VECTOR_MAGIC = ((b"SQLite format 3\x00", "GPKG"), (b"\x00\x00\x27\x0a", "ESRI Shapefile"))


def vector_driver(path: str | Path, name: str | None = None) -> str:
    """``GPKG`` or ``ESRI Shapefile`` from the file's first bytes; MeasureError for anything else."""
    label = name or str(path)
    head = _head(path, label, 72)
    for magic, driver in _VECTOR_MAGIC:
        if head.startswith(magic):
            # a GeoPackage says so in the SQLite application_id (offset 68, OGC 12-128r18 §1.1.1.1.1);
            # any other SQLite file would go to OGR's SQLite driver (VirtualOGR tables, SpatiaLite)
            if driver == "GPKG" and head[68:72] not in (b"GPKG", b"GP10", b"GP11"):
                break
            return driver
    kind = " (XML: an OGR VRT?)" if head.lstrip().startswith(b"<") else ""
    raise MeasureError(
        f"{label}: not a readable vector file: not a GeoPackage or shapefile{kind}; other "
        "vector formats are not read"
    )


@contextmanager
def readable_vector(path: str | Path, *, name: str | None = None) -> Iterator[tuple[str, str]]:
    """(a path GDAL may open, driver) for a delivered vector file, leaving the delivery untouched.

    A GeoPackage is copied (with its ``-wal``) to a temporary folder outside the delivery and read
    there: SQLite would otherwise checkpoint and delete the delivered ``-wal`` even on a read-only
    open. A shapefile is read in place (the driver writes nothing when reading).
    """
    label = name or str(path)
    driver = vector_driver(path, label)
    if driver != "GPKG":
        yield str(path), driver
        return
    with tempfile.TemporaryDirectory(prefix="orthospec-gpkg-") as tmp:
        local = Path(tmp) / "vector.gpkg"
        try:
            shutil.copyfile(path, local)
            wal = Path(f"{path}-wal")
            if wal.is_file() and not wal.is_symlink():
                shutil.copyfile(wal, Path(f"{local}-wal"))
        except OSError as exc:
            raise MeasureError(f"{label}: cannot read file: {exc.strerror or exc}") from None
        yield str(local), driver


#: Features read at once by :func:`read_vector`: the WKB of one batch is in memory beside the
#: geometries already made, never the whole layer's (a 150,000-polygon seamline layer).
VECTOR_BATCH = 20_000


def read_vector(
    path: str | Path, *, name: str | None = None, batch: int = VECTOR_BATCH
) -> tuple[list[Any], str | None]:
    """Geometries (shapely) and CRS (WKT/authority string) of a vector file, with pyogrio, read in
    batches of ``batch`` features (no attribute columns: only the geometries are measured)."""
    import pyogrio
    import shapely

    label = name or str(path)
    geoms: list[Any] = []
    crs = None
    with (
        readable_vector(path, name=label) as (local, _driver),
        gdal_errors(file=label, path=local, what="vector file"),
    ):
        total = pyogrio.read_info(local).get("features", -1)
        skip = 0
        while True:
            meta, _fids, geometry, _fields = pyogrio.raw.read(
                local, columns=[], skip_features=skip, max_features=batch
            )
            crs = meta.get("crs")
            n = 0 if geometry is None else len(geometry)
            if n:
                geoms.extend(g for g in shapely.from_wkb(geometry) if g is not None)
            del geometry
            skip += n
            if n < batch or (total >= 0 and skip >= total):
                break
    return geoms, crs


@dataclass(frozen=True)
class OverlapPixels:
    """Mean DN of each band of two orthos over their common, jointly valid pixels."""

    bands: tuple[int, ...]
    mean_a: tuple[float, ...]
    mean_b: tuple[float, ...]
    pixels: int


def overlap_means(
    path_a: str | Path,
    path_b: str | Path,
    *,
    bands: Sequence[int] | None = None,
    settings: ScanSettings | None = None,
) -> OverlapPixels:
    """Stream the overlap strip of two adjacent orthos on the grid of ``path_a``.

    Both must share the CRS; ``path_b`` is read with nearest resampling onto ``path_a``'s
    pixels of the common extent. Pixels valid in both (GDAL masks) are averaged.
    """
    s = settings or ScanSettings()
    with (
        read_only_env(s),
        open_read_only(path_a) as a,
        open_read_only(path_b) as b,
        gdal_errors(file=f"{path_a} / {path_b}", what="overlap of two rasters"),
    ):
        if a.crs != b.crs:
            raise MeasureError(f"{path_a} and {path_b} have different CRS ({a.crs} vs {b.crs})")
        left = max(a.bounds.left, b.bounds.left)
        right = min(a.bounds.right, b.bounds.right)
        bottom = max(a.bounds.bottom, b.bounds.bottom)
        top = min(a.bounds.top, b.bounds.top)
        if right <= left or top <= bottom:
            raise MeasureError(f"{path_a} and {path_b} do not overlap")
        idx = list(bands or range(1, min(a.count, b.count) + 1))
        wa = a.window(left, bottom, right, top).round_offsets().round_lengths()
        wa = wa.intersection(Window(0, 0, a.width, a.height))
        sums_a = np.zeros(len(idx))
        sums_b = np.zeros(len(idx))
        n = 0
        rows = max(1, s.chunk_bytes // max(int(wa.width) * 8 * len(idx), 1))
        for r0 in range(int(wa.row_off), int(wa.row_off + wa.height), rows):
            h = min(rows, int(wa.row_off + wa.height) - r0)
            sub = Window(wa.col_off, r0, wa.width, h)
            da = a.read(idx, window=sub, masked=True)
            ba = rasterio.windows.bounds(sub, a.transform)
            wb = b.window(*ba)
            db = b.read(
                idx,
                window=wb,
                out_shape=(len(idx), h, int(wa.width)),
                boundless=True,
                masked=True,
                resampling=rasterio.enums.Resampling.nearest,
            )
            ok = ~(np.ma.getmaskarray(da).any(axis=0) | np.ma.getmaskarray(db).any(axis=0))
            n += int(ok.sum())
            sums_a += np.asarray(da.data[:, ok], dtype=np.float64).sum(axis=1)
            sums_b += np.asarray(db.data[:, ok], dtype=np.float64).sum(axis=1)
        if n == 0:
            raise MeasureError(f"{path_a} and {path_b} have no jointly valid overlap pixels")
        return OverlapPixels(
            bands=tuple(idx), mean_a=tuple(sums_a / n), mean_b=tuple(sums_b / n), pixels=n
        )


def read_window_array(
    path: str | Path,
    *,
    size: int = 1024,
    bands: Sequence[int] | None = None,
    bounds: tuple[float, float, float, float] | None = None,
    out_shape: tuple[int, int] | None = None,
) -> np.ndarray:
    """A central (or given-bounds) window as float64, for sharpness comparisons."""
    with (
        read_only_env(),
        open_read_only(path) as ds,
        gdal_errors(file=path, what="raster (pixels)"),
    ):
        idx = list(bands or range(1, ds.count + 1))
        if bounds is not None:
            win = ds.window(*bounds)
        else:
            n_r, n_c = min(size, ds.height), min(size, ds.width)
            win = Window((ds.width - n_c) // 2, (ds.height - n_r) // 2, n_c, n_r)
        shape = None if out_shape is None else (len(idx), *out_shape)
        return ds.read(
            idx,
            window=win,
            out_shape=shape,
            boundless=bounds is not None,
            resampling=rasterio.enums.Resampling.nearest,
        ).astype(np.float64)


def window_bounds(path: str | Path, size: int = 1024) -> tuple[float, float, float, float]:
    """Ground bounds of the central ``size`` window of a raster."""
    with read_only_env(), open_read_only(path) as ds:
        n_r, n_c = min(size, ds.height), min(size, ds.width)
        win = Window((ds.width - n_c) // 2, (ds.height - n_r) // 2, n_c, n_r)
        return tuple(rasterio.windows.bounds(win, ds.transform))  # type: ignore[return-value]


def pan_fused_windows(
    pan_path: str | Path, fused_path: str | Path, *, size: int = 1024
) -> tuple[np.ndarray, np.ndarray]:
    """The central PAN window and the fused product over the same ground, on the PAN grid."""
    b = window_bounds(pan_path, size)
    pan = read_window_array(pan_path, bands=[1], bounds=b)
    fused = read_window_array(fused_path, bounds=b, out_shape=pan.shape[1:])
    return pan[0], fused


def seamline_check(seamlines_path: str | Path, aoi_path: str | Path) -> Any:
    """Read seamline and AOI vector files and measure gaps/overlaps (``SeamlineCoverage``).

    Raises
    ------
    MeasureError
        when a file is missing or unreadable, or holds no polygon.
    """
    import shapely

    from ..measures.mosaic import seamline_coverage

    parts = []
    for label, p in (("seamline", seamlines_path), ("area-of-interest", aoi_path)):
        try:
            geoms, _crs = read_vector(p)
        except MeasureError as exc:
            raise MeasureError(f"{label} file unreadable: {exc}") from exc
        if not geoms:
            raise MeasureError(f"{p}: {label} file holds no geometry")
        parts.append(geoms)
    return seamline_coverage(parts[0], shapely.union_all(parts[1]))
