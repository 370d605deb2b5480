"""A draft delivery: what ``orthospec init DIR --from SOURCE`` writes (issue 27, docs/INGEST.md).

A draft holds the manifest and the tables the files allowed to write, and reads the delivered
files *in place*: nothing is copied. Under ``draft.links`` (default ``source/``) it keeps one
symbolic link per delivered file, pointing into the source folder (``draft.source``). Those links
lead out of the draft, which the containment rule (:func:`orthospec.delivery.paths.contained`)
refuses for any other delivery; :class:`SourceLinks` is the one exception it makes: a link under
``draft.links`` whose real target lies inside the real ``draft.source`` folder. Anything else
that leads out (a link elsewhere in the draft, a link under ``source/`` into any other folder) is
still refused, and the source itself must be a plain folder that neither holds nor is held by the
draft.

``TODO.md`` lists what the files could not tell; ``draft.todo_rules`` maps each rule that stays
``missing`` until a TODO entry is filled to that entry's line, so a ``missing`` record can name it
(:func:`todo_citations`, read by the evaluator).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path, PurePosixPath
from typing import Any

from ..errors import DeliveryError
from .convention import TableSpec

#: the largest rule -> TODO line map a draft may carry (a profile has a few hundred rules)
TODO_MAP_BYTES = 4 << 20


@dataclass(frozen=True)
class SourceLinks:
    """The draft's links into its source folder: which out-leading links the containment allows."""

    #: the draft folder's links directory, as written (``root/source``), not resolved
    links: Path
    #: the real (resolved) source folder
    source: Path

    def allows(self, lexical: Path, real: Path) -> bool:
        """True when ``lexical`` (a path under the draft root, as written) lies under the links
        folder and its real target lies inside the real source folder."""
        return lexical.is_relative_to(self.links) and real.is_relative_to(self.source)


def source_links(root: Path, draft: Any, *, line: int | None) -> SourceLinks | None:
    """The :class:`SourceLinks` of a draft manifest's ``draft:`` section, or None for a delivery.

    Raises
    ------
    DeliveryError
        (naming delivery.yaml and the line) when the source is not a folder, is the file system
        root, holds the draft or lies inside it, or when ``links`` is not one plain folder name.
    """
    if draft is None:
        return None

    def refuse(why: str) -> DeliveryError:
        return DeliveryError(
            f"draft.source {draft.source!r} {why}", file="delivery.yaml", line=line
        )

    name = PurePosixPath(draft.links)
    if len(name.parts) != 1 or name.parts[0] in (".", "..") or "\\" in draft.links:
        raise DeliveryError(
            f"draft.links {draft.links!r} must be one folder name inside the draft",
            file="delivery.yaml",
            line=line,
        )
    src = Path(draft.source)
    if not src.is_absolute():
        src = root / src
    try:
        real = src.resolve(strict=True)
        real_root = root.resolve(strict=True)
    except (OSError, RuntimeError) as exc:
        raise refuse(f"cannot be resolved ({exc})") from None
    if not real.is_dir():
        raise refuse("is not a folder")
    if real == Path(real.anchor):
        raise refuse("is the file system root; a draft reads one delivery's folder")
    if real_root.is_relative_to(real) or real.is_relative_to(real_root):
        raise refuse("holds the draft or lies inside it; the source and the draft are two folders")
    return SourceLinks(root / name.parts[0], real)


def draft_images_spec(spec: TableSpec) -> TableSpec:
    """The images table of a draft: ``block`` may be empty (no outlines given: unknown, listed in
    TODO.md, never guessed). Safe to leave open: a finding on an image of unknown block that would
    reject its block returns the whole delivery (engine/rollup.py), and block items come from the
    manifest or the point tables, never from an empty cell."""
    col = spec.columns.get("block")
    if col is None or not col.required:
        return spec
    return replace(spec, columns={**spec.columns, "block": replace(col, required=False)})


def todo_citations(path_of: Callable[..., Path], draft: Any) -> dict[str, str]:
    """Rule id -> ``"TODO.md line N: <what>"`` from the draft's ``todo_rules`` map ({} without one).

    The map is written by ``init --from``; a damaged one is refused (exit 2), never ignored, so a
    ``missing`` record never silently loses its pointer. ``path_of`` is the delivery's contained
    path resolver (``Delivery.path``).
    """
    if draft is None or not draft.todo_rules:
        return {}
    p = path_of(draft.todo_rules, what="draft.todo_rules")
    try:
        if p.stat().st_size > TODO_MAP_BYTES:
            raise DeliveryError(f"larger than {TODO_MAP_BYTES} bytes", file=draft.todo_rules)
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DeliveryError(
            f"cannot be read as the draft's TODO map: {exc}", file=draft.todo_rules
        ) from None
    if not isinstance(data, dict) or not all(
        isinstance(k, str)
        and isinstance(v, list)
        and len(v) == 2
        and isinstance(v[0], int)
        and isinstance(v[1], str)
        for k, v in data.items()
    ):
        raise DeliveryError("expected {rule id: [line, what]}", file=draft.todo_rules)
    return {k: f"{draft.todo} line {v[0]}: {v[1]}" for k, v in data.items()}
