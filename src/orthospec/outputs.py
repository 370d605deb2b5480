"""Every file orthospec writes goes through here (issue 28 item 1): one atomic writer.

:func:`atomic_path` hands out a temporary path beside the target (same folder, so the rename is
atomic on one file system) and renames it over the target only when the block ends without error;
on any exception, interrupt included, the temporary file is removed and the target is untouched.
:func:`atomic_write` is the same for data already in memory, fsynced before the rename. The file
gets the ordinary mode of a new file (0666 less the umask), not mkstemp's 0600.

The all-or-none writing of a set of report files into one folder is ``api.write_outputs`` (it
stages every file first, then moves them in, undoing the moves on error).

Foundation layer: the standard library only.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_path", "atomic_write", "file_mode"]


def file_mode() -> int:
    """The mode of an ordinary new file under the current umask."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextlib.contextmanager
def atomic_path(path: Path, suffix: str | None = None) -> Iterator[Path]:
    """A temporary path beside ``path``, renamed over it when the block ends without error.

    ``suffix`` is the temporary file's suffix (a writer that picks its driver from the suffix,
    GDAL for one, needs the target's); ``.tmp`` when not given."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or ".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, file_mode())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write(path: Path, data: str | bytes) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` atomically: temp file, fsync, rename."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data.encode("utf-8") if isinstance(data, str) else data)
        fh.flush()
        os.fsync(fh.fileno())
