"""Stream rasters block by block into the pure radiometry accumulators: the one read of the pixels.

Why this shape:

* windows are unions of whole internal blocks (:func:`~orthospec.raster.opening.chunk_windows`),
  so memory stays bounded by ``ScanSettings.chunk_bytes`` (8 MB) whatever the image size;
* every pixel is read once: statistics, histograms, noise, luminosity, the pixel facts and the
  misregistration windows (raster/misregistration.py) are all fed from the same chunks (floats
  add one pass for their binned histogram), and the chunks are counted in two threads while a
  third decodes the next one into a recycled buffer; a side thread takes the slow, rare work
  (the noise of the sampled chunks' integer bands, the phase correlation of completed
  misregistration windows) so that it never holds up the counting of the next chunks;
* the scan owns its threads: a scan counting in one thread lends the counting a helper thread
  (:func:`helper_pool`, one per process) for long arrays (measures/counting.py);
* overviews are never used for statistics (plain full-resolution ``read``).
"""

from __future__ import annotations

import math
import os
import threading
from collections import deque
from collections.abc import Sequence
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import rasterio
from rasterio.windows import Window

from ..measures.counting import counting_helper
from ..measures.histogram import (
    BandStats,
    BinnedHistogramAccumulator,
    MaskShareAccumulator,
    band_stats_from_histogram,
    band_stats_from_moments,
)
from ..measures.noise import NoiseAccumulator
from .accumulators import ScanAccumulators
from .misregistration import MisregistrationWindows
from .opening import (
    BandInfo,
    band_infos,
    chunk_windows,
    gdal_errors,
    open_read_only,
    read_only_env,
    validity,
)
from .stats import RasterStats, ScanSettings

#: Counter of full raster scans in this process (tests use it to check the cache).
SCAN_COUNT = {"scans": 0}


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
    acc = ScanAccumulators.for_bands(infos, s, ds)
    capture = (
        MisregistrationWindows.plan(ds, infos) if s.misregistration and ds.count >= 2 else None
    )
    chunks = _stream(ds, infos, s, acc, capture)
    binned = _binned_histograms(ds, infos, acc, s)  # floats / 32-bit only
    bands: list[BandStats] = []
    for b in infos:
        nz = acc.noise.get(b.index)
        if b.index in acc.hists:
            h = acc.hists[b.index]
            if not b.use_mask:
                h.exclude_value(b.nodata)
            bands.append(
                band_stats_from_histogram(
                    str(b.index), b.dtype, h, b.grey, noise=nz, nodata=b.nodata
                )
            )
        else:
            ec = acc.edge_counts[b.index]
            bands.append(
                band_stats_from_moments(
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
        lum_stats = band_stats_from_histogram("luminosity", first.dtype, acc.lum, first.grey)
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


def helper_pool() -> Executor | None:
    """The counting helper thread of this process (re-created after a fork: threads do not
    survive it); None on a single core. Lent to the counting of a scan that counts in one thread
    (:func:`~orthospec.measures.counting.counting_helper`)."""
    if (os.cpu_count() or 1) < 2:
        return None
    if _helper["pid"] != os.getpid():
        _helper["pool"] = ThreadPoolExecutor(max_workers=1, thread_name_prefix="orthospec-count")
        _helper["pid"] = os.getpid()
    return _helper["pool"]


_helper: dict[str, Any] = {"pid": None, "pool": None}


def _stream(
    ds: rasterio.io.DatasetReader,
    infos: Sequence[BandInfo],
    s: ScanSettings,
    acc: ScanAccumulators,
    capture: MisregistrationWindows | None,
) -> int:
    """The one read of the pixels: feed every chunk to ``acc`` and ``capture``; the chunk count.

    A reader thread decodes the next chunks (GDAL releases the GIL) while up to ``s.threads``
    threads count the previous ones (numpy and Pillow release it too); only the reader touches
    the dataset. At most :data:`CHUNKS_IN_FLIGHT` chunks are in memory at once.
    """
    stream = _ChunkStream(ds, infos, s, acc, capture, list(chunk_windows(ds, s.chunk_bytes)))
    if len(stream.wins) <= 1:  # one chunk (a small image): no thread to start and hand off to
        for k, win in enumerate(stream.wins):
            stream.slots.acquire()
            stream.feed(k, win, *stream.fetch(win))
    else:
        stream.run_threaded()
    for other in stream.accs[1:]:
        acc.merge(other)
    return len(stream.wins)


class _ChunkStream:
    """The state of one :func:`_stream`: chunk windows, recycled buffers, threads."""

    def __init__(
        self,
        ds: rasterio.io.DatasetReader,
        infos: Sequence[BandInfo],
        s: ScanSettings,
        acc: ScanAccumulators,
        capture: MisregistrationWindows | None,
        wins: list[Window],
    ) -> None:
        self.ds, self.infos, self.acc, self.capture, self.wins = ds, infos, acc, capture, wins
        self.stride = 1
        if acc.noise and s.noise_max_pixels:
            self.stride = max(1, math.ceil(ds.width * ds.height / s.noise_max_pixels))
        self.mask_band = next((b.index for b in infos if b.use_mask), None)
        # Chunk arrays are recycled: a counted chunk's buffer receives a later chunk. A fresh array
        # per chunk is fresh memory that the kernel zeroes and maps page by page, and takes back
        # when it is freed: about 5 % of the CPU of a full scan. The values are the same (GDAL
        # writes every element of the window into ``out``, in the dtype ``read`` chose before).
        self.largest = max((ds.count * int(w.height) * int(w.width) for w in wins), default=0)
        self.free: list[
            np.ndarray
        ] = []  # flat buffers of ``largest`` elements, their chunk counted
        self.free_lock = threading.Lock()
        self.dtype: list[np.dtype] = []  # the dtype read() picks, from the first chunk
        # chunk k goes to accumulator set k % 2 and is counted by thread k % threads, in chunk
        # order within each set, whatever the number of threads: the floating-point sums (noise,
        # float moments) do not depend on the machine's cores or on timing
        self.accs = (acc, ScanAccumulators.for_bands(infos, s, ds)) if len(wins) > 1 else (acc,)
        self.threads = max(1, min(s.threads, os.cpu_count() or 1, len(self.accs), len(wins)))
        self.slots = threading.Semaphore(max(CHUNKS_IN_FLIGHT, self.threads + 1))
        # The noise estimators of a sampled chunk take several times a chunk's counting: in the
        # counting thread they would hold up its next chunks and, through the chunks in flight,
        # the reader and the other thread. Integer bands' noise (exact integer sums) goes to a
        # side thread instead, into one accumulator per chunk merged at the end.
        self.side: list[ThreadPoolExecutor] = []  # the side thread of a threaded scan
        self.noise_jobs: list[Future[list[tuple[int, NoiseAccumulator]]]] = []

    def fetch(self, win: Window) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """(chunk, shared mask, the chunk's recyclable flat buffer or None)."""
        ds = self.ds
        # GDAL masks of one dataset (per-dataset mask or alpha) are shared by its bands
        mask = ds.read_masks(self.mask_band, window=win) if self.mask_band is not None else None
        with self.free_lock:
            buf = self.free.pop() if self.free else None
        if buf is None:
            if (
                not self.dtype or len(self.wins) <= 1
            ):  # the first chunk: read() allocates, picks the dtype
                data = ds.read(window=win)
                self.dtype.append(data.dtype)
                flat = (
                    data.reshape(-1)
                    if data.size == self.largest and data.flags.c_contiguous
                    else None
                )
                return data, mask, flat
            buf = np.empty(
                self.largest, dtype=self.dtype[0]
            )  # none free yet: the pool grows by one
        shape = (ds.count, int(win.height), int(win.width))
        out = buf[: shape[0] * shape[1] * shape[2]].reshape(shape)
        return ds.read(window=win, out=out), mask, buf

    def done(self, buf: np.ndarray | None) -> None:
        """A chunk is counted: its buffer may take another chunk (nothing keeps a view of it:
        the misregistration capture copies), its slot another read."""
        if buf is not None:
            with self.free_lock:
                self.free.append(buf)
        self.slots.release()

    def noise_of(
        self, work: list[tuple[int, np.ndarray, np.ndarray | None]], buf: np.ndarray | None
    ) -> list[tuple[int, NoiseAccumulator]]:
        try:
            out = []
            for idx, band, valid in work:
                part = NoiseAccumulator()
                part.add(band, valid)
                out.append((idx, part))
            return out
        finally:
            self.done(buf)

    def feed(
        self,
        k: int,
        win: Window,
        data: np.ndarray,
        mask: np.ndarray | None,
        buf: np.ndarray | None,
    ) -> None:
        later: list[tuple[int, np.ndarray, np.ndarray | None]] | None = [] if self.side else None
        handed = False
        try:
            # counting threads that run in parallel count alone; a lone one gets the helper
            with counting_helper(None if self.threads > 1 else helper_pool()):
                self.accs[k % len(self.accs)].add(
                    data, mask, noise=k % self.stride == 0, later=later, win=win
                )
            if self.capture is not None:
                self.capture.take(win, data, mask)  # disjoint parts of the windows: safe in threads
            if later:
                with self.free_lock:
                    self.noise_jobs.append(self.side[0].submit(self.noise_of, later, buf))
                handed = True  # the side thread releases the chunk
        finally:
            if not handed:
                self.done(buf)

    def run_threaded(self) -> None:
        """Read in one thread, count in ``threads`` others, the slow work in a side thread."""
        wins, threads = self.wins, self.threads
        with ThreadPoolExecutor(max_workers=1) as reader, ExitStack() as stack:
            # the side thread (noise, misregistration windows): shut down after the counting
            # threads that feed it
            self.side.append(stack.enter_context(ThreadPoolExecutor(max_workers=1)))
            if self.capture is not None:
                self.capture.correlator = self.side[0]
            counters = [
                stack.enter_context(ThreadPoolExecutor(max_workers=1)) for _ in range(threads)
            ]
            queued: deque[Future[None]] = deque()
            self.slots.acquire()
            pending = reader.submit(self.fetch, wins[0])
            for k, win in enumerate(wins):
                data, shared_mask, buf = pending.result()
                if k + 1 < len(wins):
                    self.slots.acquire()  # waits while CHUNKS_IN_FLIGHT chunks are not counted yet
                    pending = reader.submit(self.fetch, wins[k + 1])
                queued.append(
                    counters[k % threads].submit(self.feed, k, win, data, shared_mask, buf)
                )
                while queued and queued[0].done():
                    queued.popleft().result()  # a counting error stops the scan early
            for fut in queued:
                fut.result()
            for job in self.noise_jobs:  # exact integer sums: any order gives the same bits
                for idx, part in job.result():
                    self.acc.noise[idx].merge(part)


def _binned_histograms(
    ds: rasterio.io.DatasetReader, infos: Sequence[BandInfo], acc: ScanAccumulators, s: ScanSettings
) -> dict[int, BinnedHistogramAccumulator]:
    """Float and 32-bit bands: a second pass for the equal-bin histogram between the exact
    min and max (only known after the first); integer bands up to 16 bits need none."""
    binned = {idx: BinnedHistogramAccumulator(m.vmin, m.vmax) for idx, m in acc.moms.items() if m.n}
    if not binned:
        return binned
    idxs = sorted(binned)
    for win in chunk_windows(ds, s.chunk_bytes):
        data = ds.read(indexes=idxs, window=win)
        for k, idx in enumerate(idxs):
            b = infos[idx - 1]
            mask = ds.read_masks(idx, window=win) if b.use_mask else None
            binned[idx].add(data[k], validity(data[k], b, mask))
    return binned


def _mask(ds: rasterio.io.DatasetReader, info: BandInfo, win: Window) -> np.ndarray | None:
    return ds.read_masks(info.index, window=win) if info.use_mask else None


def mask_share(path: str | Path, *, settings: ScanSettings | None = None) -> MaskShareAccumulator:
    """Share of non-zero pixels of band 1 of a delivered mask raster (nodata excluded)."""
    s = settings or ScanSettings()
    acc = MaskShareAccumulator()
    with read_only_env(s), open_read_only(path) as ds, gdal_errors(file=path, what="mask raster"):
        info = band_infos(ds, None)[0]
        for win in chunk_windows(ds, s.chunk_bytes):
            band = ds.read(1, window=win)
            acc.add(band, validity(band, info, _mask(ds, info, win)))
    return acc
