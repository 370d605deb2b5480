"""`orthospec measures` says what each measure is (issue 13 item 8), on one uncut line per measure."""

from __future__ import annotations

import re

from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.engine.catalog import known_measures
from orthospec.engine.registry import MEASURE_DESCRIPTIONS, ROLLUP, describe


def test_every_registered_measure_has_a_description() -> None:
    names = set(known_measures()) | set(ROLLUP)
    missing = sorted(n for n in names if not describe(n).strip())
    assert not missing, f"add a line to engine/registry.py MEASURE_DESCRIPTIONS for: {missing}"
    assert all("\n" not in d and len(d) <= 110 for d in MEASURE_DESCRIPTIONS.values())


def test_the_ce90_family_is_distinguishable() -> None:
    d = {n: describe(f"checkpoints.{n}") for n in ("ce90", "ce90_empirical", "ce90_selected")}
    assert len(set(d.values())) == 3
    assert (
        "percentile" in d["ce90_empirical"]
        and "model" in d["ce90"]
        and "bias" in d["ce90_selected"]
    )


def test_measures_command_prints_each_description_uncut() -> None:
    res = CliRunner().invoke(cli(), ["measures"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    for name in (*known_measures(), *ROLLUP):
        row = [ln for ln in lines if re.match(rf"\s*{re.escape(name)}\s", ln)]
        assert len(row) == 1, name
        assert row[0].rstrip().endswith(describe(name)), row[0]  # whole, on the measure's own line
    assert "…" not in res.output
