"""orthospec sample: draw the external-QC sample (JRC §12.4, §12.8) reproducibly from a seed."""

from __future__ import annotations

from pathlib import Path

import click

from ..delivery.reader import open_delivery
from ..engine.sample import draw
from ..outputs import atomic_write
from ..profile.loader import load_profile
from .groups import main


@main.command("sample")
@click.argument("delivery", type=click.Path(file_okay=False, path_type=Path))
@click.option("--profile", "-p", "profile", default="jrc-v3", show_default=True,
              help="Profile whose sample_fraction parameter sets the size (10 % when absent).")
@click.option(
    "--seed", type=int, required=True, help="Seed: the same seed and round give the same sample."
)
@click.option(
    "--round",
    "round_",
    type=int,
    default=0,
    show_default=True,
    help="Redelivery round: each round draws a new sample (it may include earlier items).",
)
@click.option("--scope", type=click.Choice(["image", "block"]), default="image", show_default=True)
@click.option(
    "--fraction", type=float, default=None, help="Share of items to draw (overrides the profile)."
)
@click.option("--minimum", type=int, default=1, show_default=True, help="Smallest sample size.")
@click.option(
    "--ledger",
    "ledger_url",
    default=None,
    metavar="PATH|URL",
    help="QCR ledger: a tightened audit state (JRC Tables 6, 10) draws a larger sample and "
    "adds every suspect item of the tightened families.",
)
@click.option(
    "--checker",
    "checker_file",
    type=click.Path(path_type=Path),
    default=None,
    help="With --ledger: the checker's file or folder; the contract / project it states "
    "(checker.project) names the audit trail, not the manifest's project.id.",
)
@click.option(
    "--family",
    "families",
    multiple=True,
    help="Audit families to consult in the ledger (default: all of the project's).",
)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="CSV to write (default sample-<scope>-r<round>.csv); give it to `check --sample`.",
)
def sample_cmd(
    delivery: Path,
    profile: str,
    seed: int,
    round_: int,
    scope: str,
    fraction: float | None,
    minimum: int,
    ledger_url: str | None,
    families: tuple[str, ...],
    out: Path | None,
    checker_file: Path | None = None,
) -> None:
    """Select images or blocks for external QC: systematic spread, every tag, problem batches, random part.

    Example: orthospec sample examples/deliveries/aerial-pass --seed 7 --out sample.csv
    """
    d = open_delivery(delivery)
    d.load_all_tables()
    prof = load_profile(profile)
    if fraction is None:
        fraction = _profile_fraction(prof, "sample_fraction", 0.10)
    if not 0 < fraction <= 1:
        raise click.BadParameter(f"fraction must be in (0, 1], got {fraction}")
    suspects: set[str] = set()
    state = "normal"
    if ledger_url is not None:
        from ..ledger import TIGHTENED, open_ledger

        stated = None
        if checker_file is not None:
            from ..delivery.checker import load_checker

            stated = load_checker(checker_file, delivery_root=d.root).party.project
        with open_ledger(ledger_url, create=False) as led:
            # the audit trail: what the checker states, else the earlier run whose content this
            # delivery continues, else the manifest's project id (issue 25 item 6)
            trail = led.audit_key_for(stated, d.project_id, (f["sha256"] for f in d.files))
            states = led.audit_states(trail)
            chosen = {f: st for f, st in states.items() if not families or f in families}
            tight = {f: st for f, st in chosen.items() if st.state == TIGHTENED}
            if tight:
                state = "tightened (" + ", ".join(sorted(tight)) + ")"
                fraction = min(
                    1.0, _profile_fraction(prof, "sample_fraction_tightened", 2 * fraction)
                )
                for st in tight.values():
                    suspects.update(st.suspect_items)
    got = draw(
        d,
        scope=scope,
        seed=seed,
        round=round_,
        fraction=fraction,
        minimum=minimum,
        must_include=suspects,
    )
    target = out or Path(f"sample-{scope}-r{round_}.csv")
    atomic_write(target, got.table.to_csv(index=False, lineterminator="\n"))
    s = got.sample
    click.echo(
        f"selected {len(s.ids)} of {s.n_items} {scope}s ({100 * s.fraction:.1f} %, target {s.target}) "
        f"with seed {seed}, round {round_}, audit level {state}; wrote {target}"
    )


def _profile_fraction(prof, name: str, fallback: float) -> float:
    par = prof.parameters.get(name)
    val = None if par is None else (par.value if par.value is not None else par.default)
    if val is None:
        return fallback
    return float(val) / (100.0 if par.unit == "%" else 1.0)
