"""orthospec checker init: the checker folder's skeleton (issue 29 item 4; engine/skeleton.py)."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import OrthospecError
from .groups import checker
from .options import profile_option


@checker.command("init")
@click.argument("delivery", type=click.Path(file_okay=False, path_type=Path))
@profile_option
@click.option(
    "--out",
    "out",
    type=click.Path(path_type=Path),
    required=True,
    metavar="CHECKER_DIR",
    help="The checker folder to write (outside the delivery); its checker.yaml must not exist yet.",
)
@click.option("--name", default=None, help="The checker's name (else left for you to fill in).")
def init_cmd(delivery: Path, profile: str, out: Path, name: str | None) -> None:
    """Write the checker folder's skeleton for DELIVERY: ITT values to state and every manual check item to judge.

    CHECKER_DIR/checker.yaml lists the ITT parameters PROFILE leaves open, the files the delivery uses
    (pinned with their SHA-256 and role) and every manual check item the profile applies to this
    delivery, an image's with its file and SHA-256; fill in the verdicts, then
    `orthospec check DELIVERY --profile PROFILE --checker CHECKER_DIR`.

    Example: orthospec checker init examples/deliveries/satellite-pass -p jrc-v3 --out qc-checker
    """
    from ..api import refuse_inside_delivery, write_outputs
    from ..delivery.checker import CHECKER_FILE
    from ..delivery.reader import open_delivery
    from ..engine.skeleton import checker_skeleton
    from ..profile.loader import load_profile

    refuse_inside_delivery(out, delivery, what="--out")
    if (out / CHECKER_FILE).exists():
        raise OrthospecError(
            f"{out / CHECKER_FILE} exists: a checker's file is never overwritten; choose "
            "another --out or remove it"
        )
    d = open_delivery(delivery)
    d.load_all_tables()
    sk = checker_skeleton(load_profile(profile), d, name=name)
    write_outputs(out, {CHECKER_FILE: sk.text})
    files = sum(1 for e in sk.entries if "file" in e)
    click.echo(
        f"wrote {out / CHECKER_FILE}: {len(sk.entries)} manual check items to judge ({files} bound to "
        f"an image's SHA-256), {len(sk.pins)} files pinned, {len(sk.open_parameters)} ITT parameters "
        "to state"
    )
