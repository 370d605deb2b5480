"""The click groups every command module registers on, loaded lazily.

Why lazy: the command modules import the engine (pandas, pint, SQLAlchemy, rasterio,
WeasyPrint); importing them all up front cost more than a second before even ``--help`` could
print. Each group therefore knows its commands by name from the static table ``COMMANDS``
(name -> the ``cmd_*`` module that registers it, and its one-line help) and imports a module
only when one of its commands is invoked. ``--help`` and ``--version`` import none of them.
``tests/test_cli_startup.py`` checks that the table matches what the modules register, so it
cannot drift.
"""

from __future__ import annotations

import importlib

import click

from .. import __version__

# group name -> {command name: (module in orthospec.cli, first sentence of the command's help)}
COMMANDS: dict[str, dict[str, tuple[str, str]]] = {
    "main": {
        "check": (
            "cmd_check",
            "Check DELIVERY against a spec profile; exit 0 accepted, 1 rejected, "
            "2 could not evaluate, 3 incomplete.",
        ),
        "diff": (
            "cmd_ledger",
            "What changed between two runs per rule and item: fixed, newly failing, still failing.",
        ),
        "explain": ("cmd_profiles", "Clause, quote, requirement and the evidence a rule reads."),
        "history": (
            "cmd_ledger",
            "Deliveries, redeliveries and their verdicts over time, per rule and per block.",
        ),
        "init": (
            "cmd_init",
            "Write a commented delivery template (delivery.yaml, table headers, "
            "TEMPLATE.md) into FOLDER.",
        ),
        "measures": (
            "cmd_profiles",
            "List the measures rules may read (besides the generic <table>.<column> ones).",
        ),
        "profiles": (
            "cmd_profiles",
            "List shipped profiles (and those in PATHS: files or folders) with version.",
        ),
        "report": (
            "cmd_report",
            "Render the auditor's report (HTML, archival PDF/A-3b) from a "
            "stored QCR_JSON or a ledger run.",
        ),
        "sample": (
            "cmd_sample",
            "Select images or blocks for external QC: systematic spread, every "
            "tag, problem batches, random part.",
        ),
        "signoff": ("cmd_ledger", "Countersign RUN (JRC §2.4) and record manual-check verdicts."),
        "verify": (
            "cmd_init",
            "Run a profile's own test deliveries against the verdicts they expect, per rule.",
        ),
    },
    "spec": {
        "diff": (
            "cmd_profiles",
            "What changed from profile A to profile B: rules and thresholds "
            "added, removed, changed.",
        ),
        "render": (
            "cmd_report",
            "Render PROFILE as the technical-specification annex of an invitation to tender.",
        ),
        "show": ("cmd_profiles", "Print the resolved profile (extends applied) and its SHA-256."),
        "validate": (
            "cmd_profiles",
            "Validate profile FILES (schema, models, units, expressions, "
            "measures); exit 2 on problems.",
        ),
    },
    "measure": {
        "accuracy": (
            "cmd_measure_accuracy",
            "RMSE, NSSDA, CE90/CE95, bias test and blunder screening of checkpoint discrepancies.",
        ),
        "checkpoints": (
            "cmd_measure_checkpoints",
            "Measure surveyed check points on the delivered "
            "orthoimages by subpixel image matching.",
        ),
        "edge": (
            "cmd_measure_edge",
            "Measure RER, FWHM, MTF at Nyquist and effective resolution on an edge target.",
        ),
        "radiometry": (
            "cmd_measure_radiometry",
            "Exact per-band statistics, histograms and JRC "
            "§6.3 measures plus file checks of IMAGE.",
        ),
    },
    "checker": {
        "init": (
            "cmd_checker",
            "Write the checker folder's skeleton for DELIVERY: ITT values to state and "
            "every manual check item to judge.",
        ),
    },
    "inspect": {
        "grid": (
            "cmd_inspect",
            "Write the inspection grid (GeoPackage) over the sampled images of "
            "DELIVERY into the checker's folder.",
        ),
    },
    "ledger": {
        "runs": ("cmd_ledger", "List recorded runs (oldest first)."),
        "state": (
            "cmd_ledger",
            "Normal/Tightened audit state per QCR family of PROJECT (JRC §2.3) "
            "and the next sample share.",
        ),
        "verify": (
            "cmd_ledger",
            "Check the hash chain: exit 0 when intact, 1 (TAMPERED) listing "
            "every edited or deleted row.",
        ),
    },
}


class LazyGroup(click.Group):
    """A click group whose commands come from ``COMMANDS[table]`` and load on first use."""

    def __init__(self, *args: object, table: str, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.table = table

    @property
    def lazy(self) -> dict[str, tuple[str, str]]:
        return COMMANDS[self.table]

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(self.commands) | set(self.lazy))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in self.lazy:
            importlib.import_module(f"{__package__}.{self.lazy[cmd_name][0]}")
            if cmd_name not in self.commands:  # the table lies: a bug, say which entry
                raise RuntimeError(
                    f"orthospec.cli.groups.COMMANDS[{self.table!r}][{cmd_name!r}]: "
                    f"module {self.lazy[cmd_name][0]} does not register it"
                )
        return self.commands.get(cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list from the table (no command module imported), click's layout."""
        rows: list[tuple[str, click.Command]] = []
        for name in self.list_commands(ctx):
            cmd = self.commands.get(name) or click.Command(name, help=self.lazy[name][1])
            if not cmd.hidden:
                rows.append((name, cmd))
        if rows:
            limit = formatter.width - 6 - max(len(name) for name, _ in rows)
            with formatter.section("Commands"):
                formatter.write_dl([(name, cmd.get_short_help_str(limit)) for name, cmd in rows])


@click.group(
    cls=LazyGroup,
    table="main",
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)
@click.version_option(__version__, prog_name="orthospec")
@click.option("--debug", is_flag=True, hidden=True, help="Show tracebacks for internal errors.")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """Check orthoimagery deliveries against spec profiles, clause by clause."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


@main.group(cls=LazyGroup, table="spec")
def spec() -> None:
    """Inspect, validate, compare and render spec profiles."""


@main.group(cls=LazyGroup, table="measure")
def measure() -> None:
    """Standalone measures on one file (accuracy, radiometry, edge) and check points on a delivery."""


@main.group(cls=LazyGroup, table="checker")
def checker() -> None:
    """The external QC's own folder (checker.yaml, its measurements, its inspection grid)."""


@main.group(cls=LazyGroup, table="inspect")
def inspect() -> None:
    """The checker's visual inspection of the delivered images (JRC Table 6, §6.3)."""


@main.group(cls=LazyGroup, table="ledger")
def ledger() -> None:
    """The QCR ledger: audit trail across deliveries."""
