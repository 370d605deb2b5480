"""qcr.schema.json is generated from the pydantic QCR model and every example's qcr.json passes it
(issue 15 item 4, issue 14 "still passes its schema")."""

from __future__ import annotations

import json

import jsonschema
import pytest
from pydantic import ValidationError
from tests.checking import EXAMPLES, ROOT

from orthospec import api
from orthospec.profile import schema as schema_mod
from orthospec.qcr import dumps
from orthospec.qcr_model import QcrDocument, qcr_schema

COMMITTED = ROOT / "specs" / "schema" / "qcr.schema.json"


def test_committed_schema_is_the_generated_one() -> None:
    assert COMMITTED.read_text(encoding="utf-8") == schema_mod.dumps(qcr_schema()), (
        "specs/schema/qcr.schema.json is stale: run `python -m orthospec.profile.schema`")
    jsonschema.Draft202012Validator.check_schema(json.loads(COMMITTED.read_text(encoding="utf-8")))


@pytest.mark.parametrize("name", ["aerial-pass", "aerial-fail"])
def test_example_documents_pass_the_schema_and_the_model(name: str) -> None:
    checker = ROOT / "examples" / "checker" / name
    res = api.check(EXAMPLES / name, "jrc-v3", date="2026-11-21",
                    checker=checker if checker.exists() else None)
    doc = json.loads(dumps(res.document))  # what is on disk, not the dict in memory
    jsonschema.validate(doc, json.loads(COMMITTED.read_text(encoding="utf-8")))
    model = QcrDocument.model_validate(doc)
    assert model.summary.records == doc["summary"]["records"]


def test_the_schema_refuses_what_the_writer_never_writes() -> None:
    res = api.check(EXAMPLES / "aerial-fail", "jrc-v3", date="2026-11-21",
                    checker=ROOT / "examples" / "checker" / "aerial-fail")
    doc = json.loads(dumps(res.document))
    schema = json.loads(COMMITTED.read_text(encoding="utf-8"))
    bad = json.loads(json.dumps(doc))
    bad["records"][0]["verdict"] = "passed"
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, schema)
    with pytest.raises(ValidationError):
        QcrDocument.model_validate(bad)
    bad = json.loads(json.dumps(doc))
    block = next(iter(bad["compact"].values()))
    block["verdict"] = {"all": "fail"}  # a failure is never compact: it must be a record in full
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, schema)
    bad = json.loads(json.dumps(doc))
    bad["evidence"][0]["sha256"] = "not-a-hash"
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, schema)
