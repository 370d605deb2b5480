"""Shared fixtures: small real deliveries written into tmp_path, the repository's folders."""

from __future__ import annotations

import os
import shutil
import signal
import sys
import tempfile
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
SEEDS = ROOT.parent / "shared" / "seeds"
REAL = ROOT.parent / "shared" / "data" / "real"
EXAMPLES = ROOT / "examples" / "deliveries"



# Resolved-profile cache of the test run: never the user's ~/.cache/orthospec. Made once, by the
# first process (xdist workers and the CLI subprocesses inherit it), and removed by that process.
_OWN_CACHE: str | None = None
if "ORTHOSPEC_CACHE_DIR" not in os.environ:
    _OWN_CACHE = os.environ["ORTHOSPEC_CACHE_DIR"] = tempfile.mkdtemp(
        prefix="orthospec-test-cache-"
    )


def _terminated(signum: int, frame: object) -> None:
    """SIGTERM (a CI timeout, `kill`) ends the run like Ctrl-C: pytest unwinds, so the cache above and
    the PostgreSQL server of tests/pg.py (atexit) are removed instead of left in the temp folder."""
    raise KeyboardInterrupt(f"signal {signum}")


if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
    signal.signal(signal.SIGTERM, _terminated)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """`opt_in` tests (minutes long) are deselected, not skipped, unless ORTHOSPEC_SLOW_TESTS=1."""
    if os.environ.get("ORTHOSPEC_SLOW_TESTS") == "1":
        return
    keep = [i for i in items if i.get_closest_marker("opt_in") is None]
    if len(keep) != len(items):
        config.hook.pytest_deselected(items=[i for i in items if i.get_closest_marker("opt_in")])
        items[:] = keep


def pytest_configure(config: pytest.Config) -> None:
    """Print the mutation suite's coverage line in the summary (controller side, also under xdist)."""
    if not hasattr(config, "workerinput"):
        from mutation_coverage import PLUGIN_NAME, CoverageReport

        config.pluginmanager.register(CoverageReport(), PLUGIN_NAME)


@pytest.fixture(scope="session", autouse=True)
def _postgres_ends_with_the_session() -> Iterator[None]:
    """The PostgreSQL server of tests/pg.py, if this process started one, is stopped and its folder
    removed after the process's last test, not at exit: xdist kills a worker still busy 10 s after
    its last test, which left a half-deleted data folder in the temp folder."""
    yield
    pg = sys.modules.get("pg")
    if pg is not None:
        pg.stop_server()


def pytest_unconfigure(config: pytest.Config) -> None:
    """The test run's profile cache goes with the process that made it (no folder left in /tmp)."""
    if _OWN_CACHE is not None and not hasattr(config, "workerinput"):
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)


def _strict(report: pytest.TestReport | pytest.CollectReport) -> None:
    """With ORTHOSPEC_STRICT_SKIPS=1 (set by .ci/run) a skip fails: CI must not pass on a machine
    that lacks what a test needs (../shared, gdalinfo, PostgreSQL, distributed, pyarrow)."""
    if (
        report.skipped
        and os.environ.get("ORTHOSPEC_STRICT_SKIPS") == "1"
        and not hasattr(report, "wasxfail")
    ):
        reason = report.longrepr[-1] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped under ORTHOSPEC_STRICT_SKIPS=1 (CI): {reason}"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A test that skips itself (``pytest.skip``, ``importorskip`` inside it, a skip marker)."""
    outcome = yield
    _strict(outcome.get_result())


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """A module that skips itself while being collected (a module-level ``importorskip``)."""
    outcome = yield
    _strict(outcome.get_result())


MANIFEST = """\
orthospec_delivery: 1
id: D1
project: {id: P1, name: Test project, crs: "EPSG:25832"}
contractor: {name: ACME Mapping}
operator: {name: Jane Doe}
sensor: {type: aerial, digital: true}
product: {gsd: {value: 0.25, unit: m}}
tender: {reference: ITT-1, parameters: {tolerance_xy: {value: 0.5, unit: m}}}
blocks: [{id: B1}, {id: B2}]
tables: {images: tables/images.csv, manual_checks: tables/manual.csv}
waivers: [{rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}]
"""
IMAGES = """\
image_id,file,block,roll,flying_height,std_dn
I1,images/i1.tif,B1,0.5,1000,30
I2,images/i2.tif,B1,2.5,,40
I3,images/i3.tif,B2,4,1100,20
"""
MANUAL = """\
check,item,inspector,date,verdict
R-VIS,*,Joe Bloggs,2026-01-01,pass
"""


@pytest.fixture
def mini_profile() -> Path:
    return DATA / "profiles" / "mini.yaml"


@pytest.fixture
def make_delivery(tmp_path: Path) -> Callable[..., Path]:
    """Write a small delivery; keyword args replace the manifest or a table's text."""

    def make(
        name: str = "d",
        *,
        manifest: str = MANIFEST,
        images: str | None = IMAGES,
        manual: str | None = MANUAL,
        extra: dict[str, str] | None = None,
    ) -> Path:
        root = tmp_path / name
        (root / "tables").mkdir(parents=True)
        (root / "delivery.yaml").write_text(textwrap.dedent(manifest), encoding="utf-8")
        if images is not None:
            (root / "tables" / "images.csv").write_text(images, encoding="utf-8")
        if manual is not None:
            (root / "tables" / "manual.csv").write_text(manual, encoding="utf-8")
        for rel, text in (extra or {}).items():
            (root / rel).parent.mkdir(parents=True, exist_ok=True)
            (root / rel).write_text(text, encoding="utf-8")
        return root

    return make


@pytest.fixture
def example_copy(tmp_path: Path) -> Callable[[str], Path]:
    def copy(name: str) -> Path:
        dst = tmp_path / name
        shutil.copytree(EXAMPLES / name, dst)
        return dst

    return copy
