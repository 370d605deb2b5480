"""Run the orthospec CLI on a hostile input in a subprocess with a time and memory budget.

Why a subprocess: a hostile input may hang, exhaust memory or crash the interpreter; the harness
must survive that and measure it. Memory is capped with ``RLIMIT_AS`` in the child; the peak
resident set size is the child's own ``VmHWM`` (reported by the child at exit, polled while it runs),
and ``os.wait4`` reaps it.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import selectors
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "deliveries" / "aerial-pass"
#: Address-space cap of the child (python + numpy + GDAL map ~1 GB of virtual memory at start).
MEMORY_LIMIT = 4 * 2**30
TIMEOUT_S = 60.0


@dataclass
class Run:
    exit: int | None  # None: killed at the timeout
    seconds: float
    peak_mb: float
    stdout: str
    stderr: str

    @property
    def timed_out(self) -> bool:
        return self.exit is None


#: The child sets its own address-space cap before importing anything (the same as
#: ``setrlimit`` in a ``preexec_fn``, but safe while the test runs cases from two threads).
#: At exit it writes its own peak RSS (``VmHWM``: this process image only; ``ru_maxrss`` would
#: include the forking parent's high-water mark) to the file named in argv.
_PRELUDE = """
import atexit, resource, sys
m, report = int(sys.argv.pop(1)), sys.argv.pop(1)
resource.setrlimit(resource.RLIMIT_AS, (m, m))
def _peak():
    with open("/proc/self/status") as fh:
        kb = next((ln.split()[1] for ln in fh if ln.startswith("VmHWM:")), "0")
    with open(report, "w") as out:
        out.write(kb)
atexit.register(_peak)
from orthospec.cli.main import main
main()
"""


def _vm_hwm_kb(pid: int) -> int:
    """Peak RSS so far of a running process image (0 when it is gone)."""
    try:
        with open(f"/proc/{pid}/status") as fh:
            return int(next((ln.split()[1] for ln in fh if ln.startswith("VmHWM:")), "0"))
    except (OSError, ValueError):
        return 0


def run_cli(
    args: list[str],
    *,
    cwd: Path,
    timeout: float = TIMEOUT_S,
    memory: int = MEMORY_LIMIT,
    env: dict[str, str] | None = None,
) -> Run:
    """``python -m orthospec.cli.main ARGS`` with a time and memory cap; never raises on a hang."""
    fd, report = tempfile.mkstemp(prefix="orthospec-harness-rss-")
    os.close(fd)
    cmd = [sys.executable, "-c", _PRELUDE, str(memory), report, *args]
    full_env = {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "120", **(env or {})}
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        cmd,
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        env=full_env,
        start_new_session=True,
    )
    out, err = bytearray(), bytearray()
    sel = selectors.DefaultSelector()
    assert proc.stdout is not None and proc.stderr is not None
    sel.register(proc.stdout, selectors.EVENT_READ, out)
    sel.register(proc.stderr, selectors.EVENT_READ, err)
    killed = False
    peak_kb = 0
    while sel.get_map():
        peak_kb = max(peak_kb, _vm_hwm_kb(proc.pid))
        left = timeout - (time.perf_counter() - t0)
        if left <= 0:
            os.killpg(proc.pid, signal.SIGKILL)
            killed = True
            break
        for key, _ in sel.select(timeout=min(left, 0.1)):
            chunk = os.read(key.fd, 65536)
            if not chunk:
                sel.unregister(key.fileobj)
            elif len(key.data) < 4 * 2**20:
                key.data.extend(chunk)
    sel.close()
    _pid, status, _usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    with contextlib.suppress(OSError, ValueError):
        peak_kb = max(peak_kb, int(Path(report).read_text() or 0))
    Path(report).unlink(missing_ok=True)
    proc.returncode = os.waitstatus_to_exitcode(status)
    proc.stdout.close()
    proc.stderr.close()
    return Run(
        exit=None if killed else proc.returncode,
        seconds=seconds,
        peak_mb=peak_kb / 1024,
        stdout=out.decode("utf-8", "replace"),
        stderr=err.decode("utf-8", "replace"),
    )


def tree_state(root: Path) -> dict[str, str]:
    """Every entry under ``root`` (not following links) -> a fingerprint of what it is and holds."""
    out: dict[str, str] = {}
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for name in sorted(dirnames + filenames):
            p = Path(dirpath) / name
            rel = p.relative_to(root).as_posix()
            st = os.lstat(p)
            if stat.S_ISLNK(st.st_mode):
                out[rel] = "link:" + os.readlink(p)
            elif stat.S_ISDIR(st.st_mode):
                out[rel] = "dir"
            elif stat.S_ISREG(st.st_mode):
                h = hashlib.sha256()
                with open(p, "rb") as fh:
                    while chunk := fh.read(1 << 20):
                        h.update(chunk)
                out[rel] = f"file:{st.st_size}:{h.hexdigest()}:{st.st_mtime_ns}"
            else:
                out[rel] = f"special:{stat.S_IFMT(st.st_mode)}"
    return out


def copy_example(dest: Path, *, keep_images: int = 3) -> Path:
    """A small copy of examples/deliveries/aerial-pass: the first ``keep_images`` images only."""
    shutil.copytree(EXAMPLE, dest)
    (dest / "expected.yaml").unlink()
    table = dest / "tables" / "images.csv"
    lines = table.read_text(encoding="utf-8").splitlines(keepends=True)
    kept = lines[: keep_images + 1]
    table.write_text("".join(kept), encoding="utf-8")
    keep = {ln.split(",")[1] for ln in kept[1:]}
    for f in (dest / "images").iterdir():
        if f"images/{f.name}" not in keep:
            f.unlink()
    return dest


def all_output_text(*dirs: Path) -> bytes:
    """Bytes of every regular file under the given folders (outputs to search for leaks)."""
    out = bytearray()
    for d in dirs:
        if not d.exists():
            continue
        for dirpath, _dirs, files in os.walk(d, followlinks=False):
            for name in files:
                p = Path(dirpath) / name
                if p.is_file() and not p.is_symlink():
                    out += p.read_bytes()
    return bytes(out)
