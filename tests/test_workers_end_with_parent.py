"""Issue 28 item 7: a SIGTERM (or SIGKILL) to a command leaves none of its worker processes running.

Before, `check`'s pool workers outlived the command (one run kept a core busy for 35 minutes)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import rasterio

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deliveries" / "aerial-pass"

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's"
)


def _descendants(pid: int) -> set[int]:
    """Every live descendant of ``pid`` (from /proc), zombies left out."""
    kids: dict[int, list[int]] = {}
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            stat = (p / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if fields[0] == "Z":
            continue
        kids.setdefault(int(fields[1]), []).append(int(p.name))
    out: set[int] = set()
    todo = [pid]
    while todo:
        for k in kids.get(todo.pop(), []):
            if k not in out:
                out.add(k)
                todo.append(k)
    return out


def _alive(pids: set[int]) -> set[int]:
    alive = set()
    for p in pids:
        try:
            state = Path(f"/proc/{p}/stat").read_text()
        except OSError:
            continue
        if state[state.rindex(")") + 2] != "Z":
            alive.add(p)
    return alive


def _wait_for_workers(proc: subprocess.Popen[bytes], n: int, timeout: float) -> set[int]:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        kids = _descendants(proc.pid)
        if len(kids) >= n:
            return kids
        if proc.poll() is not None:
            break
        time.sleep(0.05)
    pytest.fail(f"the command started {len(_descendants(proc.pid))} worker(s), expected {n}")


POOL = textwrap.dedent("""
    import os, sys, time
    from concurrent.futures import ProcessPoolExecutor
    from orthospec.workers import die_with_parent, mp_context
    init = die_with_parent if sys.argv[1] == "yes" else None
    with ProcessPoolExecutor(max_workers=2, mp_context=mp_context(["time"]), initializer=init,
                             initargs=(os.getpid(),) if init else ()) as pool:
        futures = [pool.submit(time.sleep, 60) for _ in range(2)]
        print("started", flush=True)
        time.sleep(60)
""")


@pytest.fixture
def own_tmp() -> Iterator[dict[str, str]]:
    """The environment with a TMPDIR of the test's own, removed after it: a command ended by a signal
    leaves its multiprocessing folder (pymp-*) behind. Short, beside the temp folder (not in
    tmp_path): the forkserver's socket path must fit in AF_UNIX's 108 bytes."""
    tmp = tempfile.mkdtemp(prefix="orthospec-w-")
    try:
        yield {**os.environ, "TMPDIR": tmp}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _left_after(initializer: str, sig: signal.Signals, env: dict[str, str]) -> set[int]:
    """The pool's processes still alive 2 s after ``sig`` ended the command that made them."""
    proc = subprocess.Popen(
        [sys.executable, "-c", POOL, initializer],
        stdout=subprocess.PIPE,
        env=env,
    )
    kids: set[int] = set()
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b"started"
        kids = _wait_for_workers(proc, 4, 20)  # the resource tracker, the forkserver, two workers
        os.kill(proc.pid, sig)
        proc.wait(5)
        time.sleep(2)
        return _alive(kids)
    finally:
        proc.kill()
        for p in _alive(kids | _descendants(proc.pid)):
            os.kill(p, signal.SIGKILL)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_pool_workers_end_within_2_s_of_their_command(
    sig: signal.Signals, own_tmp: dict[str, str]
) -> None:
    left = _left_after("yes", sig, own_tmp)
    assert not left, f"orphans after {sig.name}: {sorted(left)}"


def test_without_the_initializer_the_workers_would_outlive_it(own_tmp: dict[str, str]) -> None:
    """The test above can fail: a pool without die_with_parent leaves its sleeping workers behind."""
    assert _left_after("no", signal.SIGKILL, own_tmp), (
        "the workers ended anyway: the test above proves nothing"
    )


def test_sigterm_to_check_leaves_no_worker(tmp_path: Path, own_tmp: dict[str, str]) -> None:
    """The real command, scanning large images with two workers, ended by SIGTERM mid-scan."""
    d = tmp_path / "delivery"
    shutil.copytree(EXAMPLE, d)
    rng = np.random.default_rng(28)
    big = rng.integers(0, 255, size=(4, 3000, 3000), dtype=np.uint8)
    for tif in sorted((d / "images").glob("*.tif"))[:8]:
        with rasterio.open(tif) as src:
            profile = {
                **src.profile,
                "width": 3000,
                "height": 3000,
                "tiled": True,
                "blockxsize": 256,
                "blockysize": 256,
                "compress": "deflate",
            }
        with rasterio.open(tif, "w", **profile) as dst:
            dst.write(big)
    cmd = [
        str(Path(sys.executable).parent / "orthospec"),
        "check",
        str(d),
        "--profile",
        "jrc-v3",
        "--workers",
        "2",
        "--param",
        "map_crs=EPSG:25832",
        "--param",
        "tolerance_xy=0.5",
        "--out",
        str(tmp_path / "out"),
        "--date",
        "2026-11-21",
        "--format",
        "json",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=own_tmp)
    try:
        kids = _wait_for_workers(proc, 3, 60)
        time.sleep(0.3)
        kids |= _descendants(proc.pid)
        os.kill(proc.pid, signal.SIGTERM)
        proc.wait(5)
        time.sleep(2)
        assert not _alive(kids), f"orphans after SIGTERM: {sorted(_alive(kids))}"
    finally:
        proc.kill()
        for p in _alive(_descendants(proc.pid)):
            os.kill(p, signal.SIGKILL)
