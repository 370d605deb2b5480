"""Result cache keyed by file content (SHA-256) and scan settings, in SQLite.

Why: a national delivery is re-checked after partial redelivery; only files whose bytes
changed should be read again. The key is the content hash, not the path or mtime, so a
renamed or copied file is still a hit and a rewritten file with the same size and date is
still a miss. Optionally (``trust_mtime``) the SHA-256 itself is remembered per absolute
path, size and modification time, so unchanged files are not even re-hashed. The cache
lives outside the delivery (``scan_images`` refuses a cache directory
that contains an image) and is written only by the coordinating process; workers only read.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

from .. import __version__

CACHE_FILE = "orthospec-raster-cache.sqlite"
#: Bump when the content of cached results changes meaning.
CACHE_SCHEMA = 2


class ResultCache:
    """``(sha256, settings key) -> JSON result`` in ``cache_dir/orthospec-raster-cache.sqlite``."""

    def __init__(self, cache_dir: str | Path, *, read_only: bool = False) -> None:
        self.dir = Path(cache_dir)
        self.path = self.dir / CACHE_FILE
        self.read_only = read_only
        if read_only:
            self._con = None
            if self.path.exists():
                self._con = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True, timeout=30)
            return
        self.dir.mkdir(parents=True, exist_ok=True)
        self._con = sqlite3.connect(self.path, timeout=30)
        self._con.execute(
            "CREATE TABLE IF NOT EXISTS results (sha256 TEXT NOT NULL, settings TEXT NOT NULL, "
            "result TEXT NOT NULL, PRIMARY KEY (sha256, settings))")
        self._con.execute(
            "CREATE TABLE IF NOT EXISTS hashes (path TEXT PRIMARY KEY, size INTEGER NOT NULL, "
            "mtime_ns INTEGER NOT NULL, sha256 TEXT NOT NULL)")
        self._con.commit()

    @staticmethod
    def key(settings_key: str) -> str:
        return f"schema={CACHE_SCHEMA};orthospec={__version__};{settings_key}"

    def get(self, sha256: str, settings_key: str) -> dict[str, Any] | None:
        if self._con is None:
            return None
        try:
            row = self._con.execute("SELECT result FROM results WHERE sha256=? AND settings=?",
                                    (sha256, self.key(settings_key))).fetchone()
        except sqlite3.OperationalError:  # table not created yet
            return None
        return None if row is None else json.loads(row[0])

    def put(self, sha256: str, settings_key: str, result: dict[str, Any]) -> None:
        if self._con is None or self.read_only:
            raise RuntimeError("cache opened read-only")
        self._con.execute("INSERT OR REPLACE INTO results VALUES (?, ?, ?)",
                          (sha256, self.key(settings_key),
                           json.dumps(result, sort_keys=True, allow_nan=True)))
        self._con.commit()

    def get_hash(self, path: str, size: int, mtime_ns: int) -> str | None:
        """SHA-256 recorded for this absolute path with the same size and mtime, if any."""
        if self._con is None:
            return None
        try:
            row = self._con.execute("SELECT sha256 FROM hashes WHERE path=? AND size=? AND "
                                    "mtime_ns=?", (path, size, mtime_ns)).fetchone()
        except sqlite3.OperationalError:
            return None
        return None if row is None else str(row[0])

    def put_hash(self, path: str, size: int, mtime_ns: int, sha256: str) -> None:
        if self._con is None or self.read_only:
            raise RuntimeError("cache opened read-only")
        self._con.execute("INSERT OR REPLACE INTO hashes VALUES (?, ?, ?, ?)",
                          (path, size, mtime_ns, sha256))
        self._con.commit()

    def __len__(self) -> int:
        if self._con is None:
            return 0
        try:
            return int(self._con.execute("SELECT COUNT(*) FROM results").fetchone()[0])
        except sqlite3.OperationalError:
            return 0

    def close(self) -> None:
        if self._con is not None:
            self._con.close()
            self._con = None

    def __enter__(self) -> ResultCache:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
