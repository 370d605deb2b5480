"""A test run leaves nothing in the temp folder, even when it is stopped (issue 28 item 6).

The resolved-profile cache (tests/conftest.py) and the PostgreSQL data folder (tests/pg.py) are
removed when the run ends; a SIGTERM (a CI timeout) ends it like Ctrl-C, so they go then too.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
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


def test_sigterm_leaves_no_cache_folder(tmp_path: Path) -> None:
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    probe = tmp_path / "test_probe.py"
    probe.write_text(SLOW, encoding="utf-8")
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("ORTHOSPEC_CACHE_DIR", "PYTEST_XDIST_WORKER")
    }
    env["TMPDIR"] = str(tmp)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(ROOT / "tests")])
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
