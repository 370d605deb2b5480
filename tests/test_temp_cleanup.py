"""A test run leaves nothing in the temp folder, even when it is stopped (issue 28 item 6).

The resolved-profile cache (tests/conftest.py) and the PostgreSQL data folder (tests/pg.py) are
removed when the run ends; a SIGTERM (a CI timeout) ends it like Ctrl-C, so they go then too.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SLOW = """\
import time

def test_waits():
    time.sleep(60)
"""


def _leftovers(tmp: Path) -> list[str]:
    return sorted(
        p.name
        for p in tmp.iterdir()
        if p.name.startswith(("orthospec-test-cache-", "orthospec-pg-"))
    )


def _probe_env(tmp: Path) -> dict[str, str]:
    """A fresh test run's environment (no inherited cache or worker id) with its temp folder ``tmp``."""
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("ORTHOSPEC_CACHE_DIR", "PYTEST_XDIST_WORKER")
    }
    env["TMPDIR"] = str(tmp)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(ROOT / "tests")])
    return env


def test_sigterm_leaves_no_cache_folder(tmp_path: Path) -> None:
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    probe = tmp_path / "test_probe.py"
    probe.write_text(SLOW, encoding="utf-8")
    env = _probe_env(tmp)
    # the repository's conftest as a plugin, on a probe test that waits: the run is stopped while it waits
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-p",
            "no:xdist",
            "-p",
            "tests.conftest",
            "--rootdir",
            str(tmp_path),
            str(probe),
        ],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    deadline = time.monotonic() + 60
    while not any(p.name.startswith("orthospec-test-cache-") for p in tmp.iterdir()):
        assert proc.poll() is None and time.monotonic() < deadline, (
            proc.stdout.read() if proc.stdout else ""
        )
        time.sleep(0.1)
    time.sleep(1.0)  # collected and waiting in the probe
    proc.send_signal(signal.SIGTERM)
    out = proc.communicate(timeout=60)[0].decode(errors="replace")
    assert proc.returncode != 0, out  # stopped, not passed
    assert _leftovers(tmp) == [], out


USES_PG = """\
import pg

def test_database():
    assert pg.server().new_database().startswith("postgresql")
"""

BEFORE_EXIT = """\
import os, sys, pytest
rc = pytest.main(sys.argv[1:])
left = sorted(p for p in os.listdir(os.environ["TMPDIR"]) if p.startswith("orthospec-pg-"))
print("LEFT", left, "RC", int(rc))
"""


def test_postgres_folder_is_gone_when_the_session_ends(tmp_path: Path) -> None:
    """Removed after the last test, not by an exit handler: an xdist worker still busy 10 s after its
    last test is killed, and a data folder half deleted at exit stayed in the temp folder."""
    # not under tmp_path: the server runs as the postgres user, who cannot enter pytest's folders
    tmp = Path(tempfile.mkdtemp(prefix="orthospec-pgprobe-"))
    tmp.chmod(0o755)
    try:
        _run_probe(tmp, tmp_path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _run_probe(tmp: Path, tmp_path: Path) -> None:
    probe = tmp_path / "test_probe.py"
    probe.write_text(USES_PG, encoding="utf-8")
    env = _probe_env(tmp)
    args = ["-q", "-p", "no:cacheprovider", "-p", "no:xdist", "-p", "tests.conftest"]
    args += ["--rootdir", str(tmp_path), str(probe)]
    done = subprocess.run(
        [sys.executable, "-c", BEFORE_EXIT, *args],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert "LEFT [] RC 0" in done.stdout, done.stdout[-3000:] + done.stderr[-2000:]
    assert _leftovers(tmp) == []
