"""The external anchor: an append-only file outside the ledger that receives every new chain head.

Set ``$ORTHOSPEC_LEDGER_ANCHOR`` to a path the ledger's editors cannot rewrite (another host, an
append-only share): every write appends ``SEQ HASH``, and ``verify`` checks that each head in it
is still in the chain, as if each were given with ``--head``.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import LedgerError

#: an append-only file outside the ledger that receives every new chain head ("seq hash" lines);
#: `verify` then checks that each head in it is still in the chain (an external anchor)
ENV_ANCHOR = "ORTHOSPEC_LEDGER_ANCHOR"


def append_anchor(seq: int, head: str) -> None:
    """Append the new head to the anchor file named by $ORTHOSPEC_LEDGER_ANCHOR (if set)."""
    path = os.environ.get(ENV_ANCHOR)
    if not path:
        return
    try:
        with open(path, "a", encoding="utf-8") as fh:
            fh.write(f"{seq} {head}\n")
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        raise LedgerError(
            f"recorded, but the head could not be appended to ${ENV_ANCHOR} {path}: {exc}"
        ) from None


def read_anchors() -> list[tuple[int, tuple[int, str]]]:
    """(line number, (seq, hash)) of the anchor file; a missing file is an error when the variable is set."""
    path = os.environ.get(ENV_ANCHOR)
    if not path:
        return []
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        return []  # nothing recorded yet with this anchor
    except OSError as exc:
        raise LedgerError(f"${ENV_ANCHOR} {path}: cannot read: {exc}") from None
    out = []
    for n, line in enumerate(text.splitlines(), start=1):
        parts = line.split()
        if len(parts) != 2 or not parts[0].isdigit() or len(parts[1]) != 64:
            raise LedgerError(f"${ENV_ANCHOR} {path}:{n}: expected 'SEQ HASH', got {line[:80]!r}")
        out.append((n, (int(parts[0]), parts[1].lower())))
    return out
