"""A throw-away PostgreSQL server for the ledger tests, started once per test process.

The server runs from the Debian binaries (``/usr/lib/postgresql/*/bin``, installed by
scripts/sysdeps.sh) with its data directory in a temp folder, listening on 127.0.0.1 only and a
private unix socket. PostgreSQL refuses to run as root, so under root it runs as the
``postgres`` user. Each test gets a fresh database (``new_database``).
"""

from __future__ import annotations

import atexit
import contextlib
import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import uuid
from dataclasses import dataclass
from pathlib import Path

import pytest

USER = "orthospec"


def find_bindir() -> Path | None:
    """Directory holding initdb and pg_ctl, newest major version first; None when absent."""
    candidates = sorted(
        glob.glob("/usr/lib/postgresql/*/bin"),
        key=lambda p: int(Path(p).parent.name) if Path(p).parent.name.isdigit() else 0,
        reverse=True,
    )
    which = shutil.which("initdb")
    if which:
        candidates.append(str(Path(os.path.realpath(which)).parent))
    for c in candidates:
        if (Path(c) / "initdb").exists() and (Path(c) / "pg_ctl").exists():
            return Path(c)
    return None


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class PgServer:
    bindir: Path
    base: Path
    port: int
    run_as: str | None

    @property
    def data(self) -> Path:
        return self.base / "data"

    def url(self, dbname: str = "postgres") -> str:
        return f"postgresql+psycopg://{USER}@127.0.0.1:{self.port}/{dbname}"

    def _pg(self, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [str(self.bindir / args[0]), *args[1:]],
            cwd=self.base,
            user=self.run_as,
            capture_output=True,
            text=True,
            check=check,
            timeout=60,
        )

    def start(self) -> None:
        self._pg(
            "initdb",
            "-D",
            str(self.data),
            "-U",
            USER,
            "-A",
            "trust",
            "-E",
            "UTF8",
            "--locale=C",
            "--no-sync",
        )
        opts = (
            f"-c listen_addresses=127.0.0.1 -p {self.port} -k {self.base} -c fsync=off "
            "-c synchronous_commit=off -c full_page_writes=off -c max_connections=50"
        )
        res = self._pg(
            "pg_ctl",
            "-D",
            str(self.data),
            "-l",
            str(self.base / "server.log"),
            "-w",
            "-t",
            "30",
            "-o",
            opts,
            "start",
            check=False,
        )
        if res.returncode != 0:
            log = (
                (self.base / "server.log").read_text(errors="replace")
                if (self.base / "server.log").exists()
                else ""
            )
            raise RuntimeError(f"PostgreSQL did not start: {res.stdout}{res.stderr}\n{log[-2000:]}")

    def stop(self) -> None:
        with contextlib.suppress(Exception):
            self._pg("pg_ctl", "-D", str(self.data), "-m", "immediate", "-w", "stop", check=False)
        shutil.rmtree(self.base, ignore_errors=True)

    def new_database(self) -> str:
        """Create an empty database and return its SQLAlchemy URL."""
        import psycopg

        name = "t_" + uuid.uuid4().hex[:12]
        with psycopg.connect(
            host="127.0.0.1", port=self.port, user=USER, dbname="postgres", autocommit=True
        ) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)


_server: PgServer | None = None


def start_server() -> PgServer:
    """Start a server in a fresh temp folder (the caller stops it)."""
    bindir = find_bindir()
    if bindir is None:
        raise FileNotFoundError("PostgreSQL server binaries not found")
    base = Path(tempfile.mkdtemp(prefix="orthospec-pg-"))
    run_as = None
    if os.geteuid() == 0:
        pw = pwd.getpwnam("postgres")  # KeyError when the Debian package's user is missing
        os.chown(base, pw.pw_uid, pw.pw_gid)
        run_as = "postgres"
    server = PgServer(bindir, base, _free_port(), run_as)
    try:
        server.start()
    except BaseException:
        server.stop()
        raise
    return server


def server() -> PgServer:
    """The process-wide server, started on first use and stopped at exit.

    Skips (loudly) only when the server binaries are absent; any other start failure is an error.
    """
    global _server
    if _server is None:
        if find_bindir() is None:
            pytest.skip(
                "PostgreSQL SERVER BINARIES ABSENT (no initdb/pg_ctl in /usr/lib/postgresql/*/bin "
                "or PATH): the postgres variant of the ledger tests did NOT run; install them "
                "with `bash scripts/sysdeps.sh` (Debian package postgresql)"
            )
        _server = start_server()
        atexit.register(stop_server)
    return _server


def stop_server() -> None:
    """Stop the process-wide server, if one was started, and remove its folder (idempotent)."""
    global _server
    if _server is not None:
        _server.stop()
        _server = None
