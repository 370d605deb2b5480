"""Instant commands (issue 14): `--help`/`--version` import no engine, the lazy table cannot drift."""

from __future__ import annotations

import json
import subprocess
import sys

import click
import pytest
from click.testing import CliRunner

from orthospec.cli import groups
from orthospec.cli.main import cli

HEAVY = (
    "pandas",
    "pint",
    "sqlalchemy",
    "rasterio",
    "weasyprint",
    "numpy",
    "scipy",
    "matplotlib",
    "pydantic",
    "pyarrow",
    "osgeo",
    "dask",
)

PROBE = """
import json, sys
from orthospec.cli.main import main
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
mods = sorted(m for m in sys.modules if m.split('.')[0] in {heavy!r} or m.startswith('orthospec.cli.cmd_'))
print(json.dumps({{"code": code, "modules": mods}}))
"""


def probe(*args: str) -> dict:
    """Run the real entry point in a fresh interpreter; report its exit code and heavy imports."""
    proc = subprocess.run(
        [sys.executable, "-c", PROBE.format(heavy=set(HEAVY)), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize(
    "args", [["--help"], ["--version"], ["spec", "--help"], ["measure", "-h"], ["ledger", "--help"]]
)
def test_help_and_version_import_no_engine(args: list[str]) -> None:
    res = probe(*args)
    assert res["code"] == 0
    assert res["modules"] == [], f"orthospec {' '.join(args)} imported {res['modules']}"


def test_invoking_one_command_imports_only_its_module() -> None:
    res = probe("measure", "accuracy", "--help")
    assert res["code"] == 0
    cmd_modules = [m for m in res["modules"] if m.startswith("orthospec.cli.cmd_")]
    assert cmd_modules == ["orthospec.cli.cmd_measure_accuracy"]


def _registered(group: click.Group) -> dict[str, click.Command]:
    return {n: c for n, c in group.commands.items() if not isinstance(c, click.Group)}


def test_lazy_table_matches_what_the_modules_register() -> None:
    """Every command a ``cmd_*`` module registers is in COMMANDS, under the module that registers
    it and with the first sentence of its own help; and nothing else is."""
    root = cli()  # imports every cmd_* module
    lazy_groups = {
        "main": root,
        **{n: c for n, c in root.commands.items() if isinstance(c, click.Group)},
    }
    assert set(lazy_groups) == set(groups.COMMANDS)
    for gname, group in lazy_groups.items():
        assert isinstance(group, groups.LazyGroup) and group.table == gname
        registered = _registered(group)
        fix = "update the static table orthospec.cli.groups.COMMANDS"
        assert set(registered) == set(groups.COMMANDS[gname]), f"group {gname}: {fix}"
        for name, cmd in registered.items():
            module, first = groups.COMMANDS[gname][name]
            assert cmd.callback is not None
            assert cmd.callback.__module__ == f"orthospec.cli.{module}", f"{gname} {name}: {fix}"
            now = cmd.get_short_help_str(10**6)
            assert click.Command(name, help=first).get_short_help_str(10**6) == now, (
                f"{gname} {name}: help changed, {fix}: {name!r}: ({module!r}, {now!r})"
            )


FRESH_HELP = """
import json, sys
from click.testing import CliRunner
from orthospec.cli.groups import main
res = CliRunner().invoke(main, sys.argv[1:], prog_name="orthospec", terminal_width=80)
print(json.dumps({"code": res.exit_code, "output": res.output,
                  "loaded": sorted(m for m in sys.modules if m.startswith("orthospec.cli.cmd_"))}))
"""


@pytest.mark.parametrize(
    "args", [["--help"], ["spec", "--help"], ["measure", "--help"], ["ledger", "--help"]]
)
def test_lazy_help_equals_help_of_the_loaded_tree(args: list[str]) -> None:
    """`--help` in a fresh process (no command module loaded) prints exactly what the fully
    loaded tree prints: every command, each with its one-line help."""
    proc = subprocess.run(
        [sys.executable, "-c", FRESH_HELP, *args], capture_output=True, text=True, timeout=120
    )
    fresh = json.loads(proc.stdout)
    loaded = CliRunner().invoke(cli(), args, prog_name="orthospec", terminal_width=80)
    assert fresh["code"] == 0 and loaded.exit_code == 0
    assert fresh["loaded"] == []
    assert fresh["output"] == loaded.output
    for name in groups.COMMANDS["main" if args == ["--help"] else args[0]]:
        assert f"\n  {name} " in fresh["output"]


def test_unknown_command_is_a_usage_error() -> None:
    fresh = subprocess.run(
        [sys.executable, "-m", "orthospec.cli.main", "chek"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert fresh.returncode == 2 and "No such command 'chek'" in fresh.stderr


def test_measure_radiometry_help_loads_no_raster_stack() -> None:
    res = probe("measure", "radiometry", "--help")
    assert res["code"] == 0
    assert res["modules"] == ["orthospec.cli.cmd_measure_radiometry"]


def test_explain_words_a_rule_without_importing_the_engine(tmp_path, monkeypatch) -> None:
    """Issue 14: `explain` took 4-5 s because it imported the evaluator for the requirement's
    wording; the wording lives in profile/wording.py and measure names come from the shipped catalog.
    Cold cache (a fresh ORTHOSPEC_CACHE_DIR), so the profile is really validated."""
    monkeypatch.setenv("ORTHOSPEC_CACHE_DIR", str(tmp_path))
    res = probe("explain", "JRC-12.7-RMSEX", "--profile", "jrc-v3")
    assert res["code"] == 0
    # numpy is allowed: a cold validation parses the rules' expressions (profile/expr.py uses it)
    engine = [
        m
        for m in res["modules"]
        if m.split(".")[0]
        in ("pandas", "pint", "rasterio", "scipy", "sqlalchemy", "matplotlib", "weasyprint")
    ]
    assert engine == [], f"explain imported {engine}"


BLAS_PROBE = """
import os, sys
from orthospec.cli.main import main
try:
    main(["--version"])
except SystemExit:
    pass
import numpy as np
a = np.random.default_rng(0).random((300, 300))
_ = a @ a  # OpenBLAS starts its threads on the first product
tasks = os.listdir(f"/proc/{os.getpid()}/task")
print(os.environ.get("OPENBLAS_NUM_THREADS"), len(tasks))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc/<pid>/task is Linux")
@pytest.mark.parametrize("given, expected", [(None, "1"), ("3", "3")])
def test_openblas_threads_are_not_started_beside_ours(given, expected):
    """The CLI sets OPENBLAS_NUM_THREADS=1 unless the user set it: no BLAS worker threads spin
    beside orthospec's own workers (counted from /proc: the process has one thread)."""
    import os

    env = {
        k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")
    }
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    proc = subprocess.run(
        [sys.executable, "-c", BLAS_PROBE], capture_output=True, text=True, timeout=120, env=env
    )
    value, threads = proc.stdout.splitlines()[-1].split()
    assert value == expected
    if given is None:
        assert int(threads) == 1, f"{threads} threads"
