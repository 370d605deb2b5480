"""Read every image's header facts, in parallel, through the one facts reader.

Each image is read by :func:`orthospec.raster.facts.read_facts` (the same function the checks
use): nothing here opens a raster itself. Worker processes take the images in chunks (a header
read is milliseconds; one task per file would spend as long in inter-process traffic), a bounded
window of chunks is in flight, and results come back in listing order, so memory does not grow
with the number of images and the draft is the same on every run.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future
from dataclasses import dataclass
from multiprocessing.context import BaseContext

from ..raster.facts import RasterFacts, read_facts

#: images per task: amortises the process round trip over a few dozen header reads
CHUNK = 32
#: chunks in flight per worker
WINDOW_PER_WORKER = 4
#: below this many images the scan runs in this process (starting workers costs more)
SERIAL_BELOW = 64


@dataclass(frozen=True)
class Job:
    """One image to read: its path on disk and the name the draft calls it."""

    path: str
    name: str


def _read_chunk(jobs: Sequence[Job], sha256: bool) -> list[RasterFacts]:
    return [read_facts(j.path, sha256=sha256, name=j.name) for j in jobs]


def _context() -> BaseContext:
    """forkserver where available (workers fork from a server that imported the reader once)."""
    from ..workers import mp_context

    return mp_context(["orthospec.raster.facts"])


def read_all(jobs: Sequence[Job], *, sha256: bool = True, workers: int | None = None,
             on_done: Callable[[RasterFacts], None] | None = None) -> Iterator[RasterFacts]:
    """The facts of every job, in the jobs' order; ``on_done`` is called as each one arrives.

    Parameters
    ----------
    jobs
        the images (path on disk, name in the draft).
    sha256
        hash every file (a full read of each file; off: header facts only).
    workers
        worker processes (default: the CPU count); 1 reads in this process.
    """
    n = workers or os.cpu_count() or 1
    if n <= 1 or len(jobs) < SERIAL_BELOW:
        for j in jobs:
            f = read_facts(j.path, sha256=sha256, name=j.name)
            if on_done:
                on_done(f)
            yield f
        return
    from concurrent.futures import ProcessPoolExecutor

    from ..workers import die_with_parent

    chunks = (jobs[i:i + CHUNK] for i in range(0, len(jobs), CHUNK))
    pending: deque[Future[list[RasterFacts]]] = deque()
    with ProcessPoolExecutor(max_workers=n, mp_context=_context(),
                             initializer=die_with_parent, initargs=(os.getpid(),)) as pool:
        for chunk in chunks:
            pending.append(pool.submit(_read_chunk, chunk, sha256))
            if len(pending) >= WINDOW_PER_WORKER * n:
                yield from _drain(pending.popleft(), on_done)
        while pending:
            yield from _drain(pending.popleft(), on_done)


def _drain(fut: Future[list[RasterFacts]], on_done: Callable[[RasterFacts], None] | None
           ) -> Iterator[RasterFacts]:
    for f in fut.result():
        if on_done:
            on_done(f)
        yield f
