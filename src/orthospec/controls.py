"""Control and bidirectional-override characters: refused where delivery or profile text is read.

An id or a text with ESC, VT or U+202E (right-to-left override) would drive the auditor's terminal,
reorder what the PDF and the HTML page show, or make two ids look alike in qcr.csv (issue 28). They
are refused once, where a table or a YAML file is read (exit 2 naming file and line), so no output
writer has to remember them. Tab, line feed and carriage return stay (CSV and YAML use them).
"""

from __future__ import annotations

import re

#: C0 controls but tab/LF/CR, DEL, C1 controls, and the Unicode bidirectional embedding, override and
#: isolate controls (U+202A-U+202E, U+2066-U+2069)
_TEXT = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")
#: the same characters as UTF-8 bytes (C1 as \xc2\x80-\xc2\x9f, the bidi controls as E2 80 AA-AE / E2 81 A6-A9)
_UTF8 = re.compile(
    rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]|\xc2[\x80-\x9f]|\xe2\x80[\xaa-\xae]|\xe2\x81[\xa6-\xa9]"
)


def name(ch: str) -> str:
    """How a message names the character: U+001B."""
    return f"U+{ord(ch):04X}"


def find_in_text(text: str) -> int | None:
    """Index of the first refused character in ``text``, or None."""
    m = _TEXT.search(text)
    return None if m is None else m.start()


def find_in_utf8(body: bytes) -> tuple[int, str] | None:
    """(1-based line, the character) of the first refused character in UTF-8 ``body``, or None."""
    m = _UTF8.search(body)
    if m is None:
        return None
    return body.count(b"\n", 0, m.start()) + 1, m.group().decode("utf-8", "replace")
