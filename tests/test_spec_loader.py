import hashlib
import json
from pathlib import Path

import jsonschema
import pytest

from orthospec import schemas as schema_mod
from orthospec.errors import SpecError
from orthospec.profile.loader import load_profile, validate_file
from orthospec.profile.schema import dumps as schema_dumps
from orthospec.resources import specs_dir


def write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


BASE = """\
orthospec_profile: 1
id: base
version: 1.0.0
title: Base
source: {title: JRC}
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
  - id: B
    title: b
    clause: {document: JRC, section: "12.7"}
    quote: q
    scope: block
    measure: checkpoints.rmse_y
    requirement: {op: "<=", value: tol, unit: m}
    consequence: reject_block
"""


def test_mini_profile_loads_with_checksum(mini_profile):
    p = load_profile(mini_profile)
    assert p.id == "mini" and len(p.rules) == 5
    assert p.sha256 == hashlib.sha256(p.canonical_json().encode()).hexdigest()


def test_checksum_ignores_formatting_but_not_content(tmp_path):
    a = load_profile(write(tmp_path, "a.yaml", BASE))
    b = load_profile(
        write(tmp_path, "b.yaml", "# a comment\n" + BASE.replace("{title: JRC}", "{ title:  JRC }"))
    )
    c = load_profile(write(tmp_path, "c.yaml", BASE.replace("default: 2.5", "default: 2.4")))
    assert a.sha256 == b.sha256
    assert a.sha256 != c.sha256


def test_extends_overrides_and_removals(tmp_path):
    write(tmp_path, "base.yaml", BASE)
    child = write(
        tmp_path,
        "child.yaml",
        """\
orthospec_profile: 1
id: child
version: 0.1.0
title: Child
source: {title: ITT}
extends: {id: base, version: 1.0.0}
allow_no_mandatory: true  # the only rule left is made recommended
parameters:
  tol: {value: 1.0, justification: "ITT 4.1 tightens the tolerance"}
remove_rules: [{id: B, justification: "ITT 2.1: no Y accuracy is contracted"}]
rules:
  - id: A
    override: true
    level: recommended
    justification: "ITT 4.2: X accuracy is advisory"
""",
    )
    p = load_profile(child)
    assert [r.id for r in p.rules] == ["A"]
    assert [(w.id, w.changes, w.justification) for w in p.weakened] == [
        ("B", ("removed",), "ITT 2.1: no Y accuracy is contracted"),
        ("A", ("level mandatory -> recommended",), "ITT 4.2: X accuracy is advisory"),
    ]
    assert p.rule("A").level == "recommended"
    assert p.rule("A").requirement.op == "<="  # inherited keys kept
    assert p.parameters["tol"].value == 1.0 and p.parameters["tol"].unit == "m"
    assert [c[0] for c in p.chain] == ["child", "base"]


def test_extends_pins_the_version(tmp_path):
    write(tmp_path, "base.yaml", BASE)
    child = write(
        tmp_path,
        "child.yaml",
        """\
orthospec_profile: 1
id: child
version: 0.1.0
title: Child
source: {title: ITT}
extends: {id: base, version: 9.9.9}
""",
    )
    with pytest.raises(SpecError, match="unknown profile 'base' version 9.9.9"):
        load_profile(child)


def test_errors_name_file_line_and_column(tmp_path):
    bad = write(
        tmp_path,
        "bad.yaml",
        BASE.replace(
            "scope: block\n    measure: checkpoints.rmse_y",
            "scope: galaxy\n    measure: checkpoints.rmse_y",
        ),
    )
    problems = validate_file(bad)
    assert problems, "a bad scope must be reported"
    text = [str(p) for p in problems]
    assert any("bad.yaml:21:12:" in t and "galaxy" in t for t in text), text


def test_unknown_measure_and_unit_and_expression(tmp_path):
    bad = write(
        tmp_path,
        "bad.yaml",
        BASE.replace("checkpoints.rmse_y", "checkpoints.rmse_q")
        .replace(
            "value: tol, unit: m}\n    consequence: reject_block\n",
            "value: tol, unit: furlongz}\n    consequence: reject_block\n",
            1,
        )
        .replace("value: tol, unit: m}", 'value: "tol + __x", unit: m}'),
    )
    msgs = " | ".join(str(p) for p in validate_file(bad))
    assert "unknown measure 'checkpoints.rmse_q'" in msgs
    assert "furlongz" in msgs
    assert "'_'" in msgs


def test_duplicate_rule_ids_and_duplicate_keys(tmp_path):
    dup = write(tmp_path, "dup.yaml", BASE.replace("  - id: B\n", "  - id: A\n"))
    assert any("duplicate rule id 'A'" in str(p) for p in validate_file(dup))
    dk = write(tmp_path, "dk.yaml", BASE.replace("title: Base\n", "title: Base\ntitle: Again\n"))
    assert any("duplicate key 'title'" in str(p) for p in validate_file(dk))


def test_invalid_yaml_reports_position(tmp_path):
    bad = write(tmp_path, "bad.yaml", "id: [unclosed\n")
    p = validate_file(bad)
    assert p and "invalid YAML" in str(p[0])


def test_unknown_profile_lists_available():
    with pytest.raises(SpecError, match="available:"):
        load_profile("no-such-profile")


def test_published_schemas_are_up_to_date():
    for name, schema in schema_mod.all_schemas().items():
        on_disk = (specs_dir() / "schema" / name).read_text(encoding="utf-8")
        assert on_disk == schema_dumps(schema), f"{name} is stale: run python -m orthospec.schemas"
        jsonschema.Draft202012Validator.check_schema(json.loads(on_disk))


def test_suggestions_for_measures_and_profiles(tmp_path):
    bad = write(tmp_path, "bad.yaml", BASE.replace("checkpoints.rmse_y", "checkpoints.rmse_yy"))
    assert any("did you mean 'checkpoints.rmse_y'" in str(p) for p in validate_file(bad))
    with pytest.raises(SpecError, match="did you mean 'jrc-v3'"):
        load_profile("jrc-v2")


def test_removals_and_overrides_are_recorded_with_their_justification(tmp_path):
    write(tmp_path, "base.yaml", BASE)
    child = write(
        tmp_path,
        "child.yaml",
        """\
orthospec_profile: 1
id: child
version: 0.1.0
title: Child
source: {title: ITT}
extends: {id: base, version: 1.0.0}
remove_rules: [{id: B, justification: "ITT 2.1: no Y accuracy is contracted"}]
rules:
  - id: A
    override: true
    consequence: return_delivery
""",
    )
    p = load_profile(child)
    assert [(x.id, x.justification, x.profile) for x in p.removed] == [
        ("B", "ITT 2.1: no Y accuracy is contracted", "child")
    ]
    assert p.overridden == {"A": ("consequence",)}
    assert p.canonical["removed_rules"][0]["justification"].startswith("ITT 2.1")
    bad = write(
        tmp_path,
        "bad.yaml",
        child.read_text().replace(
            ', justification: "ITT 2.1: no Y accuracy is contracted"', ", justification: ''"
        ),
    )
    assert any("remove_rules/0" in str(x) for x in validate_file(bad))


def test_measure_catalog_is_up_to_date():
    from orthospec.engine import catalog as engine_catalog
    from orthospec.profile import catalog

    on_disk = json.loads(
        (specs_dir() / "schema" / catalog.CATALOG_NAME).read_text(encoding="utf-8")
    )
    assert on_disk == json.loads(json.dumps(engine_catalog.snapshot())), (
        "specs/schema/measures.json is stale: run python -m orthospec.schemas"
    )
    assert catalog.is_current()
