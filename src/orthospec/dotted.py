"""Dotted names in parsed expressions (``manifest.sensor.digital``), shared by the profile
expression grammar (profile/expr.py), the delivery vocabulary (delivery/vocabulary.py) and the
engine's name analysis (engine/names.py). Foundation layer: it imports nothing of orthospec, so
the expression grammar does not pull the vocabulary's pandas in (+0.4 s start-up)."""

from __future__ import annotations

import ast
from collections.abc import Collection


def dotted_name(node: ast.AST, *, reserved: Collection[str] = ()) -> str | None:
    """``a.b.c`` for a chain of attributes on a name; None for anything else or a ``reserved`` head."""
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name) and node.id not in reserved:
        return ".".join([node.id, *reversed(parts)])
    return None
