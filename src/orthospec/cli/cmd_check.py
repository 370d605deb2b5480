"""orthospec check: evaluate a delivery against a profile and write the QCRs."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click
from rich.console import Console

from .. import verdicts as V
from ..api import (
    FORMATS,
    CheckOptions,
    CheckResult,
    check,
    default_output_dir,
    refuse_inside_delivery,
    write_outputs,
)
from ..qcr import Output, require_pyarrow
from ..reports.terminal import render as render_terminal
from .groups import main
from .options import (
    allowed_signers_option,
    date_option,
    key_option,
    param_option,
    profile_option,
    split_formats,
)

if TYPE_CHECKING:
    from ..ledger.runs import RecordedRun

@main.command("check")
@click.argument("delivery", type=click.Path(file_okay=False, path_type=Path))
@profile_option
@param_option
@click.option(
    "--out",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for qcr.json, qcr.csv, junit.xml and reports (default reports/<delivery id>); "
    "never inside the delivery.",
)
@click.option(
    "--format",
    "formats",
    default="terminal,json,csv,junit",
    show_default=True,
    help="Comma-separated: " + ", ".join(FORMATS) + ", or a format a plugin adds "
    "(orthospec.formats entry point). parquet needs orthospec[parquet].",
)
@date_option
@click.option(
    "--checker",
    "checker_file",
    type=click.Path(path_type=Path),
    default=None,
    help="The checker's folder (or its checker.yaml alone), outside the delivery: manual-check "
    "verdicts, waivers in force, the checker's check point measurements and inspection grid "
    "(JRC §2 external QC; docs/CHECKER.md). Without it manual rules are missing, the delivery's "
    "own waivers are only requests and its check points are the contractor's internal QC.",
)
@click.option(
    "--fail-on",
    type=click.Choice([V.FAIL, V.WARN]),
    default="fail",
    show_default=True,
    help="'warn' makes recommended-level rules blocking.",
)
@click.option(
    "--operator", default=None, help="Name of the person running the check (recorded in QCRs)."
)
@click.option(
    "--workers",
    type=int,
    default=None,
    help="Worker processes for raster checks (default and maximum: the cores).",
)
@click.option(
    "--scheduler", default=None, metavar="ADDRESS", help="Dask distributed scheduler address."
)
@click.option(
    "--sample",
    "sample_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Sample table from `orthospec sample`: only those images/blocks are checked (JRC §12.3).",
)
@click.option(
    "--max-items",
    type=int,
    default=8,
    show_default=True,
    help="Offending items listed per rule in the terminal (JSON lists all).",
)
@click.option("--verbose", "-v", is_flag=True, help="Show passing rules in the terminal too.")
@click.option(
    "--ledger",
    "ledger_target",
    metavar="PATH|URL",
    default=None,
    help="Record this run in a QCR ledger: SQLite file (e.g. ./orthospec-ledger.sqlite) "
    "or postgresql+psycopg:// URL.",
)
@key_option
@allowed_signers_option
def check_cmd(
    delivery: Path,
    profile: str,
    params: tuple[str, ...],
    out_dir: Path | None,
    formats: str,
    date: str | None,
    fail_on: str,
    operator: str | None,
    workers: int | None,
    scheduler: str | None,
    sample_file: Path | None,
    max_items: int,
    verbose: bool,
    ledger_target: str | None = None,
    checker_file: Path | None = None,
    key: Path | None = None,
    allowed_signers: Path | None = None,
) -> None:
    """Check DELIVERY against a spec profile; exit 0 accepted, 1 rejected, 2 could not evaluate, 3 incomplete.

    Incomplete: nothing rejects the delivery, but the checker's part is not done; the output lists
    what the checker must add."""
    fmts = split_formats(formats, _known_formats(formats))
    if "parquet" in fmts:
        require_pyarrow()  # exit 2 before the check, not after it
    workers = _workers(workers)
    # refuse what would write into the delivery, and a ledger that cannot be used, before the check
    refuse_inside_delivery(
        out_dir if out_dir is not None else Path("reports"),
        delivery,
        what="--out"
        if out_dir is not None
        else "the default output folder (run from outside the delivery or give --out)",
    )
    options = CheckOptions(
        workers=workers,
        scheduler=scheduler,
        progress=sys.stderr.isatty(),
        sample=sample_file,
        checker=checker_file,
        fail_on=fail_on,
        max_items=max_items,
    )
    result = check(
        delivery,
        profile,
        params=params,
        date=date,
        operator=operator,
        options=options,
        ledger=ledger_target,
        allowed_signers=allowed_signers,
    )
    target = (
        out_dir if out_dir is not None else default_output_dir(result.document["delivery"]["id"])
    )
    refuse_inside_delivery(target, delivery, what="output folder")
    out_fmts = [f for f in fmts if f != "terminal"]
    run_id = None
    doc = result.with_maps(out_fmts)
    if ledger_target is None:
        files = result.render(out_fmts, target)
    else:
        written, run_id, display = _record_and_write(
            ledger_target, result, out_fmts, target, key, allowed_signers
        )
        files = sorted(written)
    if "terminal" in fmts:
        console = (
            Console(highlight=False)
            if sys.stdout.isatty()
            else Console(highlight=False, width=120, soft_wrap=False)
        )
        render_terminal(doc, console, max_items=options.max_items, verbose=verbose)
        if files:
            click.echo(f"wrote {', '.join(sorted(files))} to {target}/")
    if run_id is not None:
        click.echo(f"recorded run #{run_id} in ledger {display}")
    click.get_current_context().exit(V.exit_code(doc["verdict"]))


def _known_formats(formats: str) -> tuple[str, ...]:
    """Ours, plus the formats plugins add when a name is not ours (only then are plugins loaded)."""
    asked = {f.strip().lower() for f in formats.split(",") if f.strip()}
    if asked <= set(FORMATS):
        return FORMATS
    from .. import plugins

    return FORMATS + tuple(sorted(plugins.formats()))


def _workers(workers: int | None) -> int | None:
    """``--workers`` at least 1 and at most the cores (more only costs memory)."""
    if workers is None:
        return None
    if workers < 1:
        raise click.BadParameter(f"{workers} workers: give 1 or more", param_hint="'--workers'")
    return min(workers, os.cpu_count() or 1)


def _record_and_write(
    ledger_target: str,
    result: CheckResult,
    fmts: list[str],
    target: Path,
    key: Path | None,
    allowed_signers: Path | None,
) -> tuple[dict[str, Output], int, str]:
    """Record the run and write its outputs in one ledger transaction: the reports print the run's
    own chain entry (the head that includes it, issue 29 item 5), so `ledger verify --against` the
    report catches a chain rebuilt to rewrite this run. Rendering or writing failing records nothing;
    the outputs are written (all or none) before the transaction commits."""
    from ..ledger import open_ledger

    doc = result.document
    reports = "html" in fmts or "pdf" in fmts
    written: dict[str, Output] = {}
    with open_ledger(ledger_target, allowed_signers=allowed_signers) as led:
        history = led.history_before_recording(doc) if reports else None

        def write(run: RecordedRun) -> None:
            shown = None
            if history is not None:
                rows = [{**r, "run": run.id} if r.get("run") == "new" else r for r in history]
                shown = {
                    **doc,
                    "history": rows,
                    "ledger": {
                        "run": run.id,
                        "hash": run.hash,
                        "head": run.hash,
                        "head_seq": run.seq,
                        "problems": [],
                    },
                }
            written.update(result.outputs(fmts, shown=shown))
            write_outputs(target, written)

        run_id = led.record(doc, key=key, before_commit=write)
        r = led.run(run_id)
    trail = f"audit trail {r.audit}"
    if r.continues_run is not None:
        trail += f", continuing run #{r.continues_run}"
    elif not (doc.get("checker") or {}).get("project"):
        trail += " (the manifest's project.id: the checker file's checker.project keys it by the contract)"
    signed = (
        f"signed by {r.signer or 'key'} {r.key_fingerprint}" if r.key_fingerprint else "unsigned"
    )
    return written, run_id, f"{led.display} ({trail}; {signed})"
