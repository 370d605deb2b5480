"""The resolved-profile cache (issue 14 item 1): keyed by the SHA-256 of every file in the extends
chain, never stale, JSON only, safe to delete; and one parse per profile file per process."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from orthospec.profile import cache, catalog, files, loader
from orthospec.profile.loader import available, load_profile, validate_file

BASE = """\
orthospec_profile: 1
id: cbase
version: 1.0.0
title: Cache base
source: {title: test}
parameters:
  tol: {unit: m, default: 2.5}
rules:
  - id: A
    title: a
    clause: {document: JRC, section: "12.7"}
    quote: q
    scope: block
    measure: checkpoints.rmse_x
    requirement: {op: "<=", value: tol, unit: m}
    consequence: reject_block
"""
CHILD = """\
orthospec_profile: 1
id: cchild
version: 1.0.0
title: Cache child
source: {title: ITT}
extends: {id: cbase, version: 1.0.0}
parameters:
  tol: {value: 1.5, justification: "ITT 4.1"}
"""


@pytest.fixture
def cache_dir(tmp_path, monkeypatch) -> Path:
    d = tmp_path / "cache"
    monkeypatch.setenv("ORTHOSPEC_CACHE_DIR", str(d))
    loader._RESOLVED.clear()
    # the key includes a fingerprint of the code; recompute it so a subprocess agrees with us
    cache.code_fingerprint.cache_clear()
    catalog.fingerprint.cache_clear()
    catalog._read_snapshot.cache_clear()
    return d / "profiles"


def entries(d: Path) -> list[Path]:
    return sorted(d.glob("*.json")) if d.is_dir() else []


def fresh_process_value(path: Path, env_dir: Path) -> tuple[float, bool]:
    """Load in a new process (empty memory): (tol value, served from the disk cache?)."""
    code = (
        "import sys; from orthospec.profile.loader import load_profile; p = load_profile(sys.argv[1]); "
        "print(p.parameters['tol'].value if p.parameters['tol'].value is not None "
        "else p.parameters['tol'].default, p.sites is None)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(path)],
        capture_output=True,
        text=True,
        check=True,
        env={"ORTHOSPEC_CACHE_DIR": str(env_dir), "PATH": "/usr/bin:/bin"},
    ).stdout.split()
    return float(out[0]), out[1] == "True"


def test_cold_load_writes_json_and_a_new_process_reuses_it(tmp_path, cache_dir):
    (tmp_path / "base.yaml").write_text(BASE)
    child = tmp_path / "child.yaml"
    child.write_text(CHILD)
    cold = load_profile(child)
    assert cold.sites is not None  # validated from the files
    [entry] = entries(cache_dir)
    doc = json.loads(entry.read_text())  # JSON, not pickle
    recorded = dict(map(tuple, doc["files"]))
    assert recorded == {
        str(child): hashlib.sha256(child.read_bytes()).hexdigest(),
        str(tmp_path / "base.yaml"): hashlib.sha256(
            (tmp_path / "base.yaml").read_bytes()
        ).hexdigest(),
    }
    value, from_cache = fresh_process_value(child, cache_dir.parent)
    assert value == 1.5 and from_cache
    # what the cache serves is the same profile, byte for byte
    loader._RESOLVED.clear()
    warm = load_profile(child)
    assert warm.sites is None
    assert warm.canonical_json() == cold.canonical_json() and warm.sha256 == cold.sha256
    assert (
        warm.rules == cold.rules and warm.parameters == cold.parameters and warm.chain == cold.chain
    )
    assert warm.removed == cold.removed and warm.overridden == cold.overridden
    assert not list(cache_dir.glob(".tmp-*"))  # written atomically


@pytest.mark.parametrize("edit", ["child", "base"])
def test_a_changed_file_in_the_chain_is_never_served_stale(tmp_path, cache_dir, edit):
    base, child = tmp_path / "base.yaml", tmp_path / "child.yaml"
    base.write_text(BASE)
    child.write_text(CHILD)
    assert load_profile(child).parameters["tol"].value == 1.5
    if edit == "child":
        child.write_text(CHILD.replace("value: 1.5", "value: 1.25"))
        expected = 1.25
    else:  # the parent changes a rule; the child file is untouched
        base.write_text(BASE.replace('op: "<="', 'op: "<"'))
        expected = 1.5
    # same process (memo) and a new process (disk) both see the new content
    p = load_profile(child)
    assert p.parameters["tol"].value == expected
    assert p.rule("A").requirement.op == ("<" if edit == "base" else "<=")
    assert fresh_process_value(child, cache_dir.parent) == (expected, True)


def test_a_damaged_entry_is_a_miss(tmp_path, cache_dir):
    (tmp_path / "base.yaml").write_text(BASE)
    child = tmp_path / "child.yaml"
    child.write_text(CHILD)
    load_profile(child)
    [entry] = entries(cache_dir)
    doc = json.loads(entry.read_text())
    doc["profile"]["canonical"]["parameters"]["tol"]["value"] = 99.0  # tampered: no longer hashes
    entry.write_text(json.dumps(doc))
    loader._RESOLVED.clear()
    p = load_profile(child)
    assert p.parameters["tol"].value == 1.5 and p.sites is not None
    entry.write_text("{not json")
    loader._RESOLVED.clear()
    assert load_profile(child).parameters["tol"].value == 1.5


def test_an_invalid_profile_is_never_cached(tmp_path, cache_dir):
    (tmp_path / "base.yaml").write_text(BASE)
    child = tmp_path / "child.yaml"
    child.write_text(CHILD.replace("value: 1.5", "value: 1,5"))
    assert validate_file(child)
    assert entries(cache_dir) == []
    assert validate_file(child)  # and the second time it is still invalid


def test_cache_can_be_switched_off_and_deleted(tmp_path, monkeypatch):
    monkeypatch.setenv("ORTHOSPEC_CACHE_DIR", "off")
    assert cache.cache_dir() is None
    (tmp_path / "base.yaml").write_text(BASE)
    loader._RESOLVED.clear()
    assert load_profile(tmp_path / "base.yaml").id == "cbase"
    monkeypatch.setenv("ORTHOSPEC_CACHE_DIR", str(tmp_path / "gone"))
    assert cache.cache_dir() == tmp_path / "gone" / "profiles"
    monkeypatch.delenv("ORTHOSPEC_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "xdg" / "orthospec" / "profiles"


def test_one_parse_per_profile_file_per_process(tmp_path, cache_dir, monkeypatch):
    parsed: list[str] = []
    real = files.load_text

    def counting(text: str, file: str):
        parsed.append(Path(file).name)
        return real(text, file)

    monkeypatch.setattr(files, "load_text", counting)
    files._DOCS.clear()
    monkeypatch.setenv("ORTHOSPEC_CACHE_DIR", "off")
    (tmp_path / "t.yaml").write_text(
        CHILD.replace("cbase", "jrc-v3")
        .replace("1.0.0}", "3.0.0}")
        .replace('  tol: {value: 1.5, justification: "ITT 4.1"}', "  tolerance_xy: {value: 0.5}")
    )
    # what `orthospec profiles` and a check with a tender profile do in one process
    rows = available([tmp_path])
    assert any(r[0] == "jrc-v3" for r in rows)
    for _ in range(3):
        load_profile("jrc-v3")
        load_profile(tmp_path / "t.yaml")
    assert parsed.count("jrc-v3.yaml") == 1 and parsed.count("t.yaml") == 1, parsed
