"""On-disk cache of resolved, validated profiles (JSON, never pickle).

Where: ``$ORTHOSPEC_CACHE_DIR/profiles``, else ``$XDG_CACHE_HOME/orthospec/profiles``, else
``~/.cache/orthospec/profiles``; ``ORTHOSPEC_CACHE_DIR=off`` disables it. Safe to delete at any time.

Trust: an entry is used only when the SHA-256 of every file of its ``extends`` chain, as it is on
disk now, equals the hash recorded when the entry was written, when it was written by the same
orthospec code (version plus a fingerprint of the sources that decide validity), and when the
canonical profile it holds still hashes to its recorded ``sha256``. Anything else is a miss and
the profile is loaded and validated afresh. Entries are written atomically (temporary file +
rename), so a crash never leaves a half entry that could be read.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..yamlio import YamlError, read_regular

FORMAT = 1
_PKG = Path(__file__).resolve().parent.parent


def cache_dir() -> Path | None:
    """The profile cache folder, or None when caching is off."""
    env = os.environ.get("ORTHOSPEC_CACHE_DIR")
    if env is not None and env.strip().lower() in ("off", "none", "0", "no", ""):
        return None
    if env:
        return Path(env).expanduser() / "profiles"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "orthospec" / "profiles"


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """orthospec version + the sources that decide whether a profile is valid."""
    from .. import __version__
    from .catalog import fingerprint as measures_fingerprint

    h = hashlib.sha256(f"{FORMAT}|{__version__}|{measures_fingerprint()}".encode())
    files = [
        *sorted((_PKG / "profile").glob("*.py")),
        _PKG / "units.py",
        _PKG / "yamlio.py",
        _PKG / "delivery" / "manifest.py",
    ]
    for p in files:
        h.update(p.name.encode() + b"\0")
        try:
            h.update(hashlib.sha256(p.read_bytes()).digest())
        except OSError:
            h.update(b"(absent)")
    return h.hexdigest()


def key(path: Path, sha256: str) -> str:
    """Cache key of a profile file: its path (as given, and from where), content hash and the code.

    The path as given is part of the key because the resolved profile records it (and the chain's
    file names) for display; the working folder too when the path is relative.
    """
    where = "" if path.is_absolute() else os.getcwd()
    text = f"{code_fingerprint()}|{where}|{path}|{path.resolve()}|{sha256}"
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _sha(path: str) -> str | None:
    try:
        return hashlib.sha256(read_regular(Path(path))).hexdigest()
    except (OSError, YamlError):
        return None


def chain_current(chain_shas: list[tuple[str, str]] | tuple[tuple[str, str], ...]) -> bool:
    """Whether every file of a recorded chain still has the recorded content."""
    return bool(chain_shas) and all(_sha(f) == sha for f, sha in chain_shas)


def get(k: str) -> tuple[dict[str, Any], list[tuple[str, str]]] | None:
    """The cached payload for key ``k`` and its chain hashes, or None (miss, stale or unreadable).

    The payload is the JSON the loader wrote (``loader.dump_resolved``); the loader rebuilds the
    profile from it (and treats a payload it cannot rebuild as a miss), so this module never
    imports the loader."""
    d = cache_dir()
    if d is None:
        return None
    f = d / f"{k}.json"
    try:
        doc = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    try:
        if doc.get("format") != FORMAT or doc.get("key") != k:
            return None
        chain_shas = [(str(a), str(b)) for a, b in doc["files"]]
        if not chain_current(chain_shas):
            return None
        payload = doc["profile"]
        if not isinstance(payload, dict):
            return None
    except (
        KeyError,
        TypeError,
        ValueError,
        AttributeError,
    ):  # a damaged entry is a miss, never an error
        return None
    return payload, chain_shas


def put(k: str, payload: dict[str, Any], chain_shas: list[tuple[str, str]]) -> None:
    """Write an entry atomically; a cache that cannot be written is silently skipped."""
    d = cache_dir()
    if d is None:
        return
    doc = {"format": FORMAT, "key": k, "files": [list(t) for t in chain_shas], "profile": payload}
    try:
        d.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=".json", dir=d)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                json.dump(doc, fh, ensure_ascii=False, separators=(",", ":"), allow_nan=False)
            os.replace(tmp, d / f"{k}.json")
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except (OSError, ValueError, TypeError):
        return
