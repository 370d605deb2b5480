"""Where a delivery's paths may lead: the one containment check of orthospec (issue 17).

A delivery is untrusted input (the contractor is paid on the verdict), so every path it names or
holds goes through :func:`contained` before anything opens or hashes it: no absolute path, no
``..``, no URL or GDAL ``/vsi`` prefix, no symbolic link leaving the folder, no FIFO or device.
:func:`check_tree` vets every entry of the folder once, so table columns of paths can be checked
lexically in bulk.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path, PurePosixPath

from ..errors import DeliveryError
from .draft import SourceLinks

MANIFEST = "delivery.yaml"
#: A relative path :func:`contained` accepts on its face (ASCII names, no empty, "." or ".." part,
#: no scheme or drive letter): a national images table's paths are vetted in bulk, the rest one by one.
_PLAIN_PATH = r"[A-Za-z0-9_][A-Za-z0-9_.-]*(?:/[A-Za-z0-9_][A-Za-z0-9_.-]*)*"
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
_SPECIAL = {
    stat.S_IFIFO: "a FIFO (named pipe)",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
}


def _lexical(rel: str) -> tuple[PurePosixPath | None, str]:
    """The relative path ``rel`` names, or None and why it cannot name a file of the delivery."""
    text = str(rel)
    if not text.strip():
        return None, "is empty"
    if any(ord(c) < 32 or ord(c) == 127 for c in text):
        return None, "contains control characters"
    posix = text.replace("\\", "/")
    if posix.lower().startswith("/vsi"):
        return (
            None,
            "is a GDAL virtual file system path (/vsi...); only files inside the delivery are read",
        )
    if _SCHEME.match(posix):
        return (
            None,
            "is a URL or a drive-letter path; only relative paths inside the delivery are read",
        )
    pp = PurePosixPath(posix)
    if pp.is_absolute() or posix.startswith("//"):
        return None, "is an absolute path; paths are relative to the delivery folder"
    if ".." in pp.parts:
        return None, "contains '..'; paths must stay inside the delivery folder"
    if not pp.parts or pp.parts == (".",):
        return None, "names the delivery folder itself, not a file"
    return pp, ""


def contained(
    root: str | Path,
    rel: str,
    *,
    what: str = "file",
    file: str | None = MANIFEST,
    line: int | None = None,
    row: int | None = None,
    field: str | None = None,
    follow: bool = True,
    links: SourceLinks | None = None,
) -> Path:
    """``root/rel`` if it names something inside the delivery; else a DeliveryError saying why.

    The one containment check of orthospec (issue 17): every path a delivery names and every file
    it holds is resolved against the delivery root before it is opened or hashed. Refused: empty,
    absolute, ``..``, URL / drive letter, GDAL ``/vsi`` prefixes, control characters, a symbolic
    link (anywhere on the way) that leads out of the folder, a FIFO, device or socket. A path that
    does not exist is returned (callers report it as missing). ``follow=False`` skips the
    file-system part (for bulk table columns, after :func:`check_tree` vetted every link).
    ``links``: a draft's links into its source folder (delivery/draft.py), the one exception.

    Raises
    ------
    DeliveryError
        naming ``file`` and ``line``/``row``/``field``, and the path as written.
    """
    pp, why = _lexical(rel)

    def refuse(reason: str) -> DeliveryError:
        return DeliveryError(
            f"{what} {str(rel)[:300]!r} {reason}", file=file, line=line, row=row, field=field
        )

    if pp is None:
        raise refuse(why)
    base = Path(root)
    p = base.joinpath(*pp.parts)
    if not follow:
        return p
    try:
        real_root = base.resolve()
        real = p.resolve()
    except (OSError, RuntimeError) as exc:  # symlink loops (RuntimeError before Python 3.13)
        raise refuse(f"cannot be resolved ({exc})") from None
    if not real.is_relative_to(real_root) and not (links is not None and links.allows(p, real)):
        raise refuse("is (or passes through) a symbolic link leading out of the delivery folder")
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return p
    except OSError as exc:
        raise refuse(f"cannot be read: {exc.strerror or exc}") from None
    kind = _SPECIAL.get(stat.S_IFMT(st.st_mode))
    if kind is not None:
        raise refuse(f"is {kind}, not a regular file")
    return p


def check_tree(root: str | Path, links: SourceLinks | None = None) -> list[str]:
    """Vet every entry of the delivery folder; return its regular files (relative POSIX paths).

    Symbolic links that stay inside the folder are allowed (and not followed here); one that leads
    out, and any FIFO, device or socket, is refused with a DeliveryError naming it, so nothing
    later can be tricked into reading outside the delivery or blocking on a pipe.
    """
    base = Path(root)
    real_root = base.resolve()
    files: list[str] = []
    stack = [base]
    while stack:
        folder = stack.pop()
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError as exc:
            rel = folder.relative_to(base).as_posix()
            raise DeliveryError(f"folder {rel!r} cannot be listed: {exc.strerror or exc}") from None
        for e in entries:
            rel = Path(e.path).relative_to(base).as_posix()
            if e.is_symlink():
                try:
                    real = Path(e.path).resolve()
                except (OSError, RuntimeError):
                    raise DeliveryError(
                        "is a symbolic link that cannot be resolved (a loop?)", file=rel
                    ) from None
                if not real.is_relative_to(real_root) and not (
                    links is not None and links.allows(Path(e.path), real)
                ):
                    raise DeliveryError(
                        "is a symbolic link leading out of the delivery folder; "
                        "orthospec reads nothing outside the delivery",
                        file=rel,
                    )
                try:
                    mode = os.stat(e.path).st_mode
                except OSError:
                    continue  # dangling link inside the folder: reported as missing if listed
                if links is not None and stat.S_ISREG(mode) and links.allows(Path(e.path), real):
                    files.append(rel)  # a draft's delivered file, read in place
                    continue
            elif e.is_dir(follow_symlinks=False):
                stack.append(Path(e.path))
                continue
            elif e.is_file(follow_symlinks=False):
                files.append(rel)
                continue
            else:
                mode = e.stat(follow_symlinks=False).st_mode
            kind = _SPECIAL.get(stat.S_IFMT(mode))
            if kind is not None:
                raise DeliveryError(
                    f"is {kind}, not a regular file; a delivery holds files only", file=rel
                )
    return sorted(files)
