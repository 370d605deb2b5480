"""A profile with ``extends`` applied (:class:`ResolvedProfile`), the rules it removed, its
canonical JSON, and where each rule and parameter was written along the chain (for messages)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..yamlio import Located, YamlError
from .changes import Weakening
from .files import _load_doc
from .models import Parameter, Rule


@dataclass(frozen=True)
class ResolvedProfile:
    """A profile with ``extends`` applied: what the evaluator runs and every QCR cites."""

    id: str
    version: str
    title: str
    description: str | None
    source: Any
    parameters: dict[str, Parameter]
    tables: dict[str, Any]
    classes: dict[str, Any]
    rules: tuple[Rule, ...]
    tests: tuple[Any, ...]
    waivers: tuple[Any, ...]
    path: Path
    chain: tuple[tuple[str, str, str], ...]  # (id, version, file) from this profile to its root
    canonical: dict[str, Any] = field(repr=False)
    sha256: str = ""
    allow_no_mandatory: bool = False
    #: inherited rules taken out along the chain: (id, justification or None, profile id that removed it)
    removed: tuple[Removal, ...] = ()
    #: rule id -> keys changed by `override: true` along the chain
    overridden: dict[str, tuple[str, ...]] = field(default_factory=dict)
    #: mandatory rules of a base that the chain removed or changed so they check less, justified
    weakened: tuple[Weakening, ...] = ()
    #: where each rule / parameter was written (cold loads only; empty when served from the cache)
    sites: _Sites | None = field(default=None, repr=False, compare=False)
    _index: dict[str, int] = field(default_factory=dict, repr=False, compare=False)

    def rule(self, rule_id: str) -> Rule:
        if not self._index:
            self._index.update({r.id: i for i, r in enumerate(self.rules)})
        try:
            return self.rules[self._index[rule_id]]
        except KeyError:
            raise KeyError(rule_id) from None

    def canonical_json(self) -> str:
        return canonical_dumps(self.canonical)


@dataclass(frozen=True)
class Removal:
    """A rule an extending profile removed, with its justification (None when it gave none)."""

    id: str
    justification: str | None
    profile: str


def canonical_dumps(obj: Any) -> str:
    return json.dumps(
        obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False
    )


@dataclass
class _Sites:
    """Where things were written, for file:line:col of semantic problems (no file is re-read)."""

    rules: dict[str, list[tuple[Located, int]]] = field(default_factory=dict)  # root first
    params: dict[str, list[Located]] = field(default_factory=dict)  # root first
    top: Located | None = None
    inherited_params: set[str] = field(default_factory=set)
    own_params: set[str] = field(default_factory=set)

    def rule_where(self, rule_id: str, key: tuple[Any, ...]) -> tuple[str, int | None, int | None]:
        sites = self.rules.get(rule_id) or []
        for doc, i in reversed(sites):
            rd = _rules_of(doc)[i] if i < len(_rules_of(doc)) else {}
            if isinstance(rd, dict) and (not key or key[0] in rd):
                return (doc.file, *doc.where(("rules", i, *key)))
        if sites:
            doc, i = sites[0]
            return (doc.file, *doc.where(("rules", i)))
        return (self.top.file if self.top else "?", None, None)

    def param_where(self, name: str, key: str | None = None) -> tuple[str, int | None, int | None]:
        docs = self.params.get(name) or []
        for doc in reversed(docs):
            pd = (
                (doc.data.get("parameters") or {}).get(name) if isinstance(doc.data, dict) else None
            )
            if key is None or (isinstance(pd, dict) and key in pd):
                return (doc.file, *doc.where(("parameters", name, *((key,) if key else ()))))
        return (self.top.file if self.top else "?", None, None)


def param_location(p: ResolvedProfile, name: str, key: str | None = None) -> str:
    """``file:line`` where the chain last wrote parameter ``name`` (its ``key``), for messages;
    from the sites of a cold load, else by reading the chain's files again (error paths only)."""
    if p.sites is not None:
        file, line, _col = p.sites.param_where(name, key)
        return f"{file}:{line}" if line else file
    for _pid, _ver, f in p.chain:
        try:
            doc, _ = _load_doc(Path(f))
        except (OSError, YamlError):
            continue
        pd = (doc.data.get("parameters") or {}).get(name) if isinstance(doc.data, dict) else None
        if isinstance(pd, dict) and (key is None or key in pd):
            line, _col = doc.where(("parameters", name, *((key,) if key else ())))
            return f"{f}:{line}" if line else f
    return str(p.path)


def _rules_of(doc: Located) -> list[Any]:
    d = doc.data if isinstance(doc.data, dict) else {}
    r = d.get("rules")
    return r if isinstance(r, list) else []
