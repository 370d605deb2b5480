"""The library's result is complete without the CLI (issue 28 item 1): ``api.check`` gives the
``sample`` block and the ledger head the CLI writes, and ``CheckResult.render`` writes the same files
as ``orthospec check``, byte for byte."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from orthospec import api
from orthospec.cli.main import cli
from orthospec.errors import OrthospecError

PARAMS = ["tolerance_xy=0.5"]
SAMPLE = "item,scope,reason,seed,round\nI1,image,random,1,0\nI3,image,random,1,0\n"


def _cli(*args: object) -> str:
    res = CliRunner().invoke(cli(), [str(a) for a in args])
    assert res.exit_code in (0, 1, 3), res.output
    return res.output


def test_library_document_equals_the_cli_qcr_json_with_sample_and_ledger(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    root = make_delivery()
    sample = tmp_path / "s.csv"
    sample.write_text(SAMPLE, encoding="utf-8")
    _cli(
        "check",
        root,
        "-p",
        mini_profile,
        "--sample",
        sample,
        "--ledger",
        tmp_path / "cli.sqlite",
        "--out",
        tmp_path / "cli",
        "--date",
        "2026-01-01",
        "--format",
        "json,csv,junit",
        "--param",
        PARAMS[0],
    )
    result = api.check(
        root,
        mini_profile,
        params=PARAMS,
        date="2026-01-01",
        options=api.CheckOptions(sample=sample),
        ledger=tmp_path / "lib.sqlite",
    )
    # independent of the library: the block as the schema documents it, the head of an empty chain
    assert result.document["sample"] == {
        "kind": "image",
        "items": ["I1", "I3"],
        "statement": f"sample of 2 of {len(result.evaluation.delivery.table('images').df)} images "
        "(file s.csv, JRC §12.3)",
    }
    assert result.document["ledger_head"]["seq"] == 0
    written = result.render(["json", "csv", "junit"], tmp_path / "lib")
    assert sorted(written) == ["junit.xml", "qcr.csv", "qcr.json"]
    for name in written:
        assert (tmp_path / "lib" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), (
            name
        )


def test_library_without_sample_or_ledger_has_neither_block(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    result = api.check(make_delivery(), mini_profile, params=PARAMS, date="2026-01-01")
    assert "sample" not in result.document and "ledger_head" not in result.document
    result.render(["json"], tmp_path / "o")
    assert "sample" not in json.loads((tmp_path / "o" / "qcr.json").read_text(encoding="utf-8"))


def test_render_refuses_a_folder_inside_the_delivery(make_delivery, mini_profile) -> None:
    root = make_delivery()
    result = api.check(root, mini_profile, params=PARAMS, date="2026-01-01")
    with pytest.raises(OrthospecError):
        result.render(["json"], Path(root) / "out")
    assert not (Path(root) / "out").exists()


@pytest.mark.parametrize("as_object", [False, True])
def test_a_ledger_inside_the_delivery_is_refused_however_the_delivery_is_given(
    make_delivery, mini_profile, as_object: bool
) -> None:
    """Given as a path or as an opened Delivery, a ledger file inside the delivery is refused before
    anything is created (orthospec never writes into a delivery)."""
    from orthospec.delivery.reader import open_delivery

    root = Path(make_delivery())
    target = open_delivery(root) if as_object else root
    with pytest.raises(OrthospecError, match="inside the delivery"):
        api.check(target, mini_profile, params=PARAMS, date="2026-01-01", ledger=root / "ledger.sqlite")
    assert not (root / "ledger.sqlite").exists()


def test_sample_given_as_ids_has_a_statement_without_a_file(make_delivery, mini_profile) -> None:
    result = api.check(
        make_delivery(),
        mini_profile,
        params=PARAMS,
        date="2026-01-01",
        options=api.CheckOptions(sample=("image", {"I1"})),
    )
    assert result.document["sample"]["statement"].endswith("images (JRC §12.3)")
    assert result.document["sample"]["items"] == ["I1"]
