"""Batch scans: worker processes, Dask, cache by checksum, progress, bad files in a batch."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

from orthospec.errors import MeasureError
from orthospec.raster import parallel, reading
from orthospec.raster.cache import ResultCache
from orthospec.raster.parallel import PlainProgress, make_progress, scan_images

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
RGB = REAL / "RGB.byte.tif"


def write(path: Path, seed: int, size: int = 96) -> Path:
    a = np.random.default_rng(seed).integers(1, 256, (3, size, size), dtype=np.uint8)
    with rasterio.open(path, "w", driver="GTiff", width=size, height=size, count=3,
                       dtype="uint8", crs="EPSG:25832", nodata=0,
                       transform=Affine(0.5, 0, 5e5, 0, -0.5, 6e6)) as ds:
        ds.write(a)
    return path


@pytest.fixture
def delivery(tmp_path):
    d = tmp_path / "delivery"
    d.mkdir()
    files = [write(d / f"img_{i}.tif", i) for i in range(4)]
    bad = d / "broken.tif"
    bad.write_bytes(b"II*\x00garbage")
    return files, bad


def _comparable(reports):
    return [{k: v for k, v in r.to_dict().items() if k != "cached"} for r in reports]


def test_processes_equal_in_process_and_keep_input_order(delivery):
    files, bad = delivery
    paths = [*files[:2], bad, *files[2:]]
    one = scan_images(paths, workers=1)
    two = scan_images(paths, workers=2)
    assert [r.path for r in two] == [str(p) for p in paths]
    assert _comparable(one) == _comparable(two)
    assert two[2].error and "broken.tif" in two[2].error
    assert all(r.error is None for i, r in enumerate(two) if i != 2)


def test_worker_reports_are_not_kept_once_taken(tmp_path):
    """With ``on_report`` a report lives only while it is being taken: at most the window of tasks
    in flight is alive at any time, whatever the number of images (all images' reports were kept
    until the last one finished: about 25 KB an image at 4,000 images)."""
    import gc
    import weakref

    files = [write(tmp_path / f"img_{i}.tif", i, size=16) for i in range(40)]
    taken: list[weakref.ref] = []
    alive_max = 0

    def on_report(i, rep):
        nonlocal alive_max
        gc.collect()
        alive_max = max(alive_max, sum(r() is not None for r in taken))
        taken.append(weakref.ref(rep))

    assert scan_images(files, workers=2, on_report=on_report) == []
    assert len(taken) == len(files)
    window = parallel.IN_FLIGHT_PER_WORKER * 2
    assert alive_max <= window < len(files) // 2


def test_flat_report_has_band_and_image_keys(delivery):
    files, _ = delivery
    d = scan_images([files[0]], workers=1, expect_epsg=25832, expect_gsd=0.5)[0].to_dict()
    for k in ("band1.mean", "band3.std", "band2.histogram", "band1.saturation_high_pct",
              "band1.cv_percent", "band1.nodata_fraction", "luminosity.mean",
              "image.saturation_high_pct", "driver", "crs_ok", "gsd_ok", "sha256"):
        assert k in d, k
    assert d["crs_ok"] is True and d["gsd_ok"] is True
    assert d["statistics"] == "exact, population std, nodata excluded per band, as GDAL"
    json.dumps(d)  # JSON-serialisable


def test_cache_reads_only_changed_files(delivery, tmp_path):
    files, _ = delivery
    cache = tmp_path / "cache"
    reading.SCAN_COUNT["scans"] = 0
    parallel.HASH_COUNT["files"] = 0
    first = scan_images(files, workers=1, cache_dir=cache)
    assert reading.SCAN_COUNT["scans"] == 4 and not any(r.cached for r in first)
    assert parallel.HASH_COUNT["files"] == 4
    with ResultCache(cache) as c:
        assert len(c) == 4
    write(files[1], seed=99)  # partial redelivery: one file changed
    second = scan_images(files, workers=1, cache_dir=cache)
    assert reading.SCAN_COUNT["scans"] == 5
    assert parallel.HASH_COUNT["files"] == 5  # unchanged files not even re-hashed
    assert [r.cached for r in second] == [True, False, True, True]
    assert [r.sha256 for r in second] != [r.sha256 for r in first]
    assert [r.sha256 for i, r in enumerate(second) if i != 1] == [
        r.sha256 for i, r in enumerate(first) if i != 1]
    assert second[0].to_dict()["band1.mean"] == first[0].to_dict()["band1.mean"]
    assert second[1].to_dict()["band1.mean"] != first[1].to_dict()["band1.mean"]
    # other settings are another key: everything is read again
    third = scan_images(files, workers=1, cache_dir=cache, bit_depth=7)
    assert reading.SCAN_COUNT["scans"] == 9 and not any(r.cached for r in third)
    # without trust in mtimes every file is hashed again, results still come from the cache
    fourth = scan_images(files, workers=1, cache_dir=cache, trust_mtime=False)
    assert parallel.HASH_COUNT["files"] == 9 and all(r.cached for r in fourth)


def test_cache_hits_in_worker_processes(delivery, tmp_path):
    files, _ = delivery
    cache = tmp_path / "cache"
    scan_images(files, workers=2, cache_dir=cache)
    again = scan_images(files, workers=2, cache_dir=cache)
    assert all(r.cached for r in again)


def test_cache_inside_the_delivery_is_refused(delivery):
    files, _ = delivery
    with pytest.raises(MeasureError, match="outside the delivery"):
        scan_images(files, workers=1, cache_dir=files[0].parent / ".cache")


def test_plain_progress_lines(delivery):
    files, bad = delivery
    out = io.StringIO()
    scan_images([files[0], bad], workers=1, progress=PlainProgress(out))
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("scanning 2 files")
    assert lines[1].startswith("[1/2]") and lines[1].endswith(" s")
    assert lines[2].startswith("[2/2]") and "error:" in lines[2]
    assert isinstance(make_progress(io.StringIO()), PlainProgress)


def test_dask_local_cluster(delivery, tmp_path):
    distributed = pytest.importorskip("distributed")
    from dask import config as dask_config
    files, bad = delivery
    paths = [*files, bad, RGB]
    local = scan_images(paths, workers=1)
    with (dask_config.set({"temporary-directory": str(tmp_path)}),  # no dask-scratch-space in /tmp
          distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                   dashboard_address=None) as cluster):
        remote = scan_images(paths, scheduler=cluster.scheduler_address)
    assert _comparable(remote) == _comparable(local)
    assert remote[4].error is not None


def test_public_api_names_resolve():
    import orthospec.raster as api

    assert api.__all__ == sorted(api.__all__)
    for name in api.__all__:
        assert getattr(api, name) is not None
    with pytest.raises(AttributeError):
        api.no_such_name  # noqa: B018


def test_tune_allocator_sets_the_trim_threshold():
    from orthospec.raster.parallel import tune_allocator

    assert tune_allocator(1 << 30) is True  # glibc on this platform accepts M_TRIM_THRESHOLD


def test_check_through_dask_gives_byte_identical_qcr_json(tmp_path):
    """Issue 14 item 5: `check --scheduler` (a distributed LocalCluster, in-process workers) writes
    the very bytes of the local run's qcr.json for the same delivery and --date."""
    distributed = pytest.importorskip("distributed")
    from dask import config as dask_config

    from orthospec.cli.main import main

    example = Path(__file__).resolve().parents[1] / "examples" / "deliveries" / "aerial-pass"
    common = ["check", str(example), "-p", "jrc-v3", "--format", "json", "--date", "2026-11-21",
              "--param", "tolerance_xy=0.5m", "--param", "map_crs=EPSG:25832"]

    def run(*extra: str) -> int:
        with pytest.raises(SystemExit) as exc:
            main([*common, *extra])
        return int(exc.value.code)

    local_code = run("--out", str(tmp_path / "local"), "--workers", "1")
    with (dask_config.set({"temporary-directory": str(tmp_path)}),  # no dask-scratch-space in /tmp
          distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                   dashboard_address=None) as cluster,
          distributed.Client(cluster) as client):
        dask_code = run("--out", str(tmp_path / "dask"), "--scheduler", cluster.scheduler_address)
        done = client.run_on_scheduler(_scan_tasks_done)
    local = (tmp_path / "local" / "qcr.json").read_bytes()
    assert dask_code == local_code
    assert (tmp_path / "dask" / "qcr.json").read_bytes() == local
    n_images = len(list((example / "images").glob("*.tif")))
    assert done >= n_images, "the images were not scanned by the Dask cluster"
    assert json.loads(local)["rules"]  # a real document, not an empty one


def _scan_tasks_done(dask_scheduler) -> int:
    """scan_image tasks the scheduler saw finish (runs on the scheduler)."""
    prefix = dask_scheduler.task_prefixes.get("scan_image")
    return 0 if prefix is None else int(prefix.state_counts.get("forgotten", 0))
