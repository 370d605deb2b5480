"""YAML reading that remembers where every value came from (line and column).

PyYAML's composer keeps marks on nodes; we build plain Python objects from the node tree
ourselves so that validation errors can name ``file:line:column`` and duplicate keys are refused
(YAML allows them silently; a tender author never means them).

Profiles and manifests are untrusted text, so the document is measured on its node graph before any
Python object is built (issue 17): file size, nesting depth, distinct nodes and the extra nodes
that aliases expand to are bounded (:class:`YamlLimits`), and a recursive alias is refused. An
alias bomb is refused in milliseconds instead of being expanded.

A foundation module (below delivery/ and spec/): the manifest, profiles and the checker's file
are all read through it.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from . import controls
from .errors import OrthospecError
from .limits import env_limit

Path_ = tuple[str | int, ...]


class YamlError(OrthospecError, ValueError):
    """A YAML document could not be parsed; ``file``, ``line``, ``column`` when known (1-based)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        m = _WHERE.match(message)
        self.file: str | None = m.group("file") if m else None
        self.line: int | None = int(m.group("line")) if m and m.group("line") else None
        self.column: int | None = int(m.group("col")) if m and m.group("col") else None


_WHERE = re.compile(r"^(?P<file>[^\n]+?)(?::(?P<line>\d+)(?::(?P<col>\d+))?)?: ")




@dataclass(frozen=True)
class YamlLimits:
    """Bounds on one YAML document; defaults far above a real profile or manifest.

    A 100,000-rule profile is about 30 MB and 3 million nodes with no alias; a manifest is a few
    kB. Set by ``ORTHOSPEC_MAX_YAML_BYTES``, ``ORTHOSPEC_MAX_YAML_NODES``,
    ``ORTHOSPEC_MAX_YAML_ALIAS_NODES`` and ``ORTHOSPEC_MAX_YAML_DEPTH``.
    """

    bytes: int = 64 * 2**20
    nodes: int = 20_000_000
    alias_nodes: int = 1_000_000
    depth: int = 200

    @classmethod
    def from_env(cls) -> YamlLimits:
        d = cls()
        return cls(
            bytes=env_limit("ORTHOSPEC_MAX_YAML_BYTES", d.bytes, error=YamlError),
            nodes=env_limit("ORTHOSPEC_MAX_YAML_NODES", d.nodes, error=YamlError),
            alias_nodes=env_limit("ORTHOSPEC_MAX_YAML_ALIAS_NODES", d.alias_nodes, error=YamlError),
            depth=env_limit("ORTHOSPEC_MAX_YAML_DEPTH", d.depth, error=YamlError),
        )


def _at(file: str, node: yaml.Node) -> str:
    return f"{file}:{node.start_mark.line + 1}:{node.start_mark.column + 1}: "


def _measure(root: yaml.Node, file: str, limits: YamlLimits) -> None:
    """Refuse a node graph that is too deep, too big, recursive, or that aliases blow up.

    Works on the composed graph, where an alias is a second reference to the same node, so the
    cost is linear in the distinct nodes whatever the aliases would expand to.
    """
    memo: dict[int, int] = {}
    active: set[int] = set()
    unique = 0

    def size(n: yaml.Node, depth: int) -> int:
        nonlocal unique
        k = id(n)
        if k in memo:
            return memo[k]
        if k in active:
            raise YamlError(
                f"{_at(file, n)}a recursive alias (a node that contains itself) is not allowed"
            )
        if depth > limits.depth:
            raise YamlError(f"{_at(file, n)}nested more than {limits.depth} levels deep")
        unique += 1
        if unique > limits.nodes:
            raise YamlError(
                f"{_at(file, n)}more than {limits.nodes:,} YAML nodes (ORTHOSPEC_MAX_YAML_NODES)"
            )
        active.add(k)
        total = 1
        if isinstance(n, yaml.ScalarNode) and isinstance(n.value, str):
            at = controls.find_in_text(n.value)
            if at is not None:
                raise YamlError(
                    f"{_at(file, n)}a control character ({controls.name(n.value[at])}) in a value: "
                    "terminal and bidirectional-override controls are not allowed"
                )
        if isinstance(n, yaml.MappingNode):
            for kn, vn in n.value:
                total += size(kn, depth + 1) + size(vn, depth + 1)
        elif isinstance(n, yaml.SequenceNode):
            for c in n.value:
                total += size(c, depth + 1)
        active.discard(k)
        memo[k] = total
        return total

    total = size(root, 0)
    if total - unique > limits.alias_nodes:
        raise YamlError(
            f"{file}: aliases (*name) expand the document to {total:,} nodes, more than "
            f"{limits.alias_nodes:,} beyond its {unique:,} written ones (an alias bomb?); "
            "not expanded (ORTHOSPEC_MAX_YAML_ALIAS_NODES)"
        )


def _construct(loader: yaml.SafeLoader, node: yaml.Node, file: str) -> Any:
    """A scalar (or key) as Python; a value YAML's own types reject names file:line:col."""
    try:
        return loader.construct_object(node, deep=True)
    except (ValueError, TypeError, OverflowError) as exc:  # 2026-02-30, 10**5000 digits...
        value = node.value if isinstance(node, yaml.ScalarNode) else node.tag
        raise YamlError(f"{_at(file, node)}invalid value {str(value)[:80]!r}: {exc}") from None


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

    def located_errors(
        self, errors: Sequence[Mapping[str, Any]], display: str, hint: Any = None
    ) -> list[str]:
        """``file:line:col: dotted.path: message`` for (at most 20 of) a pydantic validation's
        errors, so the manifest and the checker's file word their mistakes alike; ``hint(error)``
        may append advice (a did-you-mean)."""
        lines = []
        for e in errors[:20]:
            loc = tuple(e["loc"])
            line, col = self.where(loc)
            where = f"{display}:{line}:{col}" if line else display
            extra = hint(e) if hint else ""
            lines.append(f"{where}: {'.'.join(map(str, loc)) or '(document)'}: {e['msg']}{extra}")
        return lines


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """libyaml's parser and composer when available (10x faster, same nodes and marks)."""


def _build(
    node: yaml.Node, path: Path_, marks: dict[Path_, tuple[int, int]], loader: _Loader, file: str
) -> Any:
    marks[path] = (node.start_mark.line + 1, node.start_mark.column + 1)
    if isinstance(node, yaml.MappingNode):
        loader.flatten_mapping(node)
        out: dict[Any, Any] = {}
        for knode, vnode in node.value:
            if not isinstance(knode, yaml.ScalarNode):
                raise YamlError(f"{_at(file, knode)}mapping keys must be scalars")
            key = _construct(loader, knode, file)
            if not isinstance(key, str | int | float | bool) and key is not None:
                raise YamlError(
                    f"{file}:{knode.start_mark.line + 1}:{knode.start_mark.column + 1}: "
                    f"mapping keys must be scalars"
                )
            if key in out:
                raise YamlError(
                    f"{file}:{knode.start_mark.line + 1}:{knode.start_mark.column + 1}: "
                    f"duplicate key {key!r}"
                )
            skey = key if isinstance(key, str) else str(key)
            out[skey] = _build(vnode, (*path, skey), marks, loader, file)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_build(v, (*path, i), marks, loader, file) for i, v in enumerate(node.value)]
    return _construct(loader, node, file)


_BRACKETS = re.compile(r"[\[\]{}]")


def _flow_depth(text: str, file: str, limits: YamlLimits) -> None:
    """Refuse deep ``[[[[...`` nesting before libyaml scans it (its scanner is quadratic in it:
    20,000 levels take 9 s). Brackets inside quoted text count too, so the gate is 5x the limit."""
    if text.count("[") + text.count("{") <= 5 * limits.depth:
        return
    depth = 0
    for m in _BRACKETS.finditer(text):
        depth += 1 if m.group() in "[{" else -1
        if depth > 5 * limits.depth:
            line = text.count("\n", 0, m.start()) + 1
            raise YamlError(f"{file}:{line}: nested more than {limits.depth} levels deep")


def load_text(text: str, file: str, *, limits: YamlLimits | None = None) -> Located:
    """Parse one YAML document with the safe loader, keeping positions, within ``limits``."""
    lim = limits or YamlLimits.from_env()
    if len(text) > lim.bytes:
        raise YamlError(
            f"{file}: {len(text):,} characters exceed the limit of {lim.bytes:,} "
            "(ORTHOSPEC_MAX_YAML_BYTES)"
        )
    _flow_depth(text, file, lim)
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return Located(None, file, {(): (1, 1)}, text)
        _measure(node, file, lim)
        marks: dict[Path_, tuple[int, int]] = {}
        data = _build(node, (), marks, loader, file)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        pos = f"{mark.line + 1}:{mark.column + 1}: " if mark else ""
        raise YamlError(f"{file}:{pos}invalid YAML: {exc.problem or exc}") from None
    except yaml.YAMLError as exc:
        raise YamlError(f"{file}: invalid YAML: {exc}") from None
    except RecursionError:
        raise YamlError(f"{file}: invalid YAML: nested too deeply to read") from None
    finally:
        loader.dispose()
    return Located(data, file, marks, text)


def load_file(
    path: str | Path, *, display: str | None = None, limits: YamlLimits | None = None
) -> Located:
    """Read and parse a YAML file: a regular file, UTF-8, within the size limit."""
    p = Path(path)
    name = display or str(path)
    lim = limits or YamlLimits.from_env()
    try:
        with open(p, "rb", opener=_nonblocking) as fh:
            st = os.fstat(fh.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise YamlError(f"{name}: not a regular file")
            if st.st_size > lim.bytes:
                raise YamlError(
                    f"{name}: {st.st_size:,} bytes exceed the limit of {lim.bytes:,} "
                    "(ORTHOSPEC_MAX_YAML_BYTES)"
                )
            text = fh.read(lim.bytes + 1).decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")
    except FileNotFoundError:
        raise YamlError(f"{name}: file not found") from None
    except UnicodeDecodeError as exc:
        raise YamlError(f"{name}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise YamlError(f"{name}: cannot read: {exc.strerror}") from None
    return load_text(text, name, limits=lim)


def read_regular(path: Path, limit: int | None = None) -> bytes:
    """The bytes of a regular file, at most ``limit`` (default: the YAML size limit).

    Opened without blocking and checked with fstat, so a FIFO or device named like a profile is
    refused instead of waited on or read forever (issue 17).
    """
    lim = YamlLimits.from_env().bytes if limit is None else limit
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise YamlError(f"{path}: file not found") from None
    except OSError as exc:
        raise YamlError(f"{path}: cannot read: {exc.strerror}") from None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise YamlError(f"{path}: not a regular file")
        if limit is None and st.st_size > lim:
            raise YamlError(
                f"{path}: {st.st_size:,} bytes exceed the limit of {lim:,} (ORTHOSPEC_MAX_YAML_BYTES)"
            )
        return fh.read(lim)


def _nonblocking(path: str, flags: int) -> int:
    """Open without blocking, so a FIFO in place of a YAML file is refused, not waited on."""
    return os.open(path, flags | getattr(os, "O_NONBLOCK", 0))
