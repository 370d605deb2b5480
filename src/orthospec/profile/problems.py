"""What is wrong with a profile file, said with ``file:line:column``: the :class:`Problem` every
validation step reports, a YAML error kept at its position, and pydantic's model errors turned into
one message per location (a did-you-mean for unknown keys, the decimal comma that split a number,
the version an ``extends`` should pin).
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from ..yamlio import Located, YamlError
from .lookup import _semver_key, available
from .models import Profile, Rule, RuleOverride


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
    return Problem(
        str(path), None, None, text.split(": ", 1)[-1] if text.startswith(str(path)) else text
    )


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
            models = [
                a
                for a in (_unwrap(x) for x in args)
                if isinstance(a, type) and issubclass(a, BaseModel)
            ]
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
            if (
                get_origin(_unwrap(t)) is list
                and i + 2 < len(parts)
                and parts[i + 2] in ("rule", "override")
            ):
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
            near = difflib.get_close_matches(
                str(raw_loc[-1]), _fields_at(raw_loc[:-1]), n=1, cutoff=0.6
            )
            if near:
                suggested.add((*raw_loc[:-1], near[0]))
    for e in errors:
        if e["type"] == "missing" and tuple(e["loc"]) in suggested:
            continue
        raw_loc = tuple(e["loc"])
        path = tuple(p for p in raw_loc if not (isinstance(p, str) and p in ("rule", "override")))
        # a union of scalar types reports one error per member type: name the location once
        path = tuple(
            p for p in path if p not in ("float", "int", "str", "bool", "list[...]", "dict[...]")
        )
        line, col = doc.where(path)
        loc = "/".join(str(p) for p in path) or "(document)"
        if e["type"] == "extra_forbidden":
            key = str(path[-1])
            allowed = _fields_at(raw_loc[:-1])
            near = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
            hint = (
                f"; did you mean {near[0]!r}?"
                if near
                else (f"; allowed: {', '.join(allowed)}" if allowed else "")
            )
            if key.isdigit():  # `{value: 1,0}`: in a {flow mapping} the comma splits the number
                hint = _split_number_hint(doc, path, key)
            msg = f"{loc}: unknown key {key!r}{hint}"
        elif e["type"] == "missing" and path == ("extends", "version"):
            msg = f"{loc}: extends pins the version it builds on{_versions_hint(doc)}"
        else:
            got = e.get("input")
            shown = (
                "" if isinstance(got, dict | list) or got is None else f" (got {_short(repr(got))})"
            )
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
    return (
        f": write `extends: {{id: {pid}, version: {versions[-1]}}}` (a later {pid} is then never picked up "
        "silently)"
    )


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
        if (
            i > 0
            and isinstance(parent[keys[i - 1]], int)
            and not isinstance(parent[keys[i - 1]], bool)
        ):
            prev, whole = keys[i - 1], parent[keys[i - 1]]
            return (
                f": a decimal comma inside {{...}} splits the number (`{prev}: {whole},{key}` reads as "
                f"{prev} {whole} and a key '{key}'); write {whole}.{key}"
            )
    return (
        ": a decimal comma inside {...} splits a number (`1,0` reads as 1 and a key '0'); write 1.0"
    )


def parse_profile(doc: Located) -> tuple[Profile | None, list[Problem]]:
    """Model validation of one file (no extends resolution): one problem per location."""
    if not isinstance(doc.data, dict):
        return None, [Problem(doc.file, 1, 1, "a profile must be a YAML mapping")]
    if "orthospec_profile" not in doc.data:
        return None, [
            Problem(
                doc.file,
                1,
                1,
                "not an orthospec spec profile (it has no 'orthospec_profile: 1' key)",
            )
        ]
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


def _did_you_mean(name: str, candidates: Any, what: str = "") -> str:
    near = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    if not near:
        return ""
    return f"; did you mean {near[0]!r}" + (f" ({what})" if what else "") + "?"


def _format(problems: list[Problem]) -> str:
    head = f"{len(problems)} problem(s) in profile:" if len(problems) > 1 else "invalid profile:"
    lines = [str(p) for p in problems[:50]]
    if len(problems) > 50:
        lines.append(f"... and {len(problems) - 50} more")
    return head + "\n  " + "\n  ".join(lines)
