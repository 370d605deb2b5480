"""qcr.json: the document as text, one record (or one rule's compact block) per line.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator, Mapping
from typing import Any

from .columns import _LARGE


def dumps(doc: Mapping[str, Any]) -> str:
    """qcr.json text: readable header, then one record (or one rule's compact block) per line."""
    return "".join(iter_dumps(doc))


#: top-level keys written one element per line (a list's items, a mapping's entries) through the C
#: encoder; the other keys are small and written as ``json.dumps(value, indent=1)`` would
_PER_LINE = ("rules", "records", "compact", "evidence", "details")


def iter_dumps(doc: Mapping[str, Any]) -> Iterator[str]:
    """qcr.json as a stream of pieces (written to the file one by one; same bytes as :func:`dumps`).

    The header keys as ``json.dumps(doc, indent=1)`` would write them; ``rules``, ``records``,
    ``compact``, ``evidence`` and ``details`` one element per line (a rule summary, a record, one
    rule's columns, an evidence entry, one measure's detail), each compact: greppable, diffable,
    no piece larger than one element, and every large value goes through json's C encoder (the
    pure-Python one that ``indent`` needs took most of the time at a million check points)."""
    enc = json.JSONEncoder(ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode
    yield "{"
    for n, (key, value) in enumerate(doc.items()):
        yield ("\n " if n == 0 else ",\n ") + enc(str(key)) + ": "
        if key in _PER_LINE and isinstance(value, list) and value:
            for k, item in enumerate(value):
                yield ("[\n  " if k == 0 else ",\n  ") + enc(item)
            yield "\n ]"
        elif key in _PER_LINE and isinstance(value, dict) and value:
            for k, (name, item) in enumerate(value.items()):
                yield (
                    ("{\n  " if k == 0 else ",\n  ")
                    + enc(str(name))
                    + ": "
                    + _encode_columns(enc, item)
                )
            yield "\n }"
        else:
            yield json.dumps(value, indent=1, ensure_ascii=False, allow_nan=False).replace(
                "\n", "\n "
            )
    yield "\n}\n"


#: a list of at least this many texts is written by one join when none needs an escape
_JSON_JOIN_MIN = 256


def _encode_columns(enc: Any, value: Any) -> str:
    """``enc(value)``; a mapping's long columns of text (a compact block's item ids) joined at once
    when no text needs a JSON escape (a fifth of the encoder's time for a million ids)."""
    if (
        not isinstance(value, dict)
        or not all(type(k) is str for k in value)
        or not any(type(v) is list and len(v) >= _JSON_JOIN_MIN for v in value.values())
    ):
        return str(enc(value))
    parts = []
    for k, v in value.items():
        text = _json_texts(v) if type(v) is list and len(v) >= _JSON_JOIN_MIN else None
        parts.append(enc(k) + ":" + (enc(v) if text is None else text))
    return "{" + ",".join(parts) + "}"


#: what json escapes in a text besides the quote and the backslash (ensure_ascii=False)
_JSON_CONTROL = re.compile("[\x00-\x1f]")
_JSON_CONTROL_ASCII = bytes(range(32))


def _json_texts(values: list[Any]) -> str | None:
    """A list of texts as the JSON encoder writes it (``["a","b"]``), or None when one is not text
    or needs an escape (a quote, a backslash, a control character)."""
    try:
        joined = '","'.join(values)
    except TypeError:
        return None
    if joined.count('"') != 2 * (len(values) - 1) or "\\" in joined:
        return None
    if len(joined) >= _LARGE and joined.isascii():
        b = joined.encode("ascii")
        if len(b.translate(None, _JSON_CONTROL_ASCII)) != len(b):
            return None
    elif _JSON_CONTROL.search(joined):
        return None
    return '["' + joined + '"]'
