"""Where every value came from: file, rows or YAML path, and the file's SHA-256."""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

#: bytes hashed per call: hashlib releases the GIL for each call, and the thread needs it back
#: between calls (waiting up to the switch interval while another thread runs Python), so fewer,
#: larger calls keep a hash in a side thread at full speed
_CHUNK = 4 << 20


def sha256_file(path: str | Path) -> str:
    """SHA-256 of a regular file, streamed in 4 MiB chunks through one reused buffer.

    Opened without blocking and refused unless a regular file, so a FIFO or device slipped in
    place of a delivered file raises OSError instead of hanging or reading forever. ``readinto``
    one buffer (unbuffered file, no larger than the file): no fresh object, and its page faults,
    per chunk. Not ``mmap``: a file truncated while it is hashed would kill the process (SIGBUS)
    instead of raising.
    """
    h = hashlib.sha256()
    with open(path, "rb", buffering=0, opener=_nonblocking) as fh:
        st = os.fstat(fh.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise OSError(errno.EINVAL, "not a regular file", str(path))
        buf = bytearray(max(1, min(_CHUNK, st.st_size)))
        view = memoryview(buf)
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
