"""provenance.sha256_file: the digest hashlib gives for the whole bytes, whatever the size."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest

from orthospec import provenance
from orthospec.provenance import sha256_file

CHUNK = provenance._CHUNK


@pytest.mark.parametrize("size", [0, 1, 4095, CHUNK - 1, CHUNK, CHUNK + 1, 3 * CHUNK + 5])
def test_streamed_digest_equals_the_digest_of_the_whole_bytes(tmp_path: Path, size: int) -> None:
    data = os.urandom(size)
    path = tmp_path / "f.bin"
    path.write_bytes(data)
    assert sha256_file(path) == hashlib.sha256(data).hexdigest()


def test_a_fifo_is_refused_not_read(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match="not a regular file"):
        sha256_file(fifo)
