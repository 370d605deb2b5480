"""List a source folder's files without leaving it: what ``init --from`` may read.

The walk never follows a symbolic link to a folder (no loops), never reads a link that leads out
of the source (listed as refused, with why), and never opens a FIFO, device or socket (they could
block or never end). Names are sorted, so the listing (and the draft) is the same on every run.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass
from pathlib import Path

from ..errors import DeliveryError

#: suffixes read as images (GeoTIFF/COG and JPEG 2000 are read; the others are listed as refused
#: by the one raster reader, with its reason)
RASTER_SUFFIXES = frozenset(
    {".tif", ".tiff", ".jp2", ".j2k", ".jpf", ".jpx", ".img", ".ecw", ".sid", ".vrt"}
)
VECTOR_SUFFIXES = frozenset({".shp", ".gpkg", ".geojson", ".fgb"})
SHEET_SUFFIXES = frozenset({".csv", ".tsv", ".xlsx", ".xlsm", ".ods"})
XML_SUFFIXES = frozenset({".xml"})
#: files that belong to another (a shapefile's parts, GDAL side-cars, world files): not listed
SIDECAR_SUFFIXES = frozenset(
    {
        ".dbf",
        ".shx",
        ".prj",
        ".cpg",
        ".qix",
        ".sbn",
        ".sbx",
        ".tfw",
        ".tifw",
        ".j2w",
        ".jgw",
        ".ovr",
        ".msk",
        ".aux",
        ".rrd",
    }
)
_SPECIAL = {
    stat.S_IFIFO: "a FIFO (named pipe)",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
}


@dataclass(frozen=True)
class SourceFile:
    """One file of a source folder: ``rel`` is its POSIX path relative to the source."""

    source: Path
    rel: str
    bytes: int
    kind: str  # raster | vector | sheet | xml | sidecar | other

    @property
    def path(self) -> Path:
        return self.source.joinpath(*self.rel.split("/"))


@dataclass(frozen=True)
class Refused:
    """A source entry that is not read, and why (a line of the draft's report)."""

    rel: str
    why: str


def kind_of(name: str) -> str:
    low = name.lower()
    if low.endswith(".aux.xml"):
        return "sidecar"
    suffix = os.path.splitext(low)[1]
    for kind, suffixes in (
        ("raster", RASTER_SUFFIXES),
        ("vector", VECTOR_SUFFIXES),
        ("sheet", SHEET_SUFFIXES),
        ("xml", XML_SUFFIXES),
        ("sidecar", SIDECAR_SUFFIXES),
    ):
        if suffix in suffixes:
            return kind
    return "other"


def walk_source(source: str | Path) -> tuple[list[SourceFile], list[Refused]]:
    """Every regular file under ``source`` (sorted) and every entry refused.

    Raises
    ------
    DeliveryError
        when ``source`` does not exist or is not a folder (a source is a delivery's folder).
    """
    root = Path(source)
    try:
        st = root.stat()
    except OSError as exc:
        raise DeliveryError(
            f"source {str(source)!r} cannot be read: {exc.strerror or exc}"
        ) from None
    if not stat.S_ISDIR(st.st_mode):
        raise DeliveryError(
            f"source {str(source)!r} is a file, not a folder; `init --from` takes the "
            "folder the delivery arrived in"
        )
    real_root = root.resolve()
    files: list[SourceFile] = []
    refused: list[Refused] = []
    stack = [root]
    while stack:
        folder = stack.pop()
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError as exc:
            refused.append(
                Refused(
                    folder.relative_to(root).as_posix() + "/",
                    f"folder cannot be listed: {exc.strerror or exc}",
                )
            )
            continue
        subdirs = []
        for e in entries:
            rel = Path(e.path).relative_to(root).as_posix()
            try:
                if e.is_symlink():
                    try:
                        real = Path(e.path).resolve(strict=True)
                    except (OSError, RuntimeError):
                        refused.append(
                            Refused(
                                rel, "symbolic link that cannot be resolved (dangling or a loop)"
                            )
                        )
                        continue
                    if not real.is_relative_to(real_root):
                        refused.append(
                            Refused(rel, "symbolic link leading out of the source folder: not read")
                        )
                        continue
                    mode = os.stat(e.path).st_mode
                    if stat.S_ISDIR(mode):
                        refused.append(
                            Refused(
                                rel,
                                "symbolic link to a folder: not followed (its files are "
                                "listed under their own path)",
                            )
                        )
                        continue
                else:
                    mode = e.stat(follow_symlinks=False).st_mode
            except OSError as exc:
                refused.append(Refused(rel, f"cannot be read: {exc.strerror or exc}"))
                continue
            if stat.S_ISDIR(mode):
                subdirs.append(Path(e.path))
                continue
            special = _SPECIAL.get(stat.S_IFMT(mode))
            if special is not None or not stat.S_ISREG(mode):
                refused.append(Refused(rel, f"is {special or 'not a regular file'}: not read"))
                continue
            files.append(SourceFile(root, rel, os.stat(e.path).st_size, kind_of(e.name)))
        stack.extend(reversed(subdirs))
    files.sort(key=lambda f: f.rel)
    refused.sort(key=lambda r: r.rel)
    return files, refused
