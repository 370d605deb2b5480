"""Layers that only look down (issue 15 item 2): every import of every module, lazy ones included.

The graph is read with ``ast`` from the source files (imports at module level, inside functions
and inside ``try`` blocks alike). Checked:

* no cycle between modules, however indirect (``if TYPE_CHECKING:`` imports never run and are
  left out here);
* a module imports only modules of its own layer or of a lower one, in the order of
  docs/ARCHITECTURE.md ("Layers"), type-checking imports included;
* a measure provider (engine/providers/*, and so any plugin written like one) imports from the
  engine only engine/registry.py: the catalog imports the providers by name (pkgutil), an edge
  the parser cannot see, so a provider importing the catalog would be a hidden cycle.

``PENDING`` lists the edges a helper asked another file's owner to remove and that had not landed
when this test was written; an entry that no longer occurs fails the test, so the list only shrinks.
"""

from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

#: lowest first; a module's layer is that of its longest matching prefix
LAYERS: tuple[tuple[str, ...], ...] = (
    # foundation: no orthospec import above it (the package root only holds __version__ and lazy names)
    (
        "orthospec",
        "orthospec.errors",
        "orthospec.units",
        "orthospec.provenance",
        "orthospec.limits",
        "orthospec.resources",
        "orthospec.verdicts",
        "orthospec.yamlio",
        "orthospec.plugins",
        "orthospec.controls",
        "orthospec.workers",
        "orthospec._forkserver",
        "orthospec.outputs",
        "orthospec.dotted",
        "orthospec.present",
    ),
    ("orthospec.delivery",),  # the delivery convention and its readers
    ("orthospec.profile", "orthospec.spec"),  # profiles, written against the delivery convention
    ("orthospec.measures",),  # pure numbers
    (
        "orthospec.raster",
        "orthospec.inspection",
    ),  # reading rasters; the inspection grid (reads rasters, vectors)
    ("orthospec.engine",),  # providers, evaluator
    ("orthospec.qcr",),  # the QCR document
    (
        "orthospec.figures",
        "orthospec.reports",
        "orthospec.ledger",
        "orthospec.ingest",
        "orthospec.findings",
        "orthospec.metadata",
    ),
    ("orthospec.api", "orthospec.verify", "orthospec.schemas"),
    ("orthospec.cli",),
)

#: (importer, imported) -> who was asked to remove it; see the module docstring
PENDING: dict[tuple[str, str], str] = {}

#: cycles (sorted member tuples) asked for and not landed yet
PENDING_CYCLES: dict[tuple[str, ...], str] = {}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


@lru_cache(maxsize=1)
def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted((SRC / "orthospec").rglob("*.py"))}


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST, typing: bool) -> list[ast.Import | ast.ImportFrom]:
    out: list[ast.Import | ast.ImportFrom] = []
    stack = [tree]
    while stack:
        node = stack.pop()
        if not typing and isinstance(node, ast.If) and _is_type_checking(node):
            stack.extend(node.orelse)
            continue
        if isinstance(node, ast.Import | ast.ImportFrom):
            out.append(node)
        stack.extend(ast.iter_child_nodes(node))
    return out


def _known(name: str, mods: dict[str, Path]) -> str | None:
    while name and name not in mods:
        name = name.rpartition(".")[0]
    return name or None


@lru_cache(maxsize=2)
def graph(typing: bool = False) -> dict[str, dict[str, int]]:
    """module -> {imported orthospec module: first line}; ``typing``: with TYPE_CHECKING imports."""
    mods = _modules()
    out: dict[str, dict[str, int]] = {}
    for mod, path in mods.items():
        edges: dict[str, int] = {}
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"), str(path)), typing):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                if node.level:
                    base = package.split(".")
                    base = base[: len(base) - (node.level - 1)]
                    origin = ".".join([*base, *([node.module] if node.module else [])])
                else:
                    origin = node.module or ""
                # `from pkg import submodule` imports the submodule
                targets = [
                    f"{origin}.{a.name}" if f"{origin}.{a.name}" in mods else origin
                    for a in node.names
                ]
            for t in targets:
                if t.split(".")[0] != "orthospec":
                    continue
                k = _known(t, mods)
                if k is not None and k != mod:
                    edges.setdefault(k, node.lineno)
        out[mod] = edges
    return out


def layer_of(mod: str) -> int:
    best, best_len = -1, -1
    for i, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if (mod == p or mod.startswith(p + ".")) and len(p) > best_len:
                best, best_len = i, len(p)
    return best


def cycles(g: dict[str, dict[str, int]]) -> list[tuple[str, ...]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[tuple[str, ...]] = []
    counter = 0
    for root in sorted(g):
        if root in index:
            continue
        work = [(root, iter(sorted(g[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(g.get(w, {})))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(tuple(sorted(comp)))
    return sorted(out)


def _where(mod: str, target: str) -> str:
    path = _modules()[mod].relative_to(SRC.parent)
    return f"{path}:{graph(True)[mod][target]}: {mod} imports {target}"


def test_graph_sees_lazy_imports() -> None:
    """The walker is real: it finds a function-level import and a relative `from . import x`."""
    g = graph()
    assert len(g) > 80
    # cli/groups.py imports its command modules with importlib (by name), but cmd_check imports the
    # api inside its command function: that lazy edge must be seen
    assert "orthospec.api" in g["orthospec.cli.cmd_check"]
    assert "orthospec.errors" in g["orthospec.units"]


def test_every_module_has_a_layer() -> None:
    assert [m for m in graph() if layer_of(m) < 0] == []


def test_no_import_cycles() -> None:
    found = cycles(graph())
    problems = []
    for comp in found:
        if comp in PENDING_CYCLES:
            continue
        members = set(comp)
        lines = [_where(m, t) for m in comp for t in sorted(graph()[m]) if t in members]
        problems.append(" <-> ".join(comp) + "\n    " + "\n    ".join(lines))
    stale = [c for c in PENDING_CYCLES if c not in found]
    assert not problems, "import cycles:\n" + "\n".join(problems)
    assert not stale, f"PENDING_CYCLES entries that no longer occur (remove them): {stale}"


def test_layers_only_look_down() -> None:
    g = graph(typing=True)
    bad = []
    seen_pending = set()
    for mod, edges in sorted(g.items()):
        for target in sorted(edges):
            if layer_of(target) > layer_of(mod):
                if (mod, target) in PENDING:
                    seen_pending.add((mod, target))
                    continue
                bad.append(f"{_where(mod, target)} (layer {layer_of(mod)} -> {layer_of(target)})")
    stale = sorted(set(PENDING) - seen_pending)
    assert not bad, "imports reaching up a layer:\n" + "\n".join(bad)
    assert not stale, f"PENDING entries that no longer occur (remove them): {stale}"


@pytest.mark.parametrize(
    ("mod", "layer"),
    [
        ("orthospec.errors", 0),
        ("orthospec.delivery.reader", 1),
        ("orthospec.profile.loader", 2),
        ("orthospec.engine.providers.checkpoints", 5),
        ("orthospec.cli.cmd_check", 9),
    ],
)
def test_layer_of(mod: str, layer: int) -> None:
    assert layer_of(mod) == layer


def test_cycle_finder_finds_a_planted_cycle() -> None:
    g = {"a": {"b": 1}, "b": {"c": 1}, "c": {"a": 1}, "d": {"a": 1}}
    assert cycles(g) == [("a", "b", "c")]


def test_providers_import_only_the_registry_of_the_engine() -> None:
    g = graph(typing=True)
    bad = [
        _where(m, t)
        for m in sorted(g)
        if m.startswith("orthospec.engine.providers.")
        for t in sorted(g[m])
        if t.startswith("orthospec.engine.")
        and t != "orthospec.engine.registry"
        and not t.startswith("orthospec.engine.providers")
    ]
    assert not bad, "providers reaching into the engine beyond registry.py:\n" + "\n".join(bad)
