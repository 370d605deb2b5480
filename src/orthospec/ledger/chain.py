"""Tamper evidence: canonical content of a ledger entry and its chained SHA-256.

An entry's hash is ``sha256(canonical_json({"kind", "content", "prev"}))`` where ``content`` is
every stored column of the entry (and, for a run, its file and QCR rows) and ``prev`` is the hash
of the entry before it. Editing any column, deleting any row or reordering entries breaks the
chain at that point; the head row catches removal of the newest entries.

A run's canonical text is
``{"content":{"files":[...by path],"qcrs":[...by ordinal],"run":{...}},"kind":"run","prev":"..."}``
(sorted keys at every level, ``run_id`` left out of file and QCR rows, ``hash`` out of the run row).
:class:`RunHasher` feeds exactly that text to SHA-256 piece by piece, so a run of a million QCR rows
is hashed in batches without the text (or the rows) ever being in memory at once.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator, Mapping, Sequence
from json.encoder import encode_basestring  # what the encoder below writes a text with
from typing import Any

#: columns added after schema 0001: they enter an entry's canonical text only when set, so an entry
#: recorded before them (NULL there) keeps its hash
ADDED_COLUMNS = frozenset({"audit_key", "continues_run", "signer", "key_fingerprint", "signature"})
#: one encoder for every canonical text (``json.dumps`` with these options builds a new one per call)
_ENC = json.JSONEncoder(sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
#: a text value longer than this (a run's qcr.json document) is escaped and hashed in pieces of it
_CHUNK = 1 << 20


def canonical(obj: Any) -> str:
    """Sorted-key, compact JSON: the same content gives the same text on every database."""
    return _ENC.encode(obj)


def sha256_text(text: str) -> str:
    """SHA-256 of the UTF-8 text, encoded a chunk at a time (a document may be tens of MB)."""
    h = hashlib.sha256()
    for i in range(0, len(text), _CHUNK):
        h.update(text[i : i + _CHUNK].encode("utf-8"))
    return h.hexdigest()


def _canonical_pieces(d: Mapping[str, Any]) -> Iterator[str]:
    """``canonical(d)`` of a flat mapping in pieces: a long text value in escaped chunks (JSON
    escapes character by character, so the escaped chunks join to the escaped whole)."""
    yield "{"
    for n, (k, v) in enumerate(sorted(d.items())):
        yield ("," if n else "") + encode_basestring(str(k)) + ":"
        if isinstance(v, str) and len(v) > _CHUNK:
            yield '"'
            for i in range(0, len(v), _CHUNK):
                yield encode_basestring(v[i : i + _CHUNK])[1:-1]
            yield '"'
        else:
            yield _ENC.encode(v)
    yield "}"


def _hashed(row: Mapping[str, Any]) -> dict[str, Any]:
    """The columns of an entry's row its hash covers: all but ``hash``, added columns only when set."""
    return {k: v for k, v in row.items() if k != "hash" and not (v is None and k in ADDED_COLUMNS)}


class RunHasher:
    """The chain hash of a run, fed its files, then its QCR rows in ordinal order batch by batch,
    then the run row: the digest of the whole canonical text (module docstring) fed at once."""

    def __init__(self, files: Sequence[Mapping[str, Any]], prev: str) -> None:
        self._h = hashlib.sha256()
        self._prev = prev
        self._first = True
        ordered = sorted(
            ({k: v for k, v in f.items() if k != "run_id"} for f in files), key=lambda f: f["path"]
        )
        self._update('{"content":{"files":' + _ENC.encode(ordered) + ',"qcrs":[')

    def _update(self, text: str) -> None:
        self._h.update(text.encode("utf-8"))

    def qcr_texts(self, texts: Sequence[str]) -> None:
        """The next QCR rows as their canonical texts (``canonical(row)`` each, ordinal order)."""
        if not texts:
            return
        self._update(("" if self._first else ",") + ",".join(texts))
        self._first = False

    def hexdigest(self, run: Mapping[str, Any]) -> str:
        """Finish with the run row (its ``hash`` left out) and return the hash."""
        self._update('],"run":')
        for piece in _canonical_pieces(_hashed(run)):
            self._update(piece)
        self._update('},"kind":"run","prev":' + _ENC.encode(self._prev) + "}")
        return self._h.hexdigest()


def signoff_hash(signoff: Mapping[str, Any], prev: str) -> str:
    """Hash of a sign-off row; it embeds the signed run's hash, binding the two."""
    content = _hashed(signoff)
    return sha256_text(canonical({"kind": "signoff", "content": content, "prev": prev}))
