"""The counting helper thread belongs to the caller (issue 28 item 2): measures/counting.py starts no
thread; a scan lends one (raster/scan.py) and only to the thread that counts alone."""

from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import pytest
from tests.test_raster_reading import write_tif

from orthospec.measures import counting
from orthospec.raster import scan as scan_module
from orthospec.raster.scan import ScanSettings, helper_pool, scan_raster


class CountingPool(ThreadPoolExecutor):
    """A one-thread pool that counts the tasks it was given."""

    def __init__(self) -> None:
        super().__init__(max_workers=1)
        self.tasks = 0

    def submit(self, fn, /, *args, **kwargs) -> Future:  # type: ignore[no-untyped-def, override]
        self.tasks += 1
        return super().submit(fn, *args, **kwargs)


@pytest.mark.parametrize(
    ("dtype", "size"),
    [
        ("uint16", counting.PARALLEL_BINCOUNT_MIN * 2 + 7),
        ("uint8", counting.PARALLEL_BINCOUNT_MIN * 3 + 1),
    ],
)
def test_a_lent_helper_counts_half_and_the_counts_are_numpys(dtype, size):
    a = np.random.default_rng(size).integers(
        0, np.iinfo(dtype).max, size, endpoint=True, dtype=dtype
    )
    bins = np.iinfo(dtype).max + 1
    want = np.bincount(a, minlength=bins)
    with CountingPool() as pool:
        assert np.array_equal(counting.numpy_bincount(a, bins), want)
        assert pool.tasks == 0  # nothing lent: counted in this thread alone
        with counting.counting_helper(pool):
            assert np.array_equal(counting.numpy_bincount(a, bins), want)
        assert pool.tasks == 1
        assert np.array_equal(counting.numpy_bincount(a, bins), want)  # the loan ended
        assert pool.tasks == 1


def test_a_helper_is_lent_to_the_entering_thread_only():
    a = np.arange(counting.PARALLEL_BINCOUNT_MIN * 2, dtype=np.uint16)
    got: list[np.ndarray] = []
    with CountingPool() as pool, counting.counting_helper(pool):
        t = threading.Thread(target=lambda: got.append(counting.numpy_bincount(a, 65536)))
        t.start()
        t.join()
        assert pool.tasks == 0
    assert np.array_equal(got[0], np.bincount(a, minlength=65536))


def test_the_scan_owns_one_helper_per_process():
    pool = helper_pool()
    assert pool is helper_pool()
    assert pool is None or isinstance(pool, ThreadPoolExecutor)


def test_a_scan_counting_in_one_thread_gives_what_two_threads_give(tmp_path, monkeypatch):
    """16-bit chunks of 1.4 Mpx a band: bincount with the scan's helper (one counting thread) or
    alone (two counting threads), the same statistics."""
    rng = np.random.default_rng(7)
    data = rng.integers(0, 4096, (3, 1024, 2048), dtype=np.uint16)
    path = write_tif(tmp_path / "u16.tif", data, tiled=True, blockxsize=256, blockysize=256)
    with CountingPool() as pool:
        monkeypatch.setattr(scan_module, "helper_pool", lambda: pool)
        one = scan_raster(path, ScanSettings(threads=1, noise=False, misregistration=False))
        lent = pool.tasks
        two = scan_raster(path, ScanSettings(threads=2, noise=False, misregistration=False))
        if (os.cpu_count() or 1) >= 2:
            assert lent > 0 and pool.tasks == lent  # lent to the lone counting thread only
    assert one.to_dict() == two.to_dict()
    for k, b in enumerate(one.bands):
        assert b.mean == pytest.approx(float(data[k].mean()), rel=1e-12)
        assert b.histogram is not None
        assert sum(b.histogram.counts) == data[k].size
