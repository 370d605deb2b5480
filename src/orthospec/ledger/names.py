"""People's names as the ledger compares them: one person however the name is typed.

JRC §2.4 asks for an independent countersignature, so "is this the run's own checker?" must not
be answered by comparing free text: ``A. Auditor`` with a zero-width space or a soft hyphen in it,
with a Cyrillic ``А``, or written ``A.Auditor`` is the same person. Wherever names are compared
they go through :func:`name_keys`:

1. NFKC (compatibility forms: full-width letters, ligatures, superscripts fold to plain ones);
2. default-ignorable code points (Unicode DerivedCoreProperties, e.g. U+00AD SOFT HYPHEN,
   U+200B ZERO WIDTH SPACE, U+2060 WORD JOINER, variation selectors), other format and control
   characters removed;
3. the confusable skeleton (Unicode TR39 §4: each character mapped to the prototype of the
   characters it can be confused with; data of the ``confusable_homoglyphs`` package, built from
   Unicode's confusables.txt), case folded and mapped again, so ``I``/``l``/``1`` and ``А``/``A``
   meet;
4. spaces and punctuation dropped (``A. Auditor`` = ``A.Auditor`` = ``A Auditor``), and, as a second
   key, the words sorted (``Auditor, A.``).

Two names are the same person when either key is equal. This errs towards "same": two different
people whose names collide cannot countersign each other by name; keys (the allowed-signers
principal) tell them apart only if their principals differ too (e.g. an e-mail address).
"""

from __future__ import annotations

import unicodedata
from functools import lru_cache

__all__ = ["display_name", "name_keys", "same_person", "skeleton"]

#: Default_Ignorable_Code_Point (Unicode 15.1 DerivedCoreProperties.txt), inclusive ranges
_IGNORABLE = (
    (0x00AD, 0x00AD), (0x034F, 0x034F), (0x061C, 0x061C), (0x115F, 0x1160), (0x17B4, 0x17B5),
    (0x180B, 0x180F), (0x200B, 0x200F), (0x202A, 0x202E), (0x2060, 0x206F), (0x3164, 0x3164),
    (0xFE00, 0xFE0F), (0xFEFF, 0xFEFF), (0xFFA0, 0xFFA0), (0xFFF0, 0xFFF8), (0x1BCA0, 0x1BCA3),
    (0x1D173, 0x1D17A), (0xE0000, 0xE0FFF),
)


def _ignorable(ch: str) -> bool:
    cp = ord(ch)
    if any(lo <= cp <= hi for lo, hi in _IGNORABLE):
        return True
    return unicodedata.category(ch) in ("Cc", "Cf", "Cs", "Co", "Cn")


def display_name(name: str) -> str:
    """The name as shown and stored: NFKC, ignorable and control characters removed, one space
    between words. (What it still looks like; comparisons use :func:`name_keys`.)"""
    text = "".join(ch for ch in unicodedata.normalize("NFKC", name) if not _ignorable(ch))
    return " ".join(text.split())


@lru_cache(maxsize=1)
def _prototypes() -> dict[str, str]:
    """character -> the prototype of its confusable class.

    The package stores confusables.txt as a symmetric neighbour list (each source listed under its
    prototype and the prototype under the source, right-to-left characters wrapped in U+200E).
    Prototypes are never sources (the data is closed, skeleton(skeleton(x)) = skeleton(x)), so each
    class is a star: a character with one neighbour that has several (or that is a sequence) maps to
    it; two characters that only have each other map to the smaller, which gives both the same key.
    """
    from confusable_homoglyphs import confusables

    def clean(s: str) -> str:
        return s.replace("\u200e", "").replace("\u200f", "")

    neighbours: dict[str, set[str]] = {}
    for k, found in confusables.confusables_data.items():
        neighbours.setdefault(clean(k), set()).update(clean(f["c"]) for f in found)
    out: dict[str, str] = {}
    for ch, ns in neighbours.items():
        if len(ch) != 1 or len(ns) != 1:
            continue
        (p,) = ns
        out[ch] = p if len(p) > 1 or len(neighbours.get(p, ())) > 1 else min(ch, p)
    return out


def skeleton(text: str) -> str:
    """TR39 skeleton: NFD, each character to its confusable prototype, NFD again."""
    proto = _prototypes()
    nfd = unicodedata.normalize("NFD", text)
    return unicodedata.normalize("NFD", "".join(proto.get(ch, ch) for ch in nfd))


def name_keys(name: str) -> tuple[str, str]:
    """(all words run together, words sorted) of the name's case-folded skeleton (module docstring)."""
    shown = display_name(name)
    folded = skeleton(skeleton(shown).casefold())
    # letters, digits and their combining marks make words; anything else separates them
    kept = "".join(ch if unicodedata.category(ch)[0] in "LNM" else " " for ch in folded)
    words = kept.split()
    return "".join(words), " ".join(sorted(words))


def same_person(a: str | None, b: str | None) -> bool:
    """Whether two names are the same person (module docstring); an empty name is nobody."""
    if not a or not b:
        return False
    ka, kb = name_keys(a), name_keys(b)
    if not ka[0] or not kb[0]:
        return False
    return ka[0] == kb[0] or ka[1] == kb[1]
