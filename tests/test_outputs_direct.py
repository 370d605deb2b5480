"""Outputs of a megabyte or more bypass the page cache (O_DIRECT), with the same bytes (issue 14).

Every output is fsynced, so the page-cache copy is pure cost; these tests hold the writer to
the bytes it was given whatever the size, the pieces, the file system, and a refusal of
direct I/O part way through.
"""

from __future__ import annotations

import errno
import os
import time
from pathlib import Path

import pytest

from orthospec.api import write_outputs

SPAN = 1 << 20
O_DIRECT = getattr(os, "O_DIRECT", 0)


def _pieces(total: int, piece: int, seed: int) -> list[str]:
    """``total`` characters of varied ASCII text cut into pieces of about ``piece``."""
    line = "".join(chr(33 + (seed * 7 + i * 13) % 90) for i in range(97)) + "\n"
    text = (line * (total // len(line) + 1))[:total]
    return [text[i:i + piece] for i in range(0, total, piece)] or [""]


@pytest.mark.parametrize(
    "total, piece",
    [
        (0, 1),
        (1, 1),
        (4095, 1000),
        (4096, 4096),
        (SPAN - 1, 300_000),
        (SPAN, SPAN),
        (SPAN + 1, 70_001),
        (3 * SPAN + 123, 1 << 18),
        (5 * SPAN + 4097, 3 * SPAN),
    ],
)
def test_any_size_in_any_pieces_is_written_as_given(tmp_path, total, piece):
    parts = _pieces(total, piece, total % 11)
    write_outputs(
        tmp_path,
        {"qcr.csv": iter(parts), "whole.txt": "".join(parts), "b.bin": "".join(parts).encode()},
    )
    expected = "".join(parts).encode()
    for name in ("qcr.csv", "whole.txt", "b.bin"):
        assert (tmp_path / name).read_bytes() == expected, name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bin", "qcr.csv", "whole.txt"]


@pytest.mark.skipif(not Path("/dev/shm").is_dir(), reason="no tmpfs at /dev/shm")
def test_on_tmpfs_too(tmp_path):
    import tempfile

    with tempfile.TemporaryDirectory(dir="/dev/shm") as shm:
        parts = _pieces(2 * SPAN + 5, 1 << 17, 3)
        write_outputs(shm, {"qcr.csv": iter(parts)})
        assert (Path(shm) / "qcr.csv").read_bytes() == "".join(parts).encode()


def _flags_of(path_suffix: str) -> int | None:
    """The open flags of this process's descriptor on a file whose path ends with ``path_suffix``."""
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.endswith(path_suffix):
            for line in Path(f"/proc/self/fdinfo/{fd}").read_text().splitlines():
                if line.startswith("flags:"):
                    return int(line.split()[1], 8)
    return None


@pytest.mark.skipif(
    not O_DIRECT or not Path("/proc/self/fdinfo").is_dir(), reason="Linux O_DIRECT only"
)
def test_a_large_output_is_written_with_o_direct(tmp_path):
    """Seen from the kernel (/proc/self/fdinfo): the descriptor of a large output carries O_DIRECT
    while it is written, unless the file system refuses it (then the test says so and passes)."""
    seen: list[int | None] = []

    def stream():
        yield from _pieces(3 * SPAN, 1 << 18, 1)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:  # the writer thread catches up with the pieces queued
            flags = _flags_of("/new-0")
            seen.append(flags)
            if flags is not None and flags & O_DIRECT:
                break
            time.sleep(0.01)
        yield from _pieces(SPAN + 7, 1 << 18, 2)

    write_outputs(tmp_path, {"qcr.csv": stream()})
    assert (tmp_path / "qcr.csv").read_bytes() == "".join(
        _pieces(3 * SPAN, 1 << 18, 1) + _pieces(SPAN + 7, 1 << 18, 2)
    ).encode()
    assert seen and seen[-1] is not None
    if _direct_ok(tmp_path / "probe"):
        assert seen[-1] & O_DIRECT, f"flags {seen[-1]:o} without O_DIRECT"


def _direct_ok(path: Path) -> bool:
    """Whether the file system of ``path`` takes O_DIRECT at all."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | O_DIRECT)
    except OSError:
        return False
    os.close(fd)
    return True


@pytest.mark.skipif(not O_DIRECT, reason="Linux O_DIRECT only")
def test_direct_io_refused_at_write_time_falls_back_to_the_same_bytes(tmp_path, monkeypatch):
    """A file system that accepts the O_DIRECT flag but refuses the write (EINVAL, as some FUSE and
    network file systems do): the writer goes on buffered, and the bytes are the same."""
    import fcntl

    real_write = os.write
    refused: list[int] = []

    def write(fd, data):
        if fcntl.fcntl(fd, fcntl.F_GETFL) & O_DIRECT:
            refused.append(fd)
            raise OSError(errno.EINVAL, "Invalid argument")
        return real_write(fd, data)

    monkeypatch.setattr(os, "write", write)
    parts = _pieces(3 * SPAN + 4321, 1 << 18, 5)
    write_outputs(tmp_path, {"qcr.csv": iter(parts), "small.txt": "x"})
    assert refused, "no direct write was attempted"
    assert (tmp_path / "qcr.csv").read_bytes() == "".join(parts).encode()
    assert (tmp_path / "small.txt").read_text() == "x"
