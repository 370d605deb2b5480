"""Load, validate and resolve spec profiles (``extends``, overrides, removals, checksum).

Validation reports *every* problem with ``file:line:column``: the pydantic models (one message per
location, with a did-you-mean for unknown keys), then semantic checks (unique ids, threshold
numbers, units and their dimensions, expressions, manifest paths the delivery schema defines, known
measures and their scope, parameters nobody reads, who may change a standard value).

Cost stays linear in the number of rules, each file is parsed once per process, and a resolved,
validated profile is cached on disk keyed by the SHA-256 of every file in its ``extends`` chain
(see :mod:`orthospec.profile.cache`).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from ..errors import SpecError
from ..resources import specs_dir
from ..yamlio import YamlError
from .changes import Weakening
from .extends import _check_unique_ids, _merge
from .files import _LAST_SHA, _load_doc, file_sha256
from .lookup import HEADER_BYTES, available, find_by_id, find_profile, plugin_profiles, read_header
from .models import Parameter, Rule
from .problems import Problem, _format, _yaml_problem, parse_profile
from .resolved import Removal, ResolvedProfile, _Sites, canonical_dumps, param_location
from .semantics import (
    _test_problems,
    manifest_path_problem,
    manifest_paths,
    params_named,
    semantic_problems,
)

#: Re-exported: reading files (:mod:`.files`), finding profiles (:mod:`.lookup`), validation
#: messages (:mod:`.problems`), the resolved profile (:mod:`.resolved`), ``extends``
#: (:mod:`.extends`) and the semantic checks (:mod:`.semantics`) were split out of this module;
#: their public names stay importable here.
__all__ = ["HEADER_BYTES", "MAX_EXTENDS_DEPTH", "Problem", "Removal", "ResolvedProfile",
           "available", "canonical_dumps", "file_sha256", "find_by_id", "find_profile",
           "load_profile", "manifest_path_problem", "manifest_paths", "param_location",
           "params_named", "parse_profile", "plugin_profiles", "read_header", "semantic_problems",
           "validate_file"]

MAX_EXTENDS_DEPTH = 8


_RESOLVED: dict[str, tuple[ResolvedProfile, list[tuple[str, str]]]] = {}


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

        if (
            not extended_by_plugins()
        ):  # validity then depends on installed plugins: not cached on disk
            cache.put(k, _dump(resolved), shas)
    else:
        _RESOLVED[k + ":nomeasures"] = (resolved, shas)
    return resolved, []


def _dump(p: ResolvedProfile) -> dict[str, Any]:
    """The JSON payload profile/cache.py stores for a resolved profile (_rebuild reads it back)."""
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
        id=c["id"],
        version=c["version"],
        title=c["title"],
        description=d.get("description"),
        source=Source.model_validate(c["source"]),
        parameters={k: Parameter.model_validate(v) for k, v in c["parameters"].items()},
        tables={k: LookupTable.model_validate(v) for k, v in c["tables"].items()},
        classes={k: ClassSet.model_validate(v) for k, v in c["classes"].items()},
        rules=tuple(Rule.model_validate(r) for r in c["rules"]),
        tests=tuple(ProfileTest.model_validate(t) for t in d.get("tests", [])),
        waivers=tuple(ProfileWaiver.model_validate(w) for w in c["waivers"]),
        path=Path(d["path"]),
        chain=tuple((a, b, f) for a, b, f in d["chain"]),
        canonical=c,
        sha256=sha,
        allow_no_mandatory=bool(d.get("allow_no_mandatory")),
        removed=tuple(
            Removal(x["id"], x["justification"], x["profile"]) for x in c.get("removed_rules", [])
        ),
        overridden={k: tuple(v) for k, v in d.get("overridden", {}).items()},
        weakened=tuple(Weakening.from_dict(w) for w in c.get("weakened_rules", [])),
    )


def _resolve(
    path: Path, problems: list[Problem], *, depth: int, seen: tuple[str, ...]
) -> ResolvedProfile | None:
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
        problems.append(
            Problem(
                doc.file, *doc.where(("extends",)), f"extends cycle: {' -> '.join((*seen, key))}"
            )
        )
        return None
    _check_unique_ids(prof, doc, problems)
    base: ResolvedProfile | None = None
    if prof.extends is not None:
        if depth >= MAX_EXTENDS_DEPTH:
            problems.append(Problem(doc.file, *doc.where(("extends",)), "extends chain too deep"))
            return None
        try:
            parent_path = find_by_id(
                prof.extends.id, near=path.parent, version=prof.extends.version
            )
        except SpecError as exc:
            problems.append(Problem(doc.file, *doc.where(("extends",)), str(exc)))
            return None
        base = _resolve(parent_path, problems, depth=depth + 1, seen=(*seen, key))
        if base is None:
            return None
        if (base.id, base.version) != (prof.extends.id, prof.extends.version):
            problems.append(
                Problem(
                    doc.file,
                    *doc.where(("extends",)),
                    f"extends {prof.extends.id} {prof.extends.version}, but {parent_path} "
                    f"is {base.id} {base.version}",
                )
            )
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
    return (
        f"id {p.id!r} is reserved: it names the profile {kind} in {files}, and this file is not that "
        f"profile; give this profile its own id (e.g. '{p.id}-itt') and `extends: {{id: {owners[0][0]}, "
        f"version: {owners[-1][1]}}}` to build on it"
    )
