"""orthospec init and orthospec verify."""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from .groups import main


@main.command("init")
@click.argument("folder", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--from",
    "source",
    type=click.Path(path_type=Path),
    default=None,
    help="Draft the delivery from this folder of real files (images, tile index, XML metadata, "
    "survey spreadsheets), read in place: nothing is copied or written into it.",
)
@click.option(
    "--profile",
    "-p",
    default=None,
    help="Write only the tables, columns and documents this profile reads (listed in TEMPLATE.md); "
    "with --from, the profile TODO.md names the rules of (default jrc-v3).",
)
@click.option(
    "--sensor",
    type=click.Choice(["aerial", "satellite"]),
    default=None,
    help="Sensor type (template default: aerial; with --from only when no metadata states it).",
)
@click.option(
    "--id",
    "ident",
    default=None,
    help="With --from: the delivery's identifier, when no metadata file states one.",
)
@click.option(
    "--blocks",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="With --from: a vector file of the block outlines (an id attribute per polygon); images and "
    "points are assigned to blocks by location.",
)
@click.option(
    "--mapping",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="With --from: survey layouts to apply (a draft's ingest/points-mapping.yaml, or one written "
    "for a layout init could not decide).",
)
@click.option(
    "--no-sha256", is_flag=True, help="With --from: do not hash the images (header facts only)."
)
@click.option(
    "--workers", type=int, default=None, help="With --from: worker processes (default: CPU count)."
)
def init_cmd(
    folder: Path,
    source: Path | None,
    profile: str | None,
    sensor: str | None,
    ident: str | None,
    blocks: Path | None,
    mapping: Path | None,
    no_sha256: bool,
    workers: int | None,
) -> None:
    """Write a commented delivery template (delivery.yaml, table headers, TEMPLATE.md) into FOLDER.

    With --from SOURCE: draft the delivery from the real files instead (delivery.yaml, tables/, TODO.md,
    INGEST.md); `orthospec check FOLDER` runs on it as it is.

    Examples: orthospec init my-delivery --profile jrc-v3 --sensor satellite;
    orthospec init draft --from /media/disk/lot3
    """
    if source is None:
        if blocks or mapping or no_sha256 or workers or ident:
            raise click.UsageError(
                "--id, --blocks, --mapping, --no-sha256 and --workers go with --from SOURCE"
            )
        from ..profile.template import write_template

        for p in write_template(folder, profile=profile, sensor=sensor or "aerial"):
            click.echo(f"wrote {p}")
        return
    from ..ingest import Options, make_draft

    bar = _Bar()
    try:
        draft = make_draft(
            folder,
            [source],
            Options(
                profile=profile or "jrc-v3",
                sensor=sensor,
                ident=ident,
                blocks=blocks,
                mapping=mapping,
                sha256=not no_sha256,
                workers=workers,
                progress=bar,
            ),
        )
    finally:
        bar.close()
    click.echo(
        f"drafted {folder} from {source}: {draft.images} images"
        + (f", {len(draft.unreadable)} unreadable (INGEST.md)" if draft.unreadable else "")
        + f"; {draft.todo} TODO entries, {draft.missing_rules} rules `missing` until they are filled (TODO.md)"
    )
    click.echo(f"next: orthospec check {folder} --profile {profile or 'jrc-v3'} --checker CHECKER")


class _Bar:
    """Progress of the image scan on stderr: a rich bar on a terminal, a line per tenth otherwise."""

    def __init__(self) -> None:
        import sys

        self.stream = sys.stderr
        self.rich: object = None
        self.task: object = None
        self.shown = -1

    def __call__(self, done: int, total: int) -> None:
        if self.rich is None and self.stream.isatty():
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )

            self.rich = Progress(
                TextColumn("reading images"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeRemainingColumn(),
                transient=True,
            )
            self.rich.start()
            self.task = self.rich.add_task("scan", total=total)
        if self.rich is not None:
            self.rich.update(self.task, completed=done)  # type: ignore[attr-defined]
            return
        tenth = done * 10 // max(total, 1)
        if tenth != self.shown and (tenth > self.shown):
            self.shown = tenth
            print(f"reading images: {done}/{total}", file=self.stream, flush=True)

    def close(self) -> None:
        if self.rich is not None:
            self.rich.stop()  # type: ignore[attr-defined]


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
            t.add_row(
                escape(f"{o.name}: {exp.what}"),
                escape(str(exp.expected)),
                escape(str(exp.got)),
                "[green]ok[/]" if ok else "[bold red]MISMATCH[/]",
            )
    Console(highlight=False).print(t)
    n = sum(len(o.checks) for o in outcomes)
    click.echo(f"{n - bad} of {n} expectations met in {len(outcomes)} test deliveries")
    if not outcomes:
        click.echo("the profile declares no tests: add `tests:` with delivery, params and expect")
    click.get_current_context().exit(1 if bad else 0)
