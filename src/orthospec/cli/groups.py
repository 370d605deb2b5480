"""The click groups every command module registers on."""

from __future__ import annotations

import click

from .. import __version__


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="orthospec")
@click.option("--debug", is_flag=True, hidden=True, help="Show tracebacks for internal errors.")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """Check orthoimagery deliveries against spec profiles, clause by clause."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


@main.group()
def spec() -> None:
    """Inspect, validate, compare and render spec profiles."""


@main.group()
def measure() -> None:
    """Standalone measures on one file (accuracy, radiometry, edge)."""


@main.group()
def ledger() -> None:
    """The QCR ledger: audit trail across deliveries."""
