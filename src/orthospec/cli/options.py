"""Options shared by several commands."""

from __future__ import annotations

import click

profile_option = click.option(
    "--profile", "-p", "profile", required=True, metavar="ID|PATH",
    help="Spec profile id (see `orthospec profiles`) or path to a profile YAML.")
date_option = click.option(
    "--date", metavar="YYYY-MM-DD", default=None,
    help="Date recorded in the QCRs (default today); fix it for byte-identical output.")
param_option = click.option(
    "--param", "params", multiple=True, metavar="NAME=VALUE",
    help="Set a profile parameter, e.g. --param tolerance_xy=0.5m (repeatable).")


def split_formats(value: str, allowed: tuple[str, ...]) -> list[str]:
    fmts = [f.strip().lower() for f in value.split(",") if f.strip()]
    bad = [f for f in fmts if f not in allowed]
    if bad:
        raise click.BadParameter(f"unknown format(s) {', '.join(bad)}; choose from {', '.join(allowed)}")
    return fmts
