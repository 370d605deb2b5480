"""Options shared by several commands."""

from __future__ import annotations

from pathlib import Path

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

#: the ledger's keys (ledger/signing.py): the signer's SSH key and the buyer's allowed-signers register
key_option = click.option(
    "--key",
    "key",
    type=click.Path(dir_okay=False, path_type=Path),
    envvar="ORTHOSPEC_SIGNING_KEY",
    default=None,
    help="SSH private key (or the .pub of a key in ssh-agent) that signs the ledger entry "
    "(default $ORTHOSPEC_SIGNING_KEY); the signer is that key.",
)
allowed_signers_option = click.option(
    "--allowed-signers",
    "allowed_signers",
    type=click.Path(dir_okay=False, path_type=Path),
    envvar="ORTHOSPEC_ALLOWED_SIGNERS",
    default=None,
    help="ssh-keygen allowed-signers file naming each key's owner (default $ORTHOSPEC_ALLOWED_SIGNERS); "
    "when set, every ledger entry must be signed by a key listed in it.",
)


def split_formats(value: str, allowed: tuple[str, ...]) -> list[str]:
    fmts = [f.strip().lower() for f in value.split(",") if f.strip()]
    bad = [f for f in fmts if f not in allowed]
    if bad:
        raise click.BadParameter(
            f"unknown format(s) {', '.join(bad)}; choose from {', '.join(allowed)}"
        )
    return fmts
