"""Ledger commands: history, diff and signoff on ``main``; verify, state and runs on ``ledger``.

The ledger is a SQLite file (default ``./orthospec-ledger.sqlite`` or ``$ORTHOSPEC_LEDGER``) or a
PostgreSQL URL (``postgresql+psycopg://user@host/db``). These commands only parse, call
:mod:`orthospec.ledger` and print.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import click

from .. import verdicts as V
from ..errors import LedgerError
from ..ledger import MARGIN, ROLES, Ledger, open_ledger
from ..ledger.history import History
from ..ledger.verify import heads_in_file
from .groups import ledger, main
from .options import allowed_signers_option, key_option

ledger_option = click.option(
    "--ledger", "ledger_target", metavar="PATH|URL", envvar="ORTHOSPEC_LEDGER", default=None,
    help="Ledger: SQLite file or postgresql+psycopg:// URL "
         "(default $ORTHOSPEC_LEDGER, else ./orthospec-ledger.sqlite).")
json_option = click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")

_SHORT = {V.PASS: "pass", V.FAIL: "FAIL", V.WARN: "warn", V.MISSING: "MISS", V.ERROR: "ERR",
          V.WAIVED: "wvd", V.NOT_APPLICABLE: "n/a", V.REJECTED: "REJ"}


def _open(target: str | None, allowed_signers: Path | None = None) -> Ledger:
    return open_ledger(target, create=False, allowed_signers=allowed_signers)


def _run_id(text: str) -> int:
    t = text.lstrip("#")
    if not t.isdigit():
        raise click.BadParameter(f"{text!r}: a run id is a number (see `orthospec ledger runs`)")
    return int(t)


def _grid(title: str, rows: dict[str, dict[int, str]], run_ids: list[int]) -> list[str]:
    if not rows:
        return []
    width = max(len(k) for k in rows)
    head = " " * width + "  " + " ".join(f"{'#' + str(i):>5}" for i in run_ids)
    lines = [title, head]
    for key, per in rows.items():
        cells = " ".join(
            f"{_SHORT.get(per.get(i, ''), '-') if i in per else '-':>5}" for i in run_ids
        )
        lines.append(f"{key:<{width}}  {cells}")
    return lines


_QUIET = frozenset({V.PASS, V.NOT_APPLICABLE})


def _changing(rows: dict[str, dict[int, str]]) -> dict[str, dict[int, str]]:
    """Rows whose verdict differs between runs or is not pass / not applicable in some run."""
    return {
        k: per
        for k, per in rows.items()
        if len(set(per.values())) > 1 or not set(per.values()) <= _QUIET
    }


def _history_text(h: History, show_all: bool = False) -> str:
    out = []
    ids = [e.run.id for e in h.entries]
    out.append(
        f"{'run':>5}  {'date':<10}  {'round':<14}  {'delivery':<16}  {'verdict':<8}  "
        f"{'pass':>5} {'fail':>5} {'warn':>5} {'miss':>5}  sign-offs"
    )
    for e in h.entries:
        c = e.run.summary.get("counts", {})
        kind = f"{e.round} {e.kind}"
        out.append(
            f"{'#' + str(e.run.id):>5}  {e.run.date:<10}  {kind:<14}  {e.run.delivery_id:<16}  "
            f"{e.run.verdict:<8}  {c.get('pass', 0):>5} {c.get('fail', 0):>5} "
            f"{c.get('warn', 0):>5} {c.get('missing', 0):>5}  {e.signoffs}"
        )
    for title, rows in (("per rule (worst verdict per run):", h.rules), ("per block:", h.blocks)):
        shown = rows if show_all else _changing(rows)
        grid = _grid(title, shown, ids)
        if grid:
            out += ["", *grid]
        hidden = len(rows) - len(shown)
        if hidden:
            out.append(
                f"({hidden} {'rules' if 'rule' in title else 'blocks'} passing or not applicable in "
                "every run not shown; --all shows them)"
            )
    return "\n".join(out)


@main.command("history")
@click.argument("project", required=False)
@click.option("--all", "show_all", is_flag=True, help="Also list rules that passed in every run.")
@ledger_option
@json_option
def history_cmd(
    project: str | None, show_all: bool, ledger_target: str | None, as_json: bool
) -> None:
    """Deliveries, redeliveries and their verdicts over time, per rule and per block.

    By default only rules and blocks that changed or did not pass are listed (--all for every one).
    Example: orthospec history P-2026-ORTHO-L2 --ledger qc.sqlite
    """
    with _open(ledger_target) as led:
        _warn_if_tampered(led)
        projects = [project] if project is not None else led.projects()
        hists = [led.history(p) for p in projects]
    if project is not None and not hists[0].entries:
        raise LedgerError(
            f"no runs of project {project!r} in the ledger (projects: "
            f"{', '.join(p for p in projects if p != project) or 'none'})"
        )
    if as_json:
        click.echo(
            json.dumps(
                [
                    {
                        "project": h.project,
                        "runs": [
                            {
                                "run": e.run.id,
                                "date": e.run.date,
                                "recorded_at": e.run.recorded_at,
                                "kind": e.kind,
                                "round": e.round,
                                "delivery": e.run.delivery_id,
                                "verdict": e.run.verdict,
                                "summary": e.run.summary.get("counts", {}),
                                "signoffs": e.signoffs,
                                "hash": e.run.hash,
                            }
                            for e in h.entries
                        ],
                        "rules": {
                            k: {str(i): v for i, v in per.items()} for k, per in h.rules.items()
                        },
                        "blocks": {
                            k: {str(i): v for i, v in per.items()} for k, per in h.blocks.items()
                        },
                    }
                    for h in hists
                ],
                indent=1,
                ensure_ascii=False,
            )
        )
        return
    for n, h in enumerate(hists):
        if n:
            click.echo("")
        click.echo(f"project {h.project}: {len(h.entries)} run(s)")
        click.echo(_history_text(h, show_all))


@main.command("diff")
@click.argument("run_a")
@click.argument("run_b")
@click.option(
    "--all",
    "show_all",
    is_flag=True,
    help="Also list records added or removed with a passing or not-applicable verdict.",
)
@ledger_option
@json_option
def diff_cmd(
    run_a: str, run_b: str, show_all: bool, ledger_target: str | None, as_json: bool
) -> None:
    """What changed between two runs per rule and item: fixed, newly failing, still failing.

    Example: orthospec diff 1 2 --ledger qc.sqlite
    """
    a, b = _run_id(run_a), _run_id(run_b)
    with _open(ledger_target) as led:
        d = led.diff(a, b)
    if as_json:
        click.echo(
            json.dumps(
                {
                    "run_a": a,
                    "run_b": b,
                    "counts": d.counts,
                    "changes": [asdict(c) for c in d.changes],
                },
                indent=1,
            )
        )
        return
    order = ("fixed", "newly_failing", "still_failing", "changed", "added", "removed")
    click.echo(
        f"run #{a} -> run #{b}: "
        + (
            ", ".join(f"{d.counts[k]} {k.replace('_', ' ')}" for k in order if k in d.counts)
            or "no changes"
        )
    )
    hidden = 0
    for status in order:
        group = [c for c in d.changes if c.status == status]
        if not show_all and status in ("added", "removed"):
            keep = [c for c in group if not {c.before, c.after} <= (_QUIET | {None})]
            hidden += len(group) - len(keep)
            group = keep
        if not group:
            continue
        click.echo(f"{status.replace('_', ' ')}:")
        for c in group:
            click.echo(f"  {c.rule} [{c.item}]: {c.before or '-'} -> {c.after or '-'}")
    if hidden:
        click.echo(
            f"({hidden} records added or removed with a passing or not-applicable verdict not shown; "
            "--all shows them)"
        )


def _manual(values: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for v in values:
        rule, sep, verdict = v.partition("=")
        if not sep or verdict.strip().lower() not in (V.PASS, V.FAIL) or not rule.strip():
            raise click.BadParameter(
                f"{v!r}: expected RULE=pass or RULE=fail", param_hint="--manual"
            )
        out[rule.strip()] = verdict.strip().lower()
    return out


@main.command("signoff")
@click.argument("run")
@click.option(
    "--by",
    "by",
    default=None,
    help="Name of the person countersigning (with --key and an allowed-signers file: the key's "
    "registered name, which --by must then match).",
)
@click.option("--role", type=click.Choice(ROLES), default="supervisor", show_default=True)
@click.option("--note", default=None, help="Free text recorded with the signature.")
@click.option(
    "--manual",
    "manual",
    multiple=True,
    metavar="RULE=pass|fail",
    help="Verdict of a manual check of this run (repeatable).",
)
@click.option(
    "--date", metavar="YYYY-MM-DD", default=None, help="Date of the signature (default today)."
)
@click.option(
    "--acknowledge-rejection",
    is_flag=True,
    help="Needed to sign a REJECTED run: you sign that you have seen and accept the rejection.",
)
@ledger_option
@key_option
@allowed_signers_option
def signoff_cmd(
    run: str,
    by: str | None,
    role: str,
    note: str | None,
    manual: tuple[str, ...],
    date: str | None,
    acknowledge_rejection: bool,
    ledger_target: str | None,
    key: Path | None,
    allowed_signers: Path | None,
) -> None:
    """Countersign RUN (JRC §2.4) and record manual-check verdicts.

    The run's own checker (the key that signed it, or its operator or checker-file name however
    spelt) cannot countersign it; a duplicate or a date before the run is refused.
    Example: orthospec signoff 2 --key ~/.ssh/id_ed25519 --manual JRC-6.3-ARTEFACTS=pass --ledger qc.sqlite
    """
    rid = _run_id(run)
    verdicts = _manual(manual)
    with _open(ledger_target, allowed_signers) as led:
        _warn_if_tampered(led)
        sid = led.signoff(
            rid,
            by=by,
            role=role,
            note=note,
            manual=verdicts,
            date=date,
            acknowledge_rejection=acknowledge_rejection,
            key=key,
        )
        s = led.signoffs(rid)[-1]
    extra = f" with {len(verdicts)} manual verdict(s)" if verdicts else ""
    signed = f", signed by key {s['key']}" if s.get("key") else ", unsigned (a typed name, no key)"
    click.echo(f"signed run #{rid} as {role} ({s['by']}{signed}){extra}: sign-off {sid}")


def _warn_if_tampered(led: Ledger) -> bool:
    rep = led.verify()
    if rep.ok:
        return False
    click.echo(
        f"WARNING: ledger {led.display} is TAMPERED ({len(rep.problems)} problem(s), first: "
        f"{rep.problems[0]}); run `orthospec ledger verify`",
        err=True,
    )
    return True


@ledger.command("verify")
@ledger_option
@click.option(
    "--head",
    "head",
    metavar="HASH",
    default=None,
    help="A ledger head hash printed earlier on a report or in qcr.json: the chain must still "
    "contain it (detects deleted newest entries even when the head row was rewritten).",
)
@click.option(
    "--against",
    "against",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    default=None,
    help="A report.pdf, report.html or qcr.json: check the ledger head printed in it.",
)
@click.option(
    "--expect-head",
    metavar="HASH",
    default=None,
    help="The current head must be exactly this hash (nothing recorded since).",
)
@allowed_signers_option
def verify_cmd(
    ledger_target: str | None,
    head: str | None,
    against: Path | None,
    expect_head: str | None,
    allowed_signers: Path | None,
) -> None:
    """Check the hash chain: exit 0 when intact, 1 (TAMPERED) listing every edited or deleted row.

    Every signature is checked too (by the allowed-signers file when given): one that does not
    verify is listed as well.

    Example: orthospec ledger verify --ledger qc.sqlite --against reports/run-2/report.pdf
    """
    heads = [head] if head else []
    if against is not None:
        found = heads_in_file(against)
        if not found:
            raise click.BadParameter(
                f"{against}: no ledger head hash found in it", param_hint="--against"
            )
        heads += found
    with _open(ledger_target, allowed_signers) as led:
        rep = led.verify(heads=heads)  # one pass over the ledger for every head given
    problems = list(dict.fromkeys(str(p) for p in rep.problems))
    if expect_head is not None and not rep.head_hash.startswith(expect_head.lower()):
        problems.append(f"head hash {rep.head_hash} does not match the expected {expect_head}")
    if problems:
        click.echo(f"ledger {led.display}: TAMPERED, {len(problems)} problem(s):")
        for p in problems:
            click.echo(f"  {p}")
        click.get_current_context().exit(1)
    checked = (
        f"; contains the head{'s' if len(heads) > 1 else ''} {', '.join(h[:16] for h in heads)}"
        if heads
        else ""
    )
    click.echo(
        f"ledger {led.display}: intact, {rep.entries} entries ({rep.runs} runs, "
        f"{rep.signoffs} sign-offs), head {rep.head_hash}{checked}"
    )


@ledger.command("state")
@click.argument("project")
@click.option(
    "--normal", type=float, default=0.10, show_default=True, help="Sample share when normal."
)
@click.option(
    "--tightened", type=float, default=0.20, show_default=True, help="Sample share when tightened."
)
@click.option(
    "--margin",
    type=float,
    default=MARGIN,
    show_default=True,
    help="A pass this close (relative) to its threshold is marginal and tightens (JRC §12.7).",
)
@ledger_option
@json_option
def state_cmd(
    project: str,
    normal: float,
    tightened: float,
    margin: float,
    ledger_target: str | None,
    as_json: bool,
) -> None:
    """Normal/Tightened audit state per QCR family of PROJECT (JRC §2.3) and the next sample share."""
    with _open(ledger_target) as led:
        states = led.audit_states(project, margin=margin)
    if not states:
        raise LedgerError(f"no runs of project {project!r} in the ledger")
    rows: list[dict[str, Any]] = [
        {
            **asdict(s),
            "suspect_items": list(s.suspect_items),
            "by_reason": [
                {"reason": why, "records": n, "rules": list(rules)} for why, n, rules in s.by_reason
            ],
            "sample_fraction": tightened if s.state == "tightened" else normal,
        }
        for s in states.values()
    ]
    if as_json:
        click.echo(json.dumps({"project": project, "families": rows}, indent=1, ensure_ascii=False))
        return
    width = max(len(r["family"]) for r in rows)
    for r in rows:
        suspects = r["suspect_items"]
        trail = (
            f"; trail: {', '.join(suspects[:8])}{' ...' if len(suspects) > 8 else ''}"
            if suspects
            else ""
        )
        click.echo(
            f"{r['family']:<{width}}  {r['state']:<9}  sample {100 * r['sample_fraction']:.0f} %  "
            f"since run #{r['since_run']}  ({r['reason']}{trail})"
        )
        for g in r["by_reason"]:  # the family's findings grouped by reason code
            click.echo(
                f"{'':<{width}}  - {g['reason']}: {g['records']} record(s) "
                f"({', '.join(g['rules'][:6])}{' ...' if len(g['rules']) > 6 else ''})"
            )


@ledger.command("runs")
@click.argument("project", required=False)
@ledger_option
@json_option
def runs_cmd(project: str | None, ledger_target: str | None, as_json: bool) -> None:
    """List recorded runs (oldest first)."""
    with _open(ledger_target) as led:
        runs = led.runs(project)
    if as_json:
        click.echo(
            json.dumps(
                [
                    {
                        "run": r.id,
                        "seq": r.seq,
                        "date": r.date,
                        "recorded_at": r.recorded_at,
                        "project": r.project_id,
                        "delivery": r.delivery_id,
                        "verdict": r.verdict,
                        "profile": f"{r.profile_id}@{r.profile_version}",
                        "operator": r.operator,
                        "records": r.n_records,
                        "hash": r.hash,
                        "audit_trail": r.audit,
                        "continues_run": r.continues_run,
                        "signer": r.signer,
                        "key": r.key_fingerprint,
                    }
                    for r in runs
                ],
                indent=1,
            )
        )
        return
    for r in runs:
        trail = f" (trail {r.audit})" if r.audit != r.project_id else ""
        signed = f"  signed {r.key_fingerprint[:19]}" if r.key_fingerprint else "  unsigned"
        click.echo(
            f"#{r.id:<4} {r.date}  {r.project_id}{trail}  {r.delivery_id}  {r.verdict:<8}  "
            f"{r.profile_id}@{r.profile_version}  {r.n_records} QCRs  {r.hash[:12]}{signed}"
        )
