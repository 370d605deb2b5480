"""Reading profile files: each parsed (YAML with line and column of every node) at most once
per content per process, and the SHA-256 of the bytes last parsed for each file (what the cache
of resolved profiles checks its chain against)."""

from __future__ import annotations

import hashlib
from pathlib import Path

from ..resources import shown
from ..yamlio import Located, YamlError, load_text, read_regular

_DOCS: dict[tuple[str, str], Located] = {}

_LAST_SHA: dict[str, str] = {}  # file -> SHA-256 of the content last parsed


def _file_bytes(path: Path) -> bytes:
    return read_regular(path)


def file_sha256(path: Path) -> str:
    return hashlib.sha256(_file_bytes(path)).hexdigest()


def _load_doc(path: Path) -> tuple[Located, str]:
    """The parsed document and the SHA-256 of its bytes, parsed at most once per content."""
    raw = _file_bytes(path)
    sha = hashlib.sha256(raw).hexdigest()
    key = (str(path), sha)
    doc = _DOCS.get(key)
    if doc is None:
        try:
            text = raw.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")
        except UnicodeDecodeError as exc:
            raise YamlError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
        doc = load_text(text, shown(path))  # specs/NAME, not the install path
        if len(_DOCS) > 64:
            _DOCS.clear()
        _DOCS[key] = doc
    _LAST_SHA[str(path)] = sha
    return doc, sha
