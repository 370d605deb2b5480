"""YAML reading that remembers where every value came from (line and column).

PyYAML's composer keeps marks on nodes; we build plain Python objects from the node tree
ourselves so that validation errors can name ``file:line:column`` and duplicate keys are refused
(YAML allows them silently; a tender author never means them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ..errors import OrthospecError

Path_ = tuple[str | int, ...]


class YamlError(OrthospecError, ValueError):
    """A YAML document could not be parsed."""


@dataclass
class Located:
    """A parsed YAML document plus the position of every node by its path."""

    data: Any
    file: str
    marks: dict[Path_, tuple[int, int]] = field(default_factory=dict)
    text: str = ""

    def where(self, path: Path_) -> tuple[int | None, int | None]:
        """Line and column (1-based) of ``path``, or of its nearest located parent."""
        p = tuple(path)
        while p:
            if p in self.marks:
                return self.marks[p]
            p = p[:-1]
        return self.marks.get((), (None, None))


class _Loader(yaml.SafeLoader):
    pass


def _build(node: yaml.Node, path: Path_, marks: dict[Path_, tuple[int, int]],
           loader: _Loader, file: str) -> Any:
    marks[path] = (node.start_mark.line + 1, node.start_mark.column + 1)
    if isinstance(node, yaml.MappingNode):
        loader.flatten_mapping(node)
        out: dict[Any, Any] = {}
        for knode, vnode in node.value:
            key = loader.construct_object(knode, deep=True)
            if not isinstance(key, str | int | float | bool) and key is not None:
                raise YamlError(f"{file}:{knode.start_mark.line + 1}:{knode.start_mark.column + 1}: "
                                f"mapping keys must be scalars")
            if key in out:
                raise YamlError(f"{file}:{knode.start_mark.line + 1}:{knode.start_mark.column + 1}: "
                                f"duplicate key {key!r}")
            skey = key if isinstance(key, str) else str(key)
            out[skey] = _build(vnode, (*path, skey), marks, loader, file)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_build(v, (*path, i), marks, loader, file) for i, v in enumerate(node.value)]
    return loader.construct_object(node, deep=True)


def load_text(text: str, file: str) -> Located:
    """Parse one YAML document with the safe loader, keeping positions."""
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return Located(None, file, {(): (1, 1)}, text)
        marks: dict[Path_, tuple[int, int]] = {}
        data = _build(node, (), marks, loader, file)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        pos = f"{mark.line + 1}:{mark.column + 1}: " if mark else ""
        raise YamlError(f"{file}:{pos}invalid YAML: {exc.problem or exc}") from None
    except yaml.YAMLError as exc:
        raise YamlError(f"{file}: invalid YAML: {exc}") from None
    finally:
        loader.dispose()
    return Located(data, file, marks, text)


def load_file(path: str | Path, *, display: str | None = None) -> Located:
    p = Path(path)
    name = display or str(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise YamlError(f"{name}: file not found") from None
    except UnicodeDecodeError as exc:
        raise YamlError(f"{name}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise YamlError(f"{name}: cannot read: {exc.strerror}") from None
    return load_text(text, name)
