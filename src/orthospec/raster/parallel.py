"""Scan many images at national scale: worker processes or Dask, cache, progress.

``scan_images`` is the public entry point for the rule engine: one :class:`ImageReport` per
path, in input order, each with ``error`` set instead of raising when a file is bad.
Header checks always run (cheap); the pixel scan is skipped when the cache already holds
the result for the file's SHA-256 and the same settings.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager, nullcontext, suppress
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TextIO

import rasterio

from ..errors import MeasureError, OrthospecError
from ..provenance import sha256_file
from .filechecks import checked_file
from .scan import ScanSettings, mask_share, scan_dataset

if TYPE_CHECKING:  # imported where used: `measure radiometry` needs neither processes nor the cache
    import multiprocessing.context

    from .cache import ResultCache

STATISTICS_NOTE = "exact, population std, nodata excluded per band, as GDAL"


@dataclass(frozen=True)
class ScanOptions:
    """Everything a worker needs besides the path (picklable)."""

    settings: ScanSettings = field(default_factory=ScanSettings)
    expect_epsg: int | None = None
    expect_gsd: float | None = None
    gsd_tolerance: float = 0.01
    cache_dir: str | None = None
    trust_mtime: bool = True

    def key(self) -> str:
        return self.settings.key()


@dataclass
class ImageReport:
    """File checks + exact radiometry of one image; ``error`` set when it could not be read."""

    path: str
    sha256: str | None = None
    bytes: int | None = None
    error: str | None = None
    checks: dict[str, Any] = field(default_factory=dict)
    #: the file's header facts (:class:`orthospec.raster.facts.RasterFacts`, ``to_dict``), its SHA-256 included
    facts: dict[str, Any] | None = None
    radiometry: dict[str, Any] | None = None
    cloud_cover_pct: float | None = None
    cached: bool = False
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """Flat mapping: file checks, ``band<i>.<measure>``, ``luminosity.<measure>``,
        ``image.<aggregate>``; histograms stay as nested values under ``*.histogram``."""
        out: dict[str, Any] = {
            "path": self.path,
            "sha256": self.sha256,
            "bytes": self.bytes,
            "error": self.error,
            "cached": self.cached,
            "cloud_cover_pct": self.cloud_cover_pct,
        }
        for k, v in self.checks.items():
            if k not in out:
                out[k] = v
        rad = self.radiometry
        if not rad:
            return out
        out["statistics"] = rad.get("statistics", STATISTICS_NOTE)
        bands = rad.get("bands", [])
        for b in bands:
            for k, v in b.items():
                if k != "band":
                    out[f"band{b['band']}.{k}"] = v
        lum = rad.get("luminosity")
        if lum:
            for k, v in lum.items():
                if k != "band":
                    out[f"luminosity.{k}"] = v
        for idx, m in (rad.get("misregistration") or {}).items():
            out[f"band{idx}.misregistration_px"] = m["magnitude_px"]
            out[f"band{idx}.misregistration_dy_px"] = m["dy_px"]
            out[f"band{idx}.misregistration_dx_px"] = m["dx_px"]
        out.update(_aggregates(bands, lum, rad.get("misregistration") or {}))
        return out


def _aggregates(
    bands: list[dict[str, Any]], lum: dict[str, Any] | None, mis: dict[str, Any]
) -> dict[str, Any]:
    """Image-level values for rules: the luminosity for colour images (§6.3), else worst band."""

    def vals(key: str) -> list[float]:
        return [b[key] for b in bands if b.get(key) is not None]

    def worst(key: str, fn: Callable[[list[float]], float]) -> float | None:
        v = vals(key)
        return fn(v) if v else None

    src = lum if lum else None
    out = {
        "image.saturation_low_pct": (src or {}).get(
            "saturation_low_pct", worst("saturation_low_pct", max)
        ),
        "image.saturation_high_pct": (src or {}).get(
            "saturation_high_pct", worst("saturation_high_pct", max)
        ),
        "image.saturation_low_pct_max_band": worst("saturation_low_pct", max),
        "image.saturation_high_pct_max_band": worst("saturation_high_pct", max),
        "image.cv_percent_min": worst("cv_percent", min),
        "image.cv_percent_max": worst("cv_percent", max),
        "image.std_max": worst("std", max),
        "image.dark_margin_pct_min": worst("dark_margin_pct", min),
        "image.bright_margin_pct_min": worst("bright_margin_pct", min),
        "image.noise_sigma_homogeneous_max": worst("noise_sigma_homogeneous", max),
        "image.nodata_fraction": worst("nodata_fraction", max),
        "image.used_bits_max": worst("used_bits", max),
        "image.misregistration_px_max": max(
            (m["magnitude_px"] for m in mis.values() if m.get("reliable", True)), default=None
        ),
        "image.saturation_low_hidden_by_nodata": any(
            bool(b.get("saturation_low_hidden_by_nodata")) for b in bands
        ),
    }
    nonfinite = vals("nonfinite_pixels")  # float bands only: integer images keep their keys
    if nonfinite:
        out["image.nonfinite_pixels"] = int(sum(nonfinite))
    return out


#: Files at least this big are hashed in a thread while their pixels are scanned (hashlib and
#: GDAL both release the GIL); smaller ones sequentially (a thread costs more than it saves).
HASH_THREAD_BYTES = 4 * 2**20


def scan_image(
    path: str | Path,
    options: ScanOptions | None = None,
    *,
    cloud_mask: str | Path | None = None,
    sha256: Future[str] | None = None,
) -> ImageReport:
    """Check and measure one image; never raises for a bad file.

    A header problem that leaves the pixels readable (no CRS, identity geotransform) is kept in
    ``error`` but the pixels are still measured: ``radiometry`` is set (callers that need no
    georeference, such as ``measure radiometry``, report it as a file-check finding).
    ``sha256`` is the file's hash already being computed by the caller (``measure radiometry``
    starts it before importing the raster stack, so the hash costs no wall time at all).
    """
    o = options or ScanOptions()
    t0 = time.perf_counter()
    p = str(path)
    with checked_file(
        p,
        expect_epsg=o.expect_epsg,
        expect_gsd=o.expect_gsd,
        gsd_tolerance=o.gsd_tolerance,
        settings=o.settings,
    ) as (checks, ds):
        rep = ImageReport(
            path=p,
            bytes=checks.bytes,
            checks=checks.to_dict(),
            error=checks.error,
            facts=None if checks.facts is None else checks.facts.to_dict(),
        )
        if checks.error is not None and checks.bytes in (None, 0):
            rep.seconds = time.perf_counter() - t0
            return rep
        raster = ds is not None and not (checks.error is not None and checks.driver is None)
        # With a result cache the hash decides whether to scan at all: compute it first. Without
        # one, hash a big file in a thread while its pixels are scanned (one pass of wall time).
        alongside = (
            sha256 is None
            and raster
            and not o.cache_dir
            and (checks.bytes or 0) >= HASH_THREAD_BYTES
        )
        with ThreadPoolExecutor(max_workers=1) if alongside else nullcontext() as pool:
            hashing = (
                sha256
                if sha256 is not None
                else (pool.submit(_file_hash, p, o) if pool is not None else None)
            )
            if hashing is None or not raster or o.cache_dir:  # the hash is needed first
                try:
                    rep.sha256 = _file_hash(p, o) if hashing is None else hashing.result()
                except OSError as exc:
                    rep.error = f"{p}: cannot read file: {exc.strerror or exc}"
                    return rep
                hashing = None
            if not raster or ds is None:
                if rep.facts is not None:
                    rep.facts["sha256"] = rep.sha256
                rep.seconds = time.perf_counter() - t0
                return rep  # not a raster at all: nothing more to measure
            _measure_pixels(rep, p, o, ds)
            if hashing is not None:
                try:
                    rep.sha256 = hashing.result()
                except OSError as exc:
                    rep.error, rep.radiometry = (
                        f"{p}: cannot read file: {exc.strerror or exc}",
                        None,
                    )
                    return rep
    if rep.facts is not None:
        rep.facts["sha256"] = rep.sha256
    if cloud_mask is not None and rep.error is None:
        try:
            rep.cloud_cover_pct = mask_share(cloud_mask, settings=o.settings).percent
        except OrthospecError as exc:  # refused or unreadable (reading.gdal_errors maps GDAL's)
            rep.error = f"{cloud_mask}: cloud mask unreadable: {exc}"
    rep.seconds = time.perf_counter() - t0
    return rep


def _measure_pixels(
    rep: ImageReport, p: str, o: ScanOptions, ds: rasterio.io.DatasetReader
) -> None:
    """Radiometry from the cache (by SHA-256 and settings) or from one scan of the open dataset."""
    cached = None
    if o.cache_dir and rep.sha256:
        from .cache import ResultCache

        with ResultCache(o.cache_dir, read_only=True) as cache:
            cached = cache.get(rep.sha256, o.key())
    if cached is not None:
        rep.radiometry, rep.cached = cached, True
        return
    try:
        rep.radiometry = scan_dataset(ds, o.settings, file=p).to_dict()
    except OrthospecError as exc:  # refused or unreadable: reading.gdal_errors maps GDAL's errors
        rep.error = str(exc) if p in str(exc) else f"{p}: {exc}"
    except Exception as exc:
        # Deliberately broad, documented: a GDAL driver or numpy can still surprise us on one
        # exotic file, and one file must not stop a national batch. Never swallowed: the
        # exception's type and text become this image's error, which reaches its records.
        rep.error = f"{p}: cannot read pixels: {type(exc).__name__}: {exc}"


#: Files hashed in this process (tests check that unchanged files are not re-read).
HASH_COUNT = {"files": 0}


def _stat_key(path: str) -> tuple[str, int, int]:
    st = os.stat(path)
    return str(Path(path).resolve()), st.st_size, st.st_mtime_ns


def _file_hash(path: str, o: ScanOptions) -> str:
    """SHA-256 of the file, or the one remembered for the same path, size and mtime."""
    if o.cache_dir and o.trust_mtime:
        from .cache import ResultCache

        with ResultCache(o.cache_dir, read_only=True) as cache:
            known = cache.get_hash(*_stat_key(path))
        if known:
            return known
    HASH_COUNT["files"] += 1
    return sha256_file(path)


# --------------------------------------------------------------------------- progress


class Progress(Protocol):
    """Callback interface: the CLI chooses rich (TTY) or plain lines."""

    def start(self, files: int, total_bytes: int) -> None: ...
    def advance(self, report: ImageReport) -> None: ...
    def close(self) -> None: ...


class PlainProgress:
    """One line per file: ``[i/n] path bytes status`` (logs, CI, pipes)."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.n = self.i = 0

    def start(self, files: int, total_bytes: int) -> None:
        self.n = files
        print(f"scanning {files} files, {total_bytes / 2**20:.1f} MiB", file=self.stream)

    def advance(self, report: ImageReport) -> None:
        self.i += 1
        status = (
            "error: " + report.error
            if report.error
            else ("cached" if report.cached else f"ok {report.seconds:.2f} s")
        )
        size = f"{(report.bytes or 0) / 2**20:.1f} MiB"
        print(f"[{self.i}/{self.n}] {report.path} {size} {status}", file=self.stream, flush=True)

    def close(self) -> None:
        self.stream.flush()


class RichProgress:
    """One rich progress line: ``scanning [bar] 2/3 files  2.1/3.1 MB  5.0 MB/s  0:00:01``.

    A single task counts bytes (the bar and the ETA follow the data read); the file count is a
    field of that task, so each number carries its own unit (two tasks with shared columns
    printed ``2/3 files 2/3 bytes``).
    """

    def __init__(self, console: Any = None) -> None:
        from rich.progress import (
            BarColumn,
            DownloadColumn,
            Progress,
            TextColumn,
            TimeRemainingColumn,
            TransferSpeedColumn,
        )

        self._p = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.fields[files_done]}/{task.fields[files]} files"),
            DownloadColumn(),
            TransferSpeedColumn(),
            TimeRemainingColumn(),
            console=console,
        )
        self._task: Any = None
        self._done = 0

    def start(self, files: int, total_bytes: int) -> None:
        self._p.start()
        self._task = self._p.add_task("scanning", total=total_bytes, files=files, files_done=0)

    def advance(self, report: ImageReport) -> None:
        self._done += 1
        self._p.update(self._task, advance=report.bytes or 0, files_done=self._done)

    def close(self) -> None:
        self._p.stop()


def make_progress(stream: TextIO | None = None) -> Progress:
    """Rich bar on a terminal, plain lines otherwise."""
    s = stream or sys.stderr
    return RichProgress() if s.isatty() else PlainProgress(s)


# --------------------------------------------------------------------------- batch


_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@contextmanager
def _one_thread_per_worker() -> Iterator[None]:
    """Start worker processes with single-threaded BLAS/OpenMP (as Dask's nanny does).

    N processes each spinning N BLAS threads oversubscribe the cores; the variables are set
    only while the workers are launched and restored afterwards (user settings are kept).
    """
    saved = {k: os.environ.get(k) for k in _THREAD_VARS}
    for k in _THREAD_VARS:
        os.environ.setdefault(k, "1")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _mp_context() -> multiprocessing.context.BaseContext:
    """forkserver where available: workers fork from a clean server that has already
    imported orthospec (fast start, no inherited threads or GDAL handles); else spawn."""
    from ..workers import mp_context

    return mp_context(["orthospec.raster.parallel", "pyproj"])


def _check_cache_outside(cache_dir: Path, paths: Sequence[str]) -> None:
    """Refuse a cache in (or below) an image's folder, or one that holds an image."""
    c = cache_dir.resolve()
    for p in paths:
        parent = Path(p).resolve().parent
        if parent == c or c in parent.parents or parent in c.parents:
            raise MeasureError(
                f"cache directory {cache_dir} contains the image {p}; "
                "put the cache outside the delivery"
            )


def scan_images(
    paths: Sequence[str | Path],
    *,
    workers: int | None = None,
    scheduler: Any = None,
    cache_dir: str | Path | None = None,
    bit_depth: int | None = None,
    progress: Progress | None = None,
    expect_epsg: int | None = None,
    expect_gsd: float | None = None,
    gsd_tolerance: float = 0.01,
    cloud_masks: Mapping[str, str | Path] | None = None,
    settings: ScanSettings | None = None,
    trust_mtime: bool = True,
    on_report: Callable[[int, ImageReport], None] | None = None,
) -> list[ImageReport]:
    """Check and measure many images; results in input order, bad files as ``error``.

    Parameters
    ----------
    paths
        image files.
    workers
        worker processes (default: CPU count); 1 runs in this process.
    scheduler
        a Dask distributed scheduler address (``"tcp://host:8786"``), ``Client`` or cluster
        object; when given, tasks go to Dask instead of local processes.
    cache_dir
        directory of the result cache, outside the delivery.
    bit_depth
        declared radiometric resolution overriding NBITS / dtype (e.g. 11 for 11-bit data).
    progress
        :class:`Progress` callbacks (see :func:`make_progress`).
    trust_mtime
        with a cache, reuse the SHA-256 of a file whose absolute path, size and modification
        time are unchanged instead of reading it again (False: hash every file every run).
    on_report
        called with (index in ``paths``, report) as each image completes (completion order);
        the reports are then not kept, so memory does not grow with the number of images.

    Returns
    -------
    list[ImageReport]
        one per path, in input order; unreadable files have ``error`` set. Empty when
        ``on_report`` is given.

    Raises
    ------
    MeasureError
        when ``cache_dir`` lies inside an image's folder.
    OrthospecError
        when ``scheduler`` is given and the ``[dask]`` extra is not installed.
    """
    if scheduler is not None:
        require_dask()
    p_list = [str(p) for p in paths]
    s = settings or ScanSettings()
    if bit_depth is not None:
        s = replace(s, bit_depth=bit_depth)
    if cache_dir is not None:
        _check_cache_outside(Path(cache_dir), p_list)
    opts = ScanOptions(
        settings=s,
        expect_epsg=expect_epsg,
        expect_gsd=expect_gsd,
        gsd_tolerance=gsd_tolerance,
        cache_dir=None if cache_dir is None else str(cache_dir),
        trust_mtime=trust_mtime,
    )
    masks = {str(k): str(v) for k, v in (cloud_masks or {}).items()}
    sizes = []
    for p in p_list:
        try:
            sizes.append(Path(p).stat().st_size)
        except OSError:
            sizes.append(0)
    if progress:
        progress.start(len(p_list), sum(sizes))
    results: list[ImageReport | None] = [None] * (0 if on_report else len(p_list))
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from itertools import islice

    from ..workers import die_with_parent
    from .cache import ResultCache

    # results enter the cache as they come (only this process writes it; workers read it)
    cache = ResultCache(cache_dir) if cache_dir is not None else None

    def done(i: int, rep: ImageReport) -> None:
        if cache is not None:
            _remember(cache, rep, opts)
        if on_report is not None:
            on_report(i, rep)
        else:
            results[i] = rep
        if progress:
            progress.advance(rep)

    try:
        if scheduler is not None:
            _run_dask(scheduler, p_list, opts, masks, done)
        else:
            n = workers or multiprocessing.cpu_count()
            n = max(1, min(n, len(p_list)))
            if n == 1:
                for i, p in enumerate(p_list):
                    done(i, scan_image(p, opts, cloud_mask=masks.get(p)))
            else:
                ctx = _mp_context()
                # one counting thread per worker process: the processes already fill the cores
                one = replace(opts, settings=replace(opts.settings, threads=1))
                # a bounded window of tasks in flight: a finished future holds its report (the
                # histograms: about 25 KB an image) for as long as something references it, so
                # submitting every image up front kept every report until the last one finished
                todo = iter(enumerate(p_list))
                window = IN_FLIGHT_PER_WORKER * n
                pending: dict[Future[ImageReport], int] = {}

                def submit_more() -> None:
                    for i, p in islice(todo, window - len(pending)):
                        pending[pool.submit(scan_image, p, one, cloud_mask=masks.get(p))] = i

                with ProcessPoolExecutor(
                    max_workers=n,
                    mp_context=ctx,
                    initializer=die_with_parent,
                    initargs=(os.getpid(),),
                ) as pool:
                    with _one_thread_per_worker():  # workers (and the forkserver) start here
                        submit_more()
                    while pending:
                        finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                        for fut in finished:
                            done(pending.pop(fut), fut.result())
                        del finished, fut
                        submit_more()
    finally:
        if progress:
            progress.close()
        if cache is not None:
            cache.close()
    return [r for r in results if r is not None]


def _remember(cache: ResultCache, r: ImageReport, opts: ScanOptions) -> None:
    """Put a fresh result and the file's hash (by path, size and mtime) into the cache."""
    if r.sha256 and r.radiometry is not None and not r.cached:
        cache.put(r.sha256, opts.key(), r.radiometry)
    if r.sha256 and opts.trust_mtime:
        with suppress(OSError):  # the file vanished meanwhile: nothing to keep
            cache.put_hash(*_stat_key(r.path), r.sha256)


#: Tasks queued per worker process: enough that no worker waits for the next path, few enough that
#: finished reports do not pile up (each is dropped once ``done`` has taken it).
IN_FLIGHT_PER_WORKER = 4


#: glibc mallopt parameter: bytes of free heap kept before memory is returned to the OS
_M_TRIM_THRESHOLD = -1


def tune_allocator(trim_threshold: int = 1 << 30) -> bool:
    """Keep freed block buffers in the process instead of trimming after every image.

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``: glibc then gives memory back
    after each large numpy buffer and every block read pays for fresh pages, which measured about
    twice as slow per image as a plain process here. ``mallopt`` changes that at run time.
    """
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("c")
    if not name:
        return False
    try:
        libc = ctypes.CDLL(name)
    except OSError:  # a C library that cannot be loaded: keep the allocator as it is
        return False
    if not hasattr(libc, "mallopt"):
        return False
    return bool(libc.mallopt(_M_TRIM_THRESHOLD, int(trim_threshold)))


DASK_MISSING = (
    "running on a Dask cluster (--scheduler) needs Dask, an optional extra: "
    "install it with  pip install 'orthospec[dask]'"
)


def require_dask() -> None:
    """Raise OrthospecError saying which extra to install when Dask distributed is missing.

    Callers with a scheduler option call it before any work starts (``check --scheduler``).
    """
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise OrthospecError(DASK_MISSING) from None


def _run_dask(
    scheduler: Any,
    paths: list[str],
    opts: ScanOptions,
    masks: dict[str, str],
    done: Callable[[int, ImageReport], None],
) -> None:
    require_dask()
    from distributed import Client
    from distributed import as_completed as dask_completed

    own = not isinstance(scheduler, Client)
    client = scheduler if isinstance(scheduler, Client) else Client(getattr(scheduler, "scheduler_address", scheduler))
    try:
        client.run(tune_allocator)  # False on a worker without glibc: it keeps its allocator
        futs = [
            client.submit(scan_image, p, opts, cloud_mask=masks.get(p), pure=False) for p in paths
        ]
        index = {f.key: i for i, f in enumerate(futs)}
        completed = dask_completed(futs)
        del futs  # as_completed lets each future go once it is yielded: the cluster then releases
        # that report once taken, instead of holding every one until the last image is done
        for fut in completed:
            done(index[fut.key], fut.result())
    finally:
        if own:
            client.close()
