"""Where every value came from: file, rows or YAML path, and the file's SHA-256."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

_CHUNK = 1 << 20


def sha256_file(path: str | Path) -> str:
    """SHA-256 of a file, streamed in 1 MiB chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


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
