"""A profile error never names the folder orthospec is installed in (issue 28 item 7).

A tender rule that reads an inherited parameter in a unit it cannot meet is reported at the
parameter's definition, which lives in the shipped profile: the message names it as
``specs/jrc-v3.yaml:LINE:COL``, the way the documentation does, not by an absolute path that
differs between machines and says nothing to a tender author.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from orthospec.cli.main import main
from orthospec.resources import shown, specs_dir

TENDER = """\
orthospec_profile: 1
id: t-paths
version: 1.0.0
title: x
source: {title: x, identifier: x}
extends: {id: jrc-v3, version: 3.0.0}
rules:
  - id: ITT-1
    title: x
    clause: {document: x, section: "1"}
    quote: "x"
    scope: delivery
    measure: manifest.sensor.digital
    requirement: {op: "<=", value: tolerance_xy * 2, unit: "deg"}
    consequence: return_delivery
"""


def test_shipped_files_are_named_relative_to_the_install() -> None:
    assert shown(specs_dir() / "jrc-v3.yaml") == "specs/jrc-v3.yaml"
    assert shown("tender.yaml") == "tender.yaml"  # the user's own path stays as typed


def test_error_located_in_a_shipped_profile_names_no_install_path(
    tmp_path: Path, monkeypatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    Path("tender.yaml").write_text(TENDER, encoding="utf-8")
    with pytest.raises(SystemExit) as exc:
        main(["spec", "validate", "tender.yaml"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "parameter tolerance_xy" in err and "tender.yaml:14" in err  # the problem is reported...
    line = next(
        n
        for n, t in enumerate((specs_dir() / "jrc-v3.yaml").read_text().splitlines(), 1)
        if t.startswith("  tolerance_xy:")
    )
    at = re.search(r"specs/jrc-v3\.yaml:(\d+):\d+: parameter tolerance_xy", err)
    assert at and line <= int(at[1]) <= line + 3, (
        err
    )  # ...at the shipped parameter, named as the docs do
    assert str(specs_dir()) not in err and str(specs_dir().resolve()) not in err
