"""Finding profiles by id and version, from the headers of their files (never parsing a file
that is not the one asked for): the shipped ones first, then the folder of the profile that
extends, then the profiles of installed plugins."""

from __future__ import annotations

import difflib
import re
from pathlib import Path
from typing import Any

from ..errors import SpecError
from ..resources import specs_dir
from ..yamlio import YamlError, read_regular

#: how much of a candidate file is read to learn its id and version (never the whole file)
HEADER_BYTES = 4096


_HEAD_KEY = re.compile(r"^(id|version|title|orthospec_profile)[ \t]*:[ \t]*(.*?)[ \t]*$", re.M)


def _scalar_text(v: str) -> str:
    v = re.sub(r"\s+#.*$", "", v).strip()
    if len(v) >= 2 and v[0] == v[-1] and v[0] in "'\"":
        v = v[1:-1]
    return v


def read_header(path: Path) -> tuple[str, str, str] | None:
    """(id, version, title) from the first HEADER_BYTES of a file, without parsing YAML.

    Only top-level ``key: value`` lines count. Finding a profile by id never parses a file that
    is not the one asked for (an unrelated alias bomb in the same folder cannot hang it).
    """
    try:
        head = read_regular(path, HEADER_BYTES).decode("utf-8", errors="replace")
    except (OSError, YamlError):
        return None
    found: dict[str, str] = {}
    for m in _HEAD_KEY.finditer(head):
        found.setdefault(m.group(1), _scalar_text(m.group(2)))
    if "orthospec_profile" not in found or "id" not in found:
        return None
    return found["id"], found.get("version", ""), found.get("title", "")


def available(extra: list[Path] | None = None) -> list[tuple[str, str, str, Path]]:
    """Shipped (and extra) profiles as (id, version, title, path), from their headers."""
    out = []
    for d in [specs_dir(), *(extra or [])]:
        if not d.is_dir():
            continue
        for p in sorted(d.glob("*.yaml")):
            h = read_header(p) if p.is_file() else None
            if h:
                out.append((*h, p))
    return sorted(out, key=lambda t: (t[0], t[1]))


def find_profile(ref: str | Path, *, near: Path | None = None, version: str | None = None) -> Path:
    """A path to a profile given a file path (as the user typed it) or an id."""
    p = Path(ref)
    if p.suffix in (".yaml", ".yml") or p.exists():
        if p.exists() and not p.is_file():
            raise SpecError(f"profile file {str(ref)!r} is not a regular file")
        if not p.is_file():
            raise SpecError(f"profile file {str(ref)!r} not found")
        return p
    return find_by_id(str(ref), version=version, near=near)


def plugin_profiles() -> list[tuple[str, str, str, Path]]:
    """Profiles installed plugins ship (``orthospec.profiles`` entry points), as ``available``."""
    from .. import plugins

    dirs = list(plugins.profile_dirs())
    if not dirs:
        return []
    inside = {d.resolve() for d in dirs}
    return [t for t in available(dirs) if t[3].parent.resolve() in inside]


def find_by_id(pid: str, *, version: str | None = None, near: Path | None = None) -> Path:
    """A profile by id (and pinned version): shipped profiles first, then ``near``'s folder, then
    the profiles of installed plugins (orthospec/plugins.py).

    An id is never a path: ``extends: {id: evil.yaml}`` does not open a file of that name. The
    shipped profiles win, so a file in the tender's folder (or a plugin) cannot stand in for a
    shipped standard.
    """
    def match(rows: list[tuple[str, str, str, Path]]) -> list[tuple[str, str, str, Path]]:
        return [t for t in rows if t[0] == pid and (version is None or t[1] == version)]

    shipped = available()
    hits = match(shipped)
    if not hits and near is not None and near.resolve() != specs_dir().resolve():
        local = [t for t in available([near]) if t[3].parent.resolve() == near.resolve()]
        hits = match(local)
        if version is not None and len(hits) > 1:
            files = ", ".join(str(t[3]) for t in hits)
            raise SpecError(
                f"profile {pid!r} version {version} is defined by several files: {files}"
            )
    if not hits:  # plugins are looked for only when needed: importlib.metadata costs ~0.1 s
        hits = match(plugin_profiles())
        if version is not None and len(hits) > 1:
            files = ", ".join(str(t[3]) for t in hits)
            raise SpecError(
                f"profile {pid!r} version {version} is shipped by several plugins: {files}"
            )
    if hits:
        return sorted(hits, key=lambda t: _semver_key(t[1]))[-1][3]
    raise SpecError(_unknown_profile(pid, version, near))


def _unknown_profile(pid: str, version: str | None, near: Path | None) -> str:
    """One short message for an id (and version) nobody has: the versions that exist, else the
    nearest id; the shipped and plugin profiles by id, the local folder's files only counted (a
    tender's folder of variants once made this message list the same id 23 times)."""
    shared = sorted({(i, v) for i, v, _, _ in (*available(), *plugin_profiles())})
    local = (
        []
        if near is None
        else sorted(
            {(i, v) for i, v, _, f in available([near]) if f.parent.resolve() == near.resolve()}
            - set(shared)
        )
    )
    pin = f" version {version}" if version else ""
    versions = sorted({v for i, v in (*shared, *local) if i == pid}, key=_semver_key)
    if versions:
        hint = f"; {pid} exists in version {', '.join(versions)}: pin one of them"
    else:
        close = difflib.get_close_matches(
            pid, sorted({i for i, _ in (*shared, *local)}), n=1, cutoff=0.6
        )
        hint = f"; did you mean {close[0]!r}?" if close else ""
    known = ", ".join(f"{i} {v}" for i, v in shared) or "none"
    if local:
        ids = sorted({i for i, _ in local})
        known += (
            f"; and {len(local)} in {near}: "
            + ", ".join(ids[:5])
            + (" ..." if len(ids) > 5 else "")
        )
    return f"unknown profile {pid!r}{pin}{hint}; available: {known}"


def _semver_key(v: str) -> tuple[Any, ...]:
    m = re.match(r"(\d+)\.(\d+)\.(\d+)(.*)", v)
    if not m:
        return (0, 0, 0, v)
    return (int(m[1]), int(m[2]), int(m[3]), m[4] == "", m[4])
