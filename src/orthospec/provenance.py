"""Where every value came from: file, rows or YAML path, and the file's SHA-256."""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

_CHUNK = 1 << 20


def sha256_file(path: str | Path) -> str:
    """SHA-256 of a regular file, streamed in 1 MiB chunks through one reused buffer.

    Opened without blocking and refused unless a regular file, so a FIFO or device slipped in
    place of a delivered file raises OSError instead of hanging or reading forever. ``readinto``
    one buffer (unbuffered file): no fresh 1 MiB object, and its page faults, per chunk (about
    10 % of the hash's CPU on a big image); hashlib releases the GIL while it hashes.
    """
    h = hashlib.sha256()
    buf = bytearray(_CHUNK)
    view = memoryview(buf)
    with open(path, "rb", buffering=0, opener=_nonblocking) as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            raise OSError(errno.EINVAL, "not a regular file", str(path))
        while n := fh.readinto(buf):
            h.update(view[:n])
    return h.hexdigest()


def _nonblocking(path: str, flags: int) -> int:
    return os.open(path, flags | getattr(os, "O_NONBLOCK", 0))


def sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@dataclass(frozen=True, order=True)
class Evidence:
    """One piece of evidence behind a measured value.

    ``file`` is relative to the delivery root (POSIX separators); ``rows`` are
    1-based data-row numbers of a CSV table (the header is row 0, so row N is on
    line N+1); ``path`` is a dotted YAML path for manifest values.
    """

    file: str
    sha256: str
    rows: tuple[int, ...] = field(default=())
    path: str | None = None

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {"file": self.file, "sha256": self.sha256}
        if self.rows:
            out["rows"] = list(self.rows)
        if self.path:
            out["path"] = self.path
        return out
