"""The hostile corpus of issue 17, each case a real CLI run in a subprocess with a budget.

Cases run two at a time (the runs are independent processes; the machine has two cores), then
each case is judged on its own; see cases.py for what each must do and check.py for the checks
common to all (no traceback, delivery unchanged, no marker leaked, time and memory budget).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from .cases import CASES
from .check import Outcome, run_case

RESULTS: dict[str, Outcome] = {}


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Outcome]:
    base = tmp_path_factory.mktemp("hostile")

    def one(name: str) -> Outcome:
        return run_case(name, base / name)

    with ThreadPoolExecutor(max_workers=2) as pool:
        for o in pool.map(one, CASES):
            RESULTS[o.name] = o
    return RESULTS


def test_corpus_covers_issue_17() -> None:
    """At least the cases issue 17 lists for this area are present (names are the contract)."""
    required = {
        "image_symlink_outside",
        "document_symlink_outside",
        "table_symlink_to_sparse_3gib_outside",
        "file_column_dotdot",
        "file_column_vsicurl",
        "image_fifo",
        "image_dev_zero",
        "images_are_vrts",
        "seamlines_ogr_vrt",
        "seamlines_gpkg_wal_not_rewritten",
        "out_inside_delivery",
        "cwd_inside_delivery_no_out",
        "id_with_dotdot_default_out",
        "id_absolute_into_delivery",
        "junit_path_is_a_directory",
        "workers_zero",
        "ledger_garbage",
        "rasters_declare_too_much",
        "yaml_alias_bomb_manifest",
        "yaml_alias_bomb_profile",
        "manifest_100mib_string",
        "manifest_date_feb_30",
        "expr_power_tower",
        "expr_huge_power",
        "expr_string_repetition",
        "expr_max_240_args",
        "csv_cell_1gib",
        "csv_million_extra_columns",
        "csv_cell_128kib",
        "csv_header_quoted_newline",
        "file_name_backslash",
    }
    assert required <= set(CASES), sorted(required - set(CASES))


@pytest.mark.parametrize("name", list(CASES))
def test_hostile_case(name: str, outcomes: dict[str, Outcome]) -> None:
    o = outcomes[name]
    assert not o.problems, (
        f"{name}: exit {o.run.exit}, {o.run.seconds:.1f} s, {o.run.peak_mb:.0f} MB: "
        + "; ".join(o.problems)
        + f"\nstderr: {o.run.stderr[-800:]}"
    )


def test_harness_measures_a_hang_and_memory(tmp_path: Path) -> None:
    """The budget is real: a run past its timeout is killed, a run over its memory cap fails."""
    from .cases import World
    from .harness import run_cli

    w = World(tmp_path)
    r = run_cli(w.args(), cwd=w.work, timeout=0.3)
    assert r.timed_out and r.seconds < 5
    r = run_cli(w.args(), cwd=w.work, memory=150 * 2**20)  # numpy + GDAL alone map more
    assert r.exit not in (0, 1, None) and r.seconds < 30
    r = run_cli(["--version"], cwd=w.work)
    assert r.exit == 0 and 5 < r.peak_mb < 600
