"""orthospec init and orthospec verify."""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ..spec.template import write_template
from .groups import main


@main.command("init")
@click.argument("folder", type=click.Path(file_okay=False, path_type=Path))
@click.option("--profile", "-p", default=None,
              help="Write only the tables, columns and documents this profile reads (listed in TEMPLATE.md).")
@click.option("--sensor", type=click.Choice(["aerial", "satellite"]), default="aerial", show_default=True)
def init_cmd(folder: Path, profile: str | None, sensor: str) -> None:
    """Write a commented delivery template (delivery.yaml, table headers, TEMPLATE.md) into FOLDER.

    Example: orthospec init my-delivery --profile jrc-v3 --sensor satellite
    """
    for p in write_template(folder, profile=profile, sensor=sensor):
        click.echo(f"wrote {p}")


@main.command("verify")
@click.argument("profile")
def verify_cmd(profile: str) -> None:
    """Run a profile's own test deliveries against the verdicts they expect, per rule."""
    from ..verify import verify_profile

    outcomes = verify_profile(profile)
    t = Table("test", "expected", "got", "result", box=None, header_style="bold")
    bad = 0
    for o in outcomes:
        for exp in o.checks:
            ok = exp.expected == exp.got
            bad += not ok
            t.add_row(escape(f"{o.name}: {exp.what}"), escape(str(exp.expected)), escape(str(exp.got)),
                      "[green]ok[/]" if ok else "[bold red]MISMATCH[/]")
    Console(highlight=False).print(t)
    n = sum(len(o.checks) for o in outcomes)
    click.echo(f"{n - bad} of {n} expectations met in {len(outcomes)} test deliveries")
    if not outcomes:
        click.echo("the profile declares no tests: add `tests:` with delivery, params and expect")
    click.get_current_context().exit(1 if bad else 0)
