"""Load, validate and resolve spec profiles (``extends``, overrides, removals, checksum).

Validation reports *every* problem with ``file:line:column``: the pydantic models (one message per
location, with a did-you-mean for unknown keys), then semantic checks (unique ids, threshold
numbers, units and their dimensions, expressions, manifest paths the delivery schema defines, known
measures and their scope, parameters nobody reads, who may change a standard value).

Cost stays linear in the number of rules, each file is parsed once per process, and a resolved,
validated profile is cached on disk keyed by the SHA-256 of every file in its ``extends`` chain
(see :mod:`orthospec.spec.cache`).
"""

from __future__ import annotations

import difflib
import hashlib
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from ..errors import ExpressionError, SpecError, UnitError
from ..resources import shown, specs_dir
from ..yamlio import Located, YamlError, load_text, read_regular
from .changes import Weakening, weakened_fields, weakening_changes
from .models import Parameter, Profile, Rule, RuleOverride

if TYPE_CHECKING:
    from . import expr

MAX_EXTENDS_DEPTH = 8
#: how much of a candidate file is read to learn its id and version (never the whole file)
HEADER_BYTES = 4096
_ORDER_OPS = ("<", "<=", ">", ">=", "between")


@dataclass(frozen=True)
class Problem:
    file: str
    line: int | None
    column: int | None
    message: str
    rule: str | None = None

    def __str__(self) -> str:
        where = self.file
        if self.line is not None:
            where += f":{self.line}" + (f":{self.column}" if self.column is not None else "")
        who = f" (rule {self.rule})" if self.rule else ""
        return f"{where}: {self.message}{who}"


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
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


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
            pd = (doc.data.get("parameters") or {}).get(name) if isinstance(doc.data, dict) else None
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


# --- reading files: one parse per file per process -------------------------------------------

_DOCS: dict[tuple[str, str], Located] = {}


def _file_bytes(path: Path) -> bytes:
    return read_regular(path)


def file_sha256(path: Path) -> str:
    return hashlib.sha256(_file_bytes(path)).hexdigest()


def _load_doc(path: Path) -> tuple[Located, str]:
    """The parsed document and the SHA-256 of its bytes, parsed at most once per content."""
    raw = _file_bytes(path)
    sha = hashlib.sha256(raw).hexdigest()
    key = (str(path), sha)
    doc = _DOCS.get(key)
    if doc is None:
        try:
            text = raw.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")
        except UnicodeDecodeError as exc:
            raise YamlError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
        doc = load_text(text, shown(path))  # specs/NAME, not the install path
        if len(_DOCS) > 64:
            _DOCS.clear()
        _DOCS[key] = doc
    _LAST_SHA[str(path)] = sha
    return doc, sha


_YAML_POS = re.compile(r"^(?P<file>.*?):(?P<line>\d+):(?P<col>\d+): (?P<msg>.*)$", re.S)


def _yaml_problem(path: Path, exc: YamlError) -> Problem:
    """A YAML error as a Problem that keeps its line and column."""
    line = getattr(exc, "line", None)
    col = getattr(exc, "column", None)
    text = str(exc)
    if line is not None:
        msg = str(getattr(exc, "problem", None) or text)
        m = _YAML_POS.match(msg)  # the reader's message may already start with file:line:col
        return Problem(str(path), line, col, m["msg"] if m else msg)
    m = _YAML_POS.match(text)
    if m:
        return Problem(m["file"], int(m["line"]), int(m["col"]), m["msg"])
    return Problem(str(path), None, None, text.split(": ", 1)[-1] if text.startswith(str(path)) else text)


# --- model validation ---------------------------------------------------------------------

def _short(msg: str) -> str:
    return msg if len(msg) < 300 else msg[:297] + "..."


def _rule_at(doc: Located, path: tuple[Any, ...]) -> str | None:
    if len(path) >= 2 and path[0] == "rules" and isinstance(path[1], int):
        try:
            rid = doc.data["rules"][path[1]].get("id")
            return str(rid) if rid else None
        except (KeyError, IndexError, AttributeError, TypeError):
            return None
    return None


def _unwrap(t: Any, tag: Any = None) -> Any:
    """The model class (or container type) behind Optional/Annotated/Union annotations."""
    for _ in range(8):
        origin = get_origin(t)
        if origin is None:
            return t
        args = get_args(t)
        if "Annotated" in str(origin):
            t = args[0]
            continue
        if origin is Union or str(origin) == "<class 'types.UnionType'>":
            models = [a for a in (_unwrap(x) for x in args) if isinstance(a, type) and issubclass(a, BaseModel)]
            if tag == "override" and RuleOverride in models:
                return RuleOverride
            if tag == "rule" and Rule in models:
                return Rule
            if len(models) == 1:
                return models[0]
            conts = [a for a in args if get_origin(a) in (list, dict)]
            return conts[0] if conts else t
        return t
    return t


def _fields_at(loc: tuple[Any, ...]) -> list[str]:
    """Field names of the model an error location points into (for did-you-mean)."""
    t: Any = Profile
    parts = list(loc)
    i = 0
    while i < len(parts):
        part = parts[i]
        t = _unwrap(t)
        if isinstance(t, type) and issubclass(t, BaseModel):
            f = t.model_fields.get(str(part))
            if f is None:
                return []
            t = f.annotation
            if get_origin(_unwrap(t)) is list and i + 2 < len(parts) and parts[i + 2] in ("rule", "override"):
                t = _unwrap(get_args(_unwrap(t))[0], tag=parts[i + 2])
                i += 3
                continue
        elif get_origin(t) is list:
            t = get_args(t)[0]
        elif get_origin(t) is dict:
            t = get_args(t)[1]
        else:
            return []
        i += 1
    t = _unwrap(t)
    return list(t.model_fields) if isinstance(t, type) and issubclass(t, BaseModel) else []


def _pydantic_problems(doc: Located, exc: ValidationError) -> list[Problem]:
    out = []
    errors = exc.errors()
    # a misspelt key also makes the real key "missing": say it once, at the misspelling
    suggested: set[tuple[Any, ...]] = set()
    for e in errors:
        if e["type"] == "extra_forbidden":
            raw_loc = tuple(e["loc"])
            near = difflib.get_close_matches(str(raw_loc[-1]), _fields_at(raw_loc[:-1]), n=1, cutoff=0.6)
            if near:
                suggested.add((*raw_loc[:-1], near[0]))
    for e in errors:
        if e["type"] == "missing" and tuple(e["loc"]) in suggested:
            continue
        raw_loc = tuple(e["loc"])
        path = tuple(p for p in raw_loc if not (isinstance(p, str) and p in ("rule", "override")))
        # a union of scalar types reports one error per member type: name the location once
        path = tuple(p for p in path if p not in ("float", "int", "str", "bool", "list[...]", "dict[...]"))
        line, col = doc.where(path)
        loc = "/".join(str(p) for p in path) or "(document)"
        if e["type"] == "extra_forbidden":
            key = str(path[-1])
            allowed = _fields_at(raw_loc[:-1])
            near = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
            hint = f"; did you mean {near[0]!r}?" if near else (f"; allowed: {', '.join(allowed)}" if allowed else "")
            if key.isdigit():  # `{value: 1,0}`: in a {flow mapping} the comma splits the number
                hint = _split_number_hint(doc, path, key)
            msg = f"{loc}: unknown key {key!r}{hint}"
        elif e["type"] == "missing" and path == ("extends", "version"):
            msg = f"{loc}: extends pins the version it builds on{_versions_hint(doc)}"
        else:
            got = e.get("input")
            shown = "" if isinstance(got, dict | list) or got is None else f" (got {_short(repr(got))})"
            msg = f"{loc}: {e['msg']}{shown}"
        out.append(Problem(doc.file, line, col, msg, _rule_at(doc, path)))
    return out


def _versions_hint(doc: Located) -> str:
    """`: write extends: {id: jrc-v3, version: 3.0.0}` from the versions the id exists in."""
    ext = doc.data.get("extends") if isinstance(doc.data, dict) else None
    pid = ext.get("id") if isinstance(ext, dict) else None
    versions = sorted({v for i, v, _, _ in available() if i == pid}, key=_semver_key) if pid else []
    if not versions:
        return " (write `extends: {id: ..., version: ...}`)"
    return (f": write `extends: {{id: {pid}, version: {versions[-1]}}}` (a later {pid} is then never picked up "
            "silently)")


def _split_number_hint(doc: Located, path: tuple[Any, ...], key: str) -> str:
    """`{value: 0,5}` reads as value 0 and a key '5': name the number the author meant."""
    parent: Any = doc.data
    for part in path[:-1]:
        try:
            parent = parent[part]
        except (KeyError, IndexError, TypeError):
            parent = None
            break
    if isinstance(parent, dict) and key in parent:
        keys = list(parent)
        i = keys.index(key)
        if i > 0 and isinstance(parent[keys[i - 1]], int) and not isinstance(parent[keys[i - 1]], bool):
            prev, whole = keys[i - 1], parent[keys[i - 1]]
            return (f": a decimal comma inside {{...}} splits the number (`{prev}: {whole},{key}` reads as "
                    f"{prev} {whole} and a key '{key}'); write {whole}.{key}")
    return ": a decimal comma inside {...} splits a number (`1,0` reads as 1 and a key '0'); write 1.0"


def parse_profile(doc: Located) -> tuple[Profile | None, list[Problem]]:
    """Model validation of one file (no extends resolution): one problem per location."""
    if not isinstance(doc.data, dict):
        return None, [Problem(doc.file, 1, 1, "a profile must be a YAML mapping")]
    if "orthospec_profile" not in doc.data:
        return None, [Problem(doc.file, 1, 1, "not an orthospec spec profile (it has no "
                              "'orthospec_profile: 1' key)")]
    try:
        prof = Profile.model_validate(doc.data)
    except ValidationError as exc:
        return None, _dedupe(_pydantic_problems(doc, exc))
    return prof, []


def _dedupe(problems: list[Problem]) -> list[Problem]:
    seen: set[tuple[Any, ...]] = set()
    out = []
    for p in problems:
        key = (p.file, p.line, p.column)
        if key in seen:
            continue
        seen.add(key)
        out.append(p)
    return out


# --- finding profiles by id: headers only ------------------------------------------------------

_HEAD_KEY = re.compile(r"^(id|version|title|orthospec_profile)[ \t]*:[ \t]*(.*?)[ \t]*$", re.M)


def _scalar_text(v: str) -> str:
    v = re.sub(r"\s+#.*$", "", v).strip()
    if len(v) >= 2 and v[0] == v[-1] and v[0] in "'\"":
        v = v[1:-1]
    return v


def read_header(path: Path) -> tuple[str, str, str] | None:
    """(id, version, title) from the first HEADER_BYTES of a file, without parsing YAML.

    Only top-level ``key: value`` lines count. Finding a profile by id never parses a file that
    is not the one asked for (an unrelated alias bomb in the same folder cannot hang it).
    """
    try:
        head = read_regular(path, HEADER_BYTES).decode("utf-8", errors="replace")
    except (OSError, YamlError):
        return None
    found: dict[str, str] = {}
    for m in _HEAD_KEY.finditer(head):
        found.setdefault(m.group(1), _scalar_text(m.group(2)))
    if "orthospec_profile" not in found or "id" not in found:
        return None
    return found["id"], found.get("version", ""), found.get("title", "")


def available(extra: list[Path] | None = None) -> list[tuple[str, str, str, Path]]:
    """Shipped (and extra) profiles as (id, version, title, path), from their headers."""
    out = []
    for d in [specs_dir(), *(extra or [])]:
        if not d.is_dir():
            continue
        for p in sorted(d.glob("*.yaml")):
            h = read_header(p) if p.is_file() else None
            if h:
                out.append((*h, p))
    return sorted(out, key=lambda t: (t[0], t[1]))


def find_profile(ref: str | Path, *, near: Path | None = None, version: str | None = None) -> Path:
    """A path to a profile given a file path (as the user typed it) or an id."""
    p = Path(ref)
    if p.suffix in (".yaml", ".yml") or p.exists():
        if p.exists() and not p.is_file():
            raise SpecError(f"profile file {str(ref)!r} is not a regular file")
        if not p.is_file():
            raise SpecError(f"profile file {str(ref)!r} not found")
        return p
    return find_by_id(str(ref), version=version, near=near)


def plugin_profiles() -> list[tuple[str, str, str, Path]]:
    """Profiles installed plugins ship (``orthospec.profiles`` entry points), as ``available``."""
    from .. import plugins

    dirs = list(plugins.profile_dirs())
    if not dirs:
        return []
    inside = {d.resolve() for d in dirs}
    return [t for t in available(dirs) if t[3].parent.resolve() in inside]


def find_by_id(pid: str, *, version: str | None = None, near: Path | None = None) -> Path:
    """A profile by id (and pinned version): shipped profiles first, then ``near``'s folder, then
    the profiles of installed plugins (orthospec/plugins.py).

    An id is never a path: ``extends: {id: evil.yaml}`` does not open a file of that name. The
    shipped profiles win, so a file in the tender's folder (or a plugin) cannot stand in for a
    shipped standard.
    """
    def match(rows: list[tuple[str, str, str, Path]]) -> list[tuple[str, str, str, Path]]:
        return [t for t in rows if t[0] == pid and (version is None or t[1] == version)]

    shipped = available()
    hits = match(shipped)
    if not hits and near is not None and near.resolve() != specs_dir().resolve():
        local = [t for t in available([near]) if t[3].parent.resolve() == near.resolve()]
        hits = match(local)
        if version is not None and len(hits) > 1:
            files = ", ".join(str(t[3]) for t in hits)
            raise SpecError(f"profile {pid!r} version {version} is defined by several files: {files}")
    if not hits:  # plugins are looked for only when needed: importlib.metadata costs ~0.1 s
        hits = match(plugin_profiles())
        if version is not None and len(hits) > 1:
            files = ", ".join(str(t[3]) for t in hits)
            raise SpecError(f"profile {pid!r} version {version} is shipped by several plugins: {files}")
    if hits:
        return sorted(hits, key=lambda t: _semver_key(t[1]))[-1][3]
    raise SpecError(_unknown_profile(pid, version, near))


def _unknown_profile(pid: str, version: str | None, near: Path | None) -> str:
    """One short message for an id (and version) nobody has: the versions that exist, else the
    nearest id; the shipped and plugin profiles by id, the local folder's files only counted (a
    tender's folder of variants once made this message list the same id 23 times)."""
    shared = sorted({(i, v) for i, v, _, _ in (*available(), *plugin_profiles())})
    local = [] if near is None else sorted(
        {(i, v) for i, v, _, f in available([near]) if f.parent.resolve() == near.resolve()} - set(shared))
    pin = f" version {version}" if version else ""
    versions = sorted({v for i, v in (*shared, *local) if i == pid}, key=_semver_key)
    if versions:
        hint = f"; {pid} exists in version {', '.join(versions)}: pin one of them"
    else:
        close = difflib.get_close_matches(pid, sorted({i for i, _ in (*shared, *local)}), n=1, cutoff=0.6)
        hint = f"; did you mean {close[0]!r}?" if close else ""
    known = ", ".join(f"{i} {v}" for i, v in shared) or "none"
    if local:
        ids = sorted({i for i, _ in local})
        known += (f"; and {len(local)} in {near}: " + ", ".join(ids[:5]) + (" ..." if len(ids) > 5 else ""))
    return f"unknown profile {pid!r}{pin}{hint}; available: {known}"


def _semver_key(v: str) -> tuple[Any, ...]:
    m = re.match(r"(\d+)\.(\d+)\.(\d+)(.*)", v)
    if not m:
        return (0, 0, 0, v)
    return (int(m[1]), int(m[2]), int(m[3]), m[4] == "", m[4])


# --- loading --------------------------------------------------------------------------------

_RESOLVED: dict[str, tuple[ResolvedProfile, list[tuple[str, str]]]] = {}
_LAST_SHA: dict[str, str] = {}  # file -> SHA-256 of the content last parsed


def load_profile(ref: str | Path, *, check_measures: bool = True) -> ResolvedProfile:
    """Load a profile by id or path, resolve ``extends``, validate, and checksum it."""
    path = find_profile(ref)
    resolved, problems = _load(path, check_measures=check_measures)
    if problems:
        raise SpecError(_format(problems))
    assert resolved is not None
    return resolved


def validate_file(path: str | Path, *, check_measures: bool = True) -> list[Problem]:
    """Every problem of a profile file (and what it extends), without raising.

    Besides what loading checks, the profile's own ``tests:`` (delivery folders, checker files,
    rules and verdicts named): a tender author learns of a wrong path here, with its line, not at
    ``verify``. Loading for a check does not look at them (the checker may not have the author's
    test deliveries)."""
    try:
        p = find_profile(path)
    except SpecError as exc:
        return [Problem(str(path), None, None, str(exc))]
    resolved, problems = _load(p, check_measures=check_measures)
    if problems or resolved is None or not resolved.tests:
        return problems
    try:
        doc, _ = _load_doc(p)
    except YamlError as exc:
        return [_yaml_problem(p, exc)]
    shipped = p.resolve().parent == specs_dir().resolve()  # their tests point into the source checkout
    return _test_problems(resolved, _Sites(top=doc), paths=not shipped)


def _load(path: Path, *, check_measures: bool) -> tuple[ResolvedProfile | None, list[Problem]]:
    """Memo (this process) > disk cache (hash-checked) > parse, resolve and validate."""
    from . import cache

    try:
        entry_sha = file_sha256(path)
    except YamlError as exc:
        return None, [_yaml_problem(path, exc)]
    k = cache.key(path, entry_sha)
    for mk in (k, k + ":nomeasures") if not check_measures else (k,):
        hit = _RESOLVED.get(mk)
        if hit is not None and cache.chain_current(hit[1]):
            return hit[0], []
    got = cache.get(k)
    if got is not None:
        try:
            rebuilt = (_rebuild(got[0]), got[1])
        except (KeyError, TypeError, ValueError):  # a damaged entry is a miss, never an error
            rebuilt = None
        if rebuilt is not None:
            _RESOLVED[k] = rebuilt
            return rebuilt[0], []
    problems: list[Problem] = []
    resolved = _resolve(path, problems, depth=0, seen=())
    if resolved is not None and not problems:
        problems.extend(semantic_problems(resolved, check_measures=check_measures))
    if problems or resolved is None:
        return None, problems
    shas = [(f, _LAST_SHA.get(f, "")) for _, _, f in resolved.chain]
    if shas[0][1] != entry_sha:  # the file changed while we read it: do not cache
        return resolved, []
    if len(_RESOLVED) > 32:
        _RESOLVED.clear()
    if check_measures:
        _RESOLVED[k] = (resolved, shas)
        from .catalog import extended_by_plugins

        if not extended_by_plugins():  # validity then depends on installed plugins: not cached on disk
            cache.put(k, _dump(resolved), shas)
    else:
        _RESOLVED[k + ":nomeasures"] = (resolved, shas)
    return resolved, []


def _dump(p: ResolvedProfile) -> dict[str, Any]:
    """The JSON payload spec/cache.py stores for a resolved profile (_rebuild reads it back)."""
    return {
        "canonical": p.canonical,
        "sha256": p.sha256,
        "description": p.description,
        "tests": [t.model_dump(mode="json") for t in p.tests],
        "path": str(p.path),
        "chain": [list(c) for c in p.chain],
        "allow_no_mandatory": p.allow_no_mandatory,
        "overridden": {k: list(v) for k, v in p.overridden.items()},
    }


def _rebuild(d: dict[str, Any]) -> ResolvedProfile:
    """The profile from a cache payload (raises KeyError/TypeError/ValueError when damaged)."""
    from .models import ClassSet, LookupTable, ProfileTest, ProfileWaiver, Source

    c = d["canonical"]
    sha = hashlib.sha256(canonical_dumps(c).encode("utf-8")).hexdigest()
    if sha != d["sha256"]:
        raise ValueError("cache entry does not hash to its recorded sha256")
    return ResolvedProfile(
        id=c["id"], version=c["version"], title=c["title"], description=d.get("description"),
        source=Source.model_validate(c["source"]),
        parameters={k: Parameter.model_validate(v) for k, v in c["parameters"].items()},
        tables={k: LookupTable.model_validate(v) for k, v in c["tables"].items()},
        classes={k: ClassSet.model_validate(v) for k, v in c["classes"].items()},
        rules=tuple(Rule.model_validate(r) for r in c["rules"]),
        tests=tuple(ProfileTest.model_validate(t) for t in d.get("tests", [])),
        waivers=tuple(ProfileWaiver.model_validate(w) for w in c["waivers"]),
        path=Path(d["path"]), chain=tuple((a, b, f) for a, b, f in d["chain"]),
        canonical=c, sha256=sha, allow_no_mandatory=bool(d.get("allow_no_mandatory")),
        removed=tuple(Removal(x["id"], x["justification"], x["profile"]) for x in c.get("removed_rules", [])),
        overridden={k: tuple(v) for k, v in d.get("overridden", {}).items()},
        weakened=tuple(Weakening.from_dict(w) for w in c.get("weakened_rules", [])),
    )


def _format(problems: list[Problem]) -> str:
    head = f"{len(problems)} problem(s) in profile:" if len(problems) > 1 else "invalid profile:"
    lines = [str(p) for p in problems[:50]]
    if len(problems) > 50:
        lines.append(f"... and {len(problems) - 50} more")
    return head + "\n  " + "\n  ".join(lines)


def _resolve(path: Path, problems: list[Problem], *, depth: int,
             seen: tuple[str, ...]) -> ResolvedProfile | None:
    try:
        doc, _ = _load_doc(path)
    except YamlError as exc:
        problems.append(_yaml_problem(path, exc))
        return None
    prof, probs = parse_profile(doc)
    problems.extend(probs)
    if prof is None or probs:
        return None
    key = f"{prof.id}@{prof.version}"
    if key in seen:
        problems.append(Problem(doc.file, *doc.where(("extends",)), f"extends cycle: {' -> '.join((*seen, key))}"))
        return None
    _check_unique_ids(prof, doc, problems)
    base: ResolvedProfile | None = None
    if prof.extends is not None:
        if depth >= MAX_EXTENDS_DEPTH:
            problems.append(Problem(doc.file, *doc.where(("extends",)), "extends chain too deep"))
            return None
        try:
            parent_path = find_by_id(prof.extends.id, near=path.parent, version=prof.extends.version)
        except SpecError as exc:
            problems.append(Problem(doc.file, *doc.where(("extends",)), str(exc)))
            return None
        base = _resolve(parent_path, problems, depth=depth + 1, seen=(*seen, key))
        if base is None:
            return None
        if (base.id, base.version) != (prof.extends.id, prof.extends.version):
            problems.append(Problem(doc.file, *doc.where(("extends",)),
                                    f"extends {prof.extends.id} {prof.extends.version}, but {parent_path} "
                                    f"is {base.id} {base.version}"))
            return None
    resolved = _merge(prof, base, path, doc, problems)
    if resolved is not None:
        claim = _claims_reserved_id(resolved, path)
        if claim:
            problems.append(Problem(doc.file, *doc.where(("id",)), claim))
            return None
    return resolved


def _claims_reserved_id(p: ResolvedProfile, path: Path) -> str | None:
    """Why ``p`` may not carry its id: the id of a shipped profile (or of one an installed plugin
    ships) claimed by another file with other content, or None.

    A report names the profile by id: "jrc-v3" must mean the published standard, never a local file
    that switched a rule off under its name (issue 25). A copy whose resolved content is the
    shipped profile's (same SHA-256) is the same profile and passes.
    """
    here = path.resolve()
    owners = [t for t in available() if t[0] == p.id]
    kind = "shipped"
    if not owners:
        owners = [t for t in plugin_profiles() if t[0] == p.id]
        kind = "installed by a plugin"
    if not owners or any(t[3].resolve() == here for t in owners):
        return None
    for _pid, ver, _title, owner in owners:
        if ver == p.version:
            try:
                if load_profile(owner, check_measures=False).sha256 == p.sha256:
                    return None
            except SpecError:
                pass
    files = ", ".join(sorted({str(t[3]) for t in owners}))
    return (f"id {p.id!r} is reserved: it names the profile {kind} in {files}, and this file is not that "
            f"profile; give this profile its own id (e.g. '{p.id}-itt') and `extends: {{id: {owners[0][0]}, "
            f"version: {owners[-1][1]}}}` to build on it")


def _check_unique_ids(prof: Profile, doc: Located, problems: list[Problem]) -> None:
    seen: dict[str, int] = {}
    for i, r in enumerate(prof.rules):
        if r.id in seen:
            line, col = doc.where(("rules", i, "id"))
            problems.append(Problem(doc.file, line, col, f"duplicate rule id {r.id!r} "
                                    f"(first at rules/{seen[r.id]})", r.id))
        else:
            seen[r.id] = i


def _effective(p: Parameter) -> Any:
    return p.value if p.value is not None else p.default


def _same_value(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return float(a) == float(b)
    return a == b


def _unjustified(rule_id: str, changes: list[str], base: ResolvedProfile | None, how: str) -> str:
    """One message for a mandatory rule of the base weakened without a justification."""
    where = f"{base.id} {base.version}" if base is not None else "the base profile"
    listed = "`spec diff`, the annex and every report checked under this profile list the change"
    if how == "remove":
        return (f"remove_rules: {rule_id} is a mandatory rule of {where}; removing it needs a justification: "
                f"write `{{id: {rule_id}, justification: \"ITT §...: why it does not apply\"}}` ({listed})")
    what = "; ".join(changes)
    if how == "restate":
        return (f"rule {rule_id} is mandatory in {where}, and this profile writes it again so that it checks less "
                f"({what}): write only the keys that change under `override: true`, with `justification: "
                f"\"ITT §...: why\"` ({listed})")
    return (f"rule {rule_id} is mandatory in {where}, and this override makes it check less ({what}) without a "
            f"justification: add `justification: \"ITT §...: why\"` to the override ({listed})")


def _unit_change(name: str, old: Parameter, new: Parameter, base: ResolvedProfile | None) -> str:
    """One message for an extending profile that gives an inherited parameter another unit.

    The parameter keeps the unit of the profile that defines it (every rule reading it, the annex
    and the QCR print that unit); without this the mistake surfaced as one dimension error per rule
    reading the parameter, some of them located in the standard's own file."""
    from ..units import profile_unit_problem

    where = f"{base.id} {base.version}" if base is not None else "the profile that defines it"
    spelled = profile_unit_problem(new.unit)
    if spelled and f"write {old.unit!r}" in spelled:
        return f"parameter {name}: {spelled}"
    head = f"parameter {name}: unit {new.unit!r}, but {name} is in {old.unit!r} in {where}"
    value = new.value if new.value is not None else None
    if isinstance(value, int | float) and not isinstance(value, bool) and old.unit not in (None, "text", "bool",
                                                                                             "date"):
        try:
            from ..units import convert

            got = float(convert([float(value)], new.unit, old.unit)[0])
            return (f"{head}: a tender gives the value in the parameter's unit: write `value: {got:g}` "
                    f"({value:g} {new.unit}) and leave out `unit`")
        except (UnitError, ValueError, TypeError):
            pass
    return (f"{head} (another kind of quantity): a tender gives the value in {old.unit!r} and leaves out "
            f"`unit`")


def _merge(prof: Profile, base: ResolvedProfile | None, path: Path, doc: Located,
           problems: list[Problem]) -> ResolvedProfile | None:
    sites = _Sites(top=doc)
    if base is not None and base.sites is not None:
        sites.rules = {k: list(v) for k, v in base.sites.rules.items()}
        sites.params = {k: list(v) for k, v in base.sites.params.items()}
    params = dict(base.parameters) if base else {}
    sites.inherited_params = set(params)
    for name, p in prof.parameters.items():
        sites.params.setdefault(name, []).append(doc)
        if name not in params:
            if p.unit is None:
                line, col = doc.where(("parameters", name))
                problems.append(Problem(doc.file, line, col, f"parameter {name}: a new parameter needs a unit"
                                        + _did_you_mean(name, sites.inherited_params, "inherited")))
                continue
            params[name] = p.model_copy(update={"set_by": p.authority()})
            sites.own_params.add(name)
            continue
        old = params[name]
        given = p.model_dump(exclude_unset=True)
        if "set_by" in given and given["set_by"] != old.authority():
            line, col = doc.where(("parameters", name, "set_by"))
            problems.append(Problem(doc.file, line, col, f"parameter {name}: set_by is {old.authority()!r} where "
                                    "the parameter is defined; an extending profile cannot change it"))
            continue
        if "unit" in given and old.unit is not None and given["unit"] != old.unit:
            line, col = doc.where(("parameters", name, "unit"))
            problems.append(Problem(doc.file, line, col, _unit_change(name, old, p, base)))
            continue
        if "default" in given and not _same_value(given["default"], old.default):
            line, col = doc.where(("parameters", name, "default"))
            problems.append(Problem(doc.file, line, col, f"parameter {name}: an extending profile sets `value:`, "
                                    "not `default:` (the default is the value of the profile that defines it)"))
            continue
        merged = old.model_dump()
        merged.update(given)
        merged["set_by"] = old.authority()
        if "justification" not in given:
            merged["justification"] = None
        new = Parameter.model_validate(merged)
        if (old.authority() == "standard" and base is not None
                and not _same_value(_effective(new), _effective(old)) and not p.justification):
            key = "value" if "value" in given else ("default" if "default" in given else None)
            line, col = doc.where(("parameters", name, *((key,) if key else ())))
            problems.append(Problem(
                doc.file, line, col,
                f"parameter {name}: {_effective(old)!r} is the standard's value ({base.id} {base.version}); "
                f"a tender profile that changes it to {_effective(new)!r} must say why: add "
                f"`justification: \"ITT §...: ...\"` to the parameter (the report annex prints it)"))
        params[name] = new
    tables = {**(base.tables if base else {}), **prof.tables}
    classes = {**(base.classes if base else {}), **prof.classes}
    rules: dict[str, Rule] = dict((r.id, r) for r in base.rules) if base else {}
    removed = list(base.removed) if base else []
    weakened = list(base.weakened) if base else []
    overridden = {k: tuple(v) for k, v in base.overridden.items()} if base else {}
    for i, item in enumerate(prof.remove_rules):
        rid = item if isinstance(item, str) else item.id
        if rid not in rules:
            line, col = doc.where(("remove_rules", i))
            problems.append(Problem(doc.file, line, col, f"remove_rules: no inherited rule {rid!r}"
                                    + _did_you_mean(rid, rules, "inherited")))
            continue
        justification = None if isinstance(item, str) else item.justification
        if rules[rid].level == "mandatory":
            if justification is None:
                line, col = doc.where(("remove_rules", i))
                problems.append(Problem(doc.file, line, col, _unjustified(rid, ["removed"], base, "remove")))
                continue
            weakened.append(Weakening(rid, ("removed",), justification, prof.id, rules[rid].title))
        del rules[rid]
        sites.rules.pop(rid, None)
        overridden.pop(rid, None)
        removed.append(Removal(rid, justification, prof.id))
    for i, r in enumerate(prof.rules):
        before = rules.get(r.id)
        if isinstance(r, RuleOverride):
            if before is None:
                line, col = doc.where(("rules", i))
                problems.append(Problem(doc.file, line, col, f"override of unknown rule {r.id!r}"
                                        + _did_you_mean(r.id, rules, "inherited"), r.id))
                continue
            merged_r = before.model_dump()
            changed = {k: v for k, v in r.model_dump(exclude_unset=True).items()
                       if k not in ("override", "id", "justification")}
            merged_r.update(changed)
            try:
                after = Rule.model_validate(merged_r)
            except ValidationError as exc:
                line, col = doc.where(("rules", i))
                problems.append(Problem(doc.file, line, col, f"override invalid: {exc.errors()[0]['msg']}", r.id))
                continue
            weak = weakening_changes(before, after)
            if weak and not r.justification:
                key = weakened_fields(before, after)[0]
                line, col = doc.where(("rules", i, key))
                problems.append(Problem(doc.file, line, col, _unjustified(r.id, weak, base, "override"), r.id))
                continue
            if weak:
                weakened.append(Weakening(r.id, tuple(weak), r.justification, prof.id, after.title))
            overridden[r.id] = tuple(sorted({*overridden.get(r.id, ()), *changed}))
            rules[r.id] = after
            sites.rules.setdefault(r.id, []).append((doc, i))
        else:
            weak = weakening_changes(before, r) if before is not None else []
            if weak:  # an inherited rule written again in full, checking less: say how to do it openly
                key = weakened_fields(before, r)[0] if before is not None else "id"
                line, col = doc.where(("rules", i, key))
                problems.append(Problem(doc.file, line, col, _unjustified(r.id, weak, base, "restate"), r.id))
                continue
            rules[r.id] = r
            sites.rules[r.id] = [(doc, i)]
            overridden.pop(r.id, None)
    if problems:
        return None
    final_rules = tuple(rules.values())
    chain = ((prof.id, prof.version, str(path)), *(base.chain if base else ()))
    waivers = (*(base.waivers if base else ()), *prof.waivers)
    canonical = {
        "id": prof.id,
        "version": prof.version,
        "title": prof.title,
        "source": prof.source.model_dump(mode="json"),
        "extends": [{"id": c[0], "version": c[1]} for c in chain[1:]],
        "parameters": {k: _param_json(v) for k, v in sorted(params.items())},
        "tables": {k: (v.model_dump(mode="json") if hasattr(v, "model_dump") else v)
                   for k, v in sorted(tables.items())},
        "classes": {k: (v.model_dump(mode="json") if hasattr(v, "model_dump") else v)
                    for k, v in sorted(classes.items())},
        "rules": [_rule_json(r) for r in final_rules],
        "waivers": [w.model_dump(mode="json") for w in waivers],
    }
    if prof.allow_no_mandatory:
        canonical["allow_no_mandatory"] = True
    if removed:
        canonical["removed_rules"] = [{"id": x.id, "justification": x.justification, "profile": x.profile}
                                      for x in removed]
    if weakened:
        canonical["weakened_rules"] = [w.to_dict() for w in weakened]
    try:
        sha = hashlib.sha256(canonical_dumps(canonical).encode("utf-8")).hexdigest()
    except ValueError:  # nan or inf somewhere: say where (only on this failure path)
        for where in _nonfinite(doc.data, ()):
            line, col = doc.where(where)
            problems.append(Problem(doc.file, line, col, f"{'/'.join(map(str, where))}: not a finite number "
                                    "(write a number such as 1.0)", _rule_at(doc, where)))
        if not problems:
            problems.append(Problem(doc.file, None, None, "the profile holds a value that is not a finite number"))
        return None
    return ResolvedProfile(
        id=prof.id, version=prof.version, title=prof.title, description=prof.description,
        source=prof.source, parameters=params, tables=tables, classes=classes, rules=final_rules,
        tests=tuple(prof.tests), waivers=waivers, path=path, chain=chain, canonical=canonical,
        sha256=sha, allow_no_mandatory=prof.allow_no_mandatory, sites=sites, removed=tuple(removed),
        overridden=overridden, weakened=tuple(weakened),
    )


#: keys added to the models after profiles were published: written into the canonical form only when
#: set, so a profile that does not use them keeps its SHA-256
_NEW_KEYS = {"checker_may_set": False, "internal_note": None}


def _rule_json(r: Rule) -> dict[str, Any]:
    d = r.model_dump(mode="json", exclude={"override"})
    if d.get("internal_note") is None:
        d.pop("internal_note", None)
    return d


def _param_json(p: Parameter) -> dict[str, Any]:
    d = p.model_dump(mode="json")
    for k, default in _NEW_KEYS.items():
        if k in d and d[k] == default:
            del d[k]
    return d


def _nonfinite(obj: Any, path: tuple[Any, ...]) -> list[tuple[Any, ...]]:
    if isinstance(obj, float) and (obj != obj or obj in (float("inf"), float("-inf"))):
        return [path]
    if isinstance(obj, dict):
        return [w for k, v in obj.items() for w in _nonfinite(v, (*path, k))]
    if isinstance(obj, list):
        return [w for i, v in enumerate(obj) for w in _nonfinite(v, (*path, i))]
    return []


def _did_you_mean(name: str, candidates: Any, what: str = "") -> str:
    near = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    if not near:
        return ""
    return f"; did you mean {near[0]!r}" + (f" ({what})" if what else "") + "?"


# --- semantic checks ---------------------------------------------------------------------------

@lru_cache(maxsize=1)
def manifest_paths() -> tuple[frozenset[str], tuple[str, ...]]:
    """Paths the delivery manifest model defines, and prefixes under which any key is allowed.

    Derived by walking ``delivery.manifest.Manifest`` (dict-typed fields such as
    ``tender.parameters`` or ``documents`` accept any sub-key), so a rule's ``when`` can only read
    facts a delivery can state in the published schema.
    """
    from ..delivery.manifest import Manifest

    exact: set[str] = set()
    open_: list[str] = []

    def walk(model: type[BaseModel], prefix: str, depth: int) -> None:
        for name, f in model.model_fields.items():
            path = f"{prefix}{name}"
            exact.add(path)
            t = _unwrap(f.annotation)
            if isinstance(t, type) and issubclass(t, BaseModel) and depth < 6:
                walk(t, path + ".", depth + 1)
            elif get_origin(t) is dict or t is dict:
                open_.append(path + ".")

    walk(Manifest, "", 0)
    return frozenset(exact), tuple(sorted(open_))


def manifest_path_problem(name: str) -> str | None:
    """Why ``manifest.<path>`` is not a path the delivery schema defines (None when it is)."""
    path = name[len("manifest."):]
    exact, open_ = manifest_paths()
    if path in exact or any(path.startswith(p) and len(path) > len(p) for p in open_):
        return None
    cands = sorted(exact | {p + "<key>" for p in open_})
    parent = path.rsplit(".", 1)[0] if "." in path else ""
    children = sorted(c[len(parent) + 1:] for c in exact if parent and c.startswith(parent + ".")
                      and "." not in c[len(parent) + 1:])
    near = difflib.get_close_matches(path, cands, n=1, cutoff=0.6)
    if children:
        near_child = difflib.get_close_matches(path.rsplit(".", 1)[1], children, n=1, cutoff=0.6)
        hint = (f"; did you mean 'manifest.{parent}.{near_child[0]}'?" if near_child else
                f"; manifest.{parent} has {', '.join(children)}")
    else:
        hint = f"; did you mean 'manifest.{near[0]}'?" if near else ""
    return (f"{name!r} is not a key the delivery manifest defines (specs/schema/delivery.schema.json): "
            f"a rule may read only what a delivery can state in its schema{hint}")


def _parse(text: str) -> expr.Expression:
    from . import expr  # numpy: only when a profile is validated, not when served from the cache

    return expr.parse(text)


def semantic_problems(p: ResolvedProfile, *, check_measures: bool = True) -> list[Problem]:
    """Units, threshold numbers, expressions, manifest paths, measures, parameters: linear in rules."""
    from ..units import NON_NUMERIC, number_problem, profile_unit_problem
    from ..units import check_unit as parse_unit  # the usual spellings without loading pint
    from .catalog import measure_info

    out: list[Problem] = []
    sites = p.sites or _Sites()

    def add(rule: Rule | None, key: tuple[Any, ...], msg: str) -> None:
        if rule is None:
            out.append(Problem(str(p.path), None, None, msg))
            return
        file, line, col = sites.rule_where(rule.id, key)
        out.append(Problem(file, line, col, msg, rule.id))

    def add_param(name: str, key: str | None, msg: str) -> None:
        file, line, col = sites.param_where(name, key)
        out.append(Problem(file, line, col, msg))

    numeric_units: dict[str, str] = {}
    for name, par in p.parameters.items():
        unit = par.unit
        spelled = profile_unit_problem(unit)
        if spelled:
            add_param(name, "unit", f"parameter {name}: {spelled}")
            continue
        for key in ("value", "default"):
            v = getattr(par, key)
            if v is not None and par.choices is not None and v not in par.choices:
                add_param(name, key, f"parameter {name}: {key} {v!r} is not one of "
                          f"{', '.join(map(str, par.choices))}" + _did_you_mean(str(v), map(str, par.choices)))
            elif isinstance(v, str) and unit == "text" and name.endswith("_crs"):
                why = _crs_problem(v)
                if why:
                    add_param(name, key, f"parameter {name}: {why}")
        if unit is None or unit in NON_NUMERIC:
            continue
        try:
            parse_unit(unit)
        except UnitError as exc:
            add_param(name, "unit", f"parameter {name}: {exc}")
            continue
        numeric_units[name] = unit
        for key in ("value", "default"):
            v = getattr(par, key)
            if v is not None:
                why = number_problem(v)
                if why:
                    add_param(name, key, f"parameter {name}: {key}: {why}")
        for i, c in enumerate(par.choices or []):
            why = number_problem(c)
            if why:
                add_param(name, "choices", f"parameter {name}: choices[{i}]: {why}")
    for cname, cset in p.classes.items():
        try:
            why = profile_unit_problem(cset.unit)
            if why:
                raise UnitError(why)
            parse_unit(cset.unit)
        except UnitError as exc:
            out.append(Problem(str(p.path), None, None, f"class set {cname}: {exc}"))
    known = set(p.parameters) | {f"class.{c}" for c in p.classes}
    read_params: set[str] = set()
    manifest_checked: dict[str, str | None] = {}
    unit_ok: dict[tuple[str, str], str | None] = {}
    mandatory = 0

    def check_manifest_names(rule: Rule, key: tuple[str, ...], names: Any) -> None:
        for n in names:
            if n.startswith("manifest."):
                if n not in manifest_checked:
                    manifest_checked[n] = manifest_path_problem(n)
                if manifest_checked[n]:
                    add(rule, key, str(manifest_checked[n]))

    for r in p.rules:
        if r.level == "mandatory":
            mandatory += 1
        info = None
        if r.manual or r.measure.startswith("manual."):
            if not r.measure.startswith("manual."):
                add(r, ("measure",), f"a manual rule reads measure 'manual.{r.id}', not {r.measure!r}")
        elif r.measure.startswith("manifest."):
            check_manifest_names(r, ("measure",), (r.measure,))
        elif check_measures:
            info = measure_info(r.measure)
            if info is None:
                add(r, ("measure",), f"unknown measure {r.measure!r}{_near_measure(r.measure)} "
                    "(see `orthospec measures`)")
            elif info[0] != r.scope:  # located at the measure: an override that swaps it is the cause
                add(r, ("measure",), f"measure {r.measure!r} is at scope {info[0]!r}, rule says {r.scope!r}")
        req = r.requirement
        req_numeric = req.unit is not None and req.unit not in NON_NUMERIC and req.unit != "any"
        if req_numeric:
            try:
                why = profile_unit_problem(req.unit)
                if why:
                    raise UnitError(why)
                parse_unit(req.unit)
            except UnitError as exc:
                add(r, ("requirement", "unit"), str(exc))
                req_numeric = False
        if req.op == "between" and (req.min is None and req.max is None):
            add(r, ("requirement",), "op 'between' needs min and/or max")
        if req.op == "in" and not req.values:
            add(r, ("requirement",), "op 'in' needs values")
        if req.op in ("<", "<=", ">", ">=", "==", "!=") and req.value is None:
            add(r, ("requirement",), f"op {req.op!r} needs a value")
        if r.when:
            try:
                e = _parse(r.when)
            except ExpressionError as exc:
                add(r, ("when",), str(exc) + _single_equals(r.when))
            else:
                if not e.names:
                    add(r, ("when",), _constant_when(e, r.when))
                _check_names(r, ("when",), e, known, check_measures, measure_info, add)
                check_manifest_names(r, ("when",), e.names)
                read_params |= params_named(e.names, p.parameters)
        numeric_threshold = req_numeric or req.op in _ORDER_OPS
        for key in ("value", "min", "max"):
            v = getattr(req, key)
            if v is None:
                continue
            if not isinstance(v, str):
                if numeric_threshold:
                    why = number_problem(v)
                    if why:
                        add(r, ("requirement", key), f"requirement {key}: {why}")
                continue
            if numeric_threshold:
                why = number_problem(v)
                if why and "is not a number" not in why:
                    add(r, ("requirement", key), f"requirement {key}: {why}")
                    continue
            elif req.op in ("==", "!=", "in") and not _looks_like_expr(v, known):
                continue
            try:
                e = _parse(v)
            except ExpressionError as exc:
                hint = " (a threshold is a number such as 1.0, or an expression over parameters)" \
                    if numeric_threshold else ""
                add(r, ("requirement", key), f"{exc}{hint}{_single_equals(v)}")
                continue
            _check_names(r, ("requirement", key), e, known, check_measures, measure_info, add)
            check_manifest_names(r, ("requirement", key), e.names)
            used = params_named(e.names, p.parameters)
            read_params |= used
            if req_numeric and used:
                _check_dimensions(r, key, v, e, used, numeric_units, req.unit, unit_ok, out, sites)
    # a parameter an extending profile adds but no rule reads is almost always a misspelling
    for name in sorted(sites.own_params - read_params):
        if not sites.inherited_params:
            break
        near = difflib.get_close_matches(name, sorted(sites.inherited_params), n=1, cutoff=0.6)
        hint = (f"; did you mean {near[0]!r} (inherited)? As written, the inherited {near[0]} keeps its "
                "value") if near else ""
        add_param(name, None, f"parameter {name} is defined here but no rule reads it{hint}")
    if mandatory == 0 and not p.allow_no_mandatory:
        top = sites.top
        out.append(Problem(top.file if top else str(p.path), 1 if top else None, 1 if top else None,
                           f"profile {p.id} has no mandatory rule, so it would accept every delivery; "
                           "add one, or say so explicitly with `allow_no_mandatory: true`"))
    return out


def _crs_problem(text: str) -> str | None:
    """Why a map projection value cannot be used (pyproj cannot read it, or it has no EPSG code)."""
    from ..delivery.crs import CrsProblem, epsg_name

    try:
        epsg_name(text)
    except CrsProblem as exc:
        return str(exc)
    return None


_VERDICTS_EXPECTED = ("accepted", "rejected", "incomplete")


def _test_problems(p: ResolvedProfile, sites: _Sites, *, paths: bool = True) -> list[Problem]:
    """The profile's own `tests:`: every delivery folder and checker file exists (relative to the
    profile file), every parameter and rule named exists, every verdict is one a check gives. Found
    here with a line, not later by `orthospec verify`."""
    from ..verdicts import VERDICTS

    top = sites.top
    out: list[Problem] = []

    def add(i: int, key: tuple[Any, ...], msg: str) -> None:
        line, col = top.where(("tests", i, *key)) if top is not None else (None, None)
        out.append(Problem(top.file if top is not None else str(p.path), line, col, f"tests[{i}]: {msg}"))

    here = p.path.parent
    rule_ids = {r.id for r in p.rules}
    for i, t in enumerate(p.tests):
        folder = here / t.delivery
        if not paths:
            pass
        elif not folder.is_dir():
            add(i, ("delivery",), f"delivery folder {t.delivery!r} not found (paths are relative to the profile "
                f"file's folder {str(here)!r}){_near_path(folder)}")
        elif not (folder / "delivery.yaml").is_file():
            add(i, ("delivery",), f"{t.delivery!r} is not a delivery (it has no delivery.yaml)")
        checker = here / t.checker if t.checker is not None else None
        if paths and checker is not None and not (
            checker.is_file() or (checker / "checker.yaml").is_file()
        ):
            add(i, ("checker",), f"checker file or folder {t.checker!r} not found (relative to the profile file's folder)"
                + _near_path(checker))
        for name, given in t.params.items():
            par = p.parameters.get(name)
            if par is None:
                add(i, ("params", name), f"params: profile {p.id} has no parameter {name!r}"
                    + _did_you_mean(name, p.parameters))
                continue
            own = par.value if par.value is not None else par.default
            if (len(p.chain) > 1 and not par.checker_may_set and own is not None
                    and isinstance(given, int | float) and isinstance(own, int | float)
                    and not isinstance(given, bool) and float(given) != float(own)):
                add(i, ("params", name), f"params: {name} = {given} differs from {own}, the value this tender "
                    "fixes; the check would stop (the contract wins): leave it out, or mark the parameter "
                    "`checker_may_set: true`")
        extra = sorted(set(t.expect) - {"verdict", "rules"})
        if extra:
            add(i, ("expect", extra[0]), f"expect: unknown key {extra[0]!r}; expect holds verdict and rules")
        verdict = t.expect.get("verdict")
        if verdict is not None and verdict not in _VERDICTS_EXPECTED:
            add(i, ("expect", "verdict"), f"expect: verdict {verdict!r} is not one of {', '.join(_VERDICTS_EXPECTED)}"
                + _did_you_mean(str(verdict), _VERDICTS_EXPECTED))
        rules = t.expect.get("rules") or {}
        if not isinstance(rules, dict):
            add(i, ("expect", "rules"), "expect: rules maps a rule id to the verdict expected, e.g. "
                "{JRC-12.7-RMSEX: pass}")
            continue
        for rid, want in rules.items():
            if rid not in rule_ids:
                add(i, ("expect", "rules", rid), f"expect: profile {p.id} has no rule {rid!r}"
                    + _did_you_mean(str(rid), rule_ids))
            elif want not in VERDICTS:
                add(i, ("expect", "rules", rid), f"expect: {rid}: verdict {want!r} is not one of "
                    f"{', '.join(VERDICTS)}" + _did_you_mean(str(want), VERDICTS))
    return out


def _near_path(path: Path) -> str:
    """`; did you mean '../x'?` for a missing path whose name exists in a nearby folder."""
    parent = path.parent
    for _ in range(4):
        if parent.is_dir():
            break
        parent = parent.parent
    else:
        return ""
    try:
        names = [x.name for x in parent.iterdir()][:500]
    except OSError:
        return ""
    near = difflib.get_close_matches(path.name, names, n=1, cutoff=0.8)
    return f"; {str(parent / near[0])!r} exists" if near and parent != path.parent else (
        f"; did you mean {near[0]!r}?" if near and near[0] != path.name else "")


def params_named(names: Any, params: Mapping[str, Any]) -> set[str]:
    """The parameters an expression's names refer to (``NAME`` or ``param.NAME``)."""
    out = set()
    for n in names:
        n2 = n[6:] if n.startswith("param.") else n
        if n2 in params:
            out.add(n2)
    return out


def _check_names(rule: Rule, key: tuple[str, ...], e: expr.Expression, known: set[str], check_measures: bool,
                 measure_info: Any, add: Any) -> None:
    for n in e.names:
        if n in known or n.startswith("manifest.") or n.startswith("param."):
            continue
        if not check_measures or measure_info(n) is not None:
            continue
        add(rule, key, f"expression {e.source!r} names {n!r}, which is neither a parameter nor a measure"
            + _did_you_mean(n, known, "parameter"))


def _check_dimensions(r: Rule, key: str, text: str, e: expr.Expression, used: set[str],
                      numeric_units: dict[str, str], req_unit: str, memo: dict[tuple[str, str], str | None],
                      out: list[Problem], sites: _Sites) -> None:
    """The unit an expression over parameters yields must meet the requirement's unit (px meets m)."""
    from ..units import UnitProbe, probe_meets

    if any(not (n in numeric_units or (n.startswith("param.") and n[6:] in numeric_units)) for n in e.names):
        return  # reads measures, manifest facts or text parameters: checked when evaluated
    sig = (text, req_unit + "|" + ",".join(f"{n}={numeric_units[n]}" for n in sorted(used)))
    if sig not in memo:
        env = {n: UnitProbe.of(numeric_units[n[6:] if n.startswith("param.") else n]) for n in e.names}
        units = ", ".join(f"{n} is in {numeric_units[n]!r}" for n in sorted(used))
        why: str | None = None
        try:
            got = e.evaluate(env)
            if not probe_meets(got, req_unit):
                why = (f"requirement {key} {text!r} yields {got.units.describe()} ({units}), which cannot be "
                       f"compared with the rule's unit {req_unit!r}")
        except (ExpressionError, UnitError, ValueError, TypeError) as exc:
            why = f"requirement {key} {text!r}: units do not combine ({units}): {exc}"
        memo[sig] = why
    if memo[sig]:
        name = sorted(used)[0]
        file, line, col = sites.param_where(name, "unit")
        rfile, rline, _ = sites.rule_where(r.id, ("requirement",))
        out.append(Problem(file, line, col, f"parameter {name}: {memo[sig]} (rule {r.id} at "
                           f"{rfile}:{rline})"))


def _constant_when(e: expr.Expression, text: str) -> str:
    """A condition that reads no fact decides nothing: say what it always is and what to write."""
    try:
        value = bool(getattr(e.evaluate({}), "magnitude", e.evaluate({})))
    except (ExpressionError, ArithmeticError, TypeError, ValueError):
        value = None
    if value is False:
        return (f"condition {text!r} reads no fact and is always false: the rule would never apply; to take a rule "
                "out, list it in remove_rules with a justification")
    return f"condition {text!r} reads no fact and is always {'true' if value else 'the same'}: leave `when` out"


def _single_equals(text: str) -> str:
    """The hint for ``a = b`` written for ``a == b`` (the grammar has no assignment)."""
    return "; compare with `==` (a single `=` is not an operator)" \
        if re.search(r"(?<![=!<>])=(?!=)", text) else ""


def _near_measure(name: str) -> str:
    from .catalog import all_names, stale_hint

    near = difflib.get_close_matches(name, all_names(), n=1, cutoff=0.8)
    return (f"; did you mean {near[0]!r}?" if near else "") + stale_hint()


def _looks_like_expr(text: str, known: set[str]) -> bool:
    try:
        e = _parse(text)
    except ExpressionError:
        return False
    return bool(e.names & known)
