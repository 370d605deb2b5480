"""scripts/sysdeps.sh decides the same way every time (issue 28: 22 of 30 runs named installed
packages as missing, because `grep -q` under `pipefail` killed the lister with SIGPIPE).

The script runs with an `ldconfig` in front of the real one that prints the real list plus 1 MiB of
other libraries (past any pipe buffer, as on a machine with many libraries: the old script failed
there every time), and an `apt-get` that records being called. On a machine where `make test` has
installed the packages (CI), the script must exit 0 and never call apt-get, 100 runs in 100.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from tests.conftest import ROOT

SCRIPT = ROOT / "scripts" / "sysdeps.sh"


def _installed() -> bool:
    return (shutil.which("pdftoppm") is not None and shutil.which("gdalinfo") is not None
            and any(Path("/usr/lib/postgresql").glob("*/bin/initdb")))


@pytest.fixture
def shims(tmp_path: Path) -> tuple[dict[str, str], Path]:
    real = shutil.which("ldconfig") or "/sbin/ldconfig"
    log = tmp_path / "apt-get.log"
    padding = tmp_path / "padding.txt"  # 1 MiB of unrelated entries after the real ones
    line = "\tlibpadding-entry-number-for-the-pipe-buffer.so.0 (libc6,x86-64) => /nowhere\n"
    padding.write_text(line * (2**20 // len(line) + 1))
    (tmp_path / "ldconfig").write_text(f'#!/bin/sh\n"{real}" "$@" || exit $?\ncat "{padding}"\n')
    (tmp_path / "apt-get").write_text(f"#!/bin/sh\necho \"$@\" >> '{log}'\nexit 1\n")
    for name in ("ldconfig", "apt-get"):
        (tmp_path / name).chmod(0o755)
    env = {**os.environ, "PATH": f"{tmp_path}:{os.environ.get('PATH', '')}"}
    return env, log


def test_installed_packages_are_never_reported_missing(shims: tuple[dict[str, str], Path]) -> None:
    if not _installed():
        pytest.skip("the system packages are not installed here (make test installs them)")
    env, log = shims
    codes = [
        subprocess.run(["bash", str(SCRIPT)], env=env, capture_output=True, text=True).returncode
        for _ in range(100)
    ]
    assert codes.count(0) == 100, f"exit codes: {sorted(set(codes))}"
    assert not log.exists(), f"apt-get was called: {log.read_text()[:300]}"


def test_a_missing_library_is_named(tmp_path: Path) -> None:
    """The decision is not always 'nothing to do': a machine whose library list lacks Pango gets it
    installed (here apt-get is the recording stand-in, so the script stops with its failure)."""
    log = tmp_path / "apt-get.log"
    (tmp_path / "ldconfig").write_text(
        "#!/bin/sh\necho 'libc.so.6 (libc6,x86-64) => /lib/libc.so.6'\n"
    )
    (tmp_path / "apt-get").write_text(f"#!/bin/sh\necho \"$@\" >> '{log}'\nexit 0\n")
    (tmp_path / "id").write_text("#!/bin/sh\necho 0\n")
    for name in ("ldconfig", "apt-get", "id"):
        (tmp_path / name).chmod(0o755)
    env = {**os.environ, "PATH": f"{tmp_path}:{os.environ.get('PATH', '')}"}
    done = subprocess.run(["bash", str(SCRIPT)], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "libpango-1.0-0" in log.read_text()
    assert log.read_text().count("libharfbuzz-subset0") == 1  # named once, not twice
