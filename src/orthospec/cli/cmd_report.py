"""orthospec report (re-render a stored qcr.json) and orthospec spec render (the tender annex)."""

from __future__ import annotations

import json
from datetime import date as Date
from pathlib import Path

import click

from ..errors import ReportError, SpecError
from ..outputs import atomic_write
from .groups import main, spec
from .options import allowed_signers_option, split_formats

REPORT_FORMATS = ("html", "pdf", "gpkg")
ANNEX_FORMATS = ("md", "html", "pdf")


def _read_qcr(path: Path) -> dict:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise ReportError(
            f"{path}: no such file (expected a qcr.json written by `orthospec check`)"
        ) from exc
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ReportError(f"{path}: not valid JSON ({exc})") from exc
    return doc


@main.command("report")
@click.argument("qcr_json", type=click.Path(dir_okay=False, path_type=Path), required=False)
@click.option(
    "--format",
    "formats",
    default="html,pdf",
    show_default=True,
    help="Comma-separated: " + ", ".join(REPORT_FORMATS) + ".",
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for report.html / report.pdf / findings.gpkg (default: beside QCR_JSON, or "
    "./report-run-N). The GeoPackage re-rendered from qcr.json alone has no seamlines layer "
    "features (they are read from the delivery by `orthospec check --format gpkg`).",
)
@click.option(
    "--ledger",
    "ledger_target",
    default=None,
    metavar="PATH|URL",
    help="Render a run stored in the QCR ledger, with its sign-offs and the project's history.",
)
@click.option(
    "--run", "run_id", type=int, default=None, help="Run id in the ledger (with --ledger)."
)
@click.option(
    "--against",
    "against",
    type=click.Path(dir_okay=False, exists=True, path_type=Path),
    default=None,
    help="With --ledger: a report.pdf/report.html/qcr.json written earlier (e.g. the run's own report "
    "from check): warn when the chain no longer holds the ledger head printed in it.",
)
@allowed_signers_option
def report_cmd(
    qcr_json: Path | None,
    formats: str,
    out_dir: Path | None,
    ledger_target: str | None,
    run_id: int | None,
    against: Path | None = None,
    allowed_signers: Path | None = None,
) -> None:
    """Render the auditor's report (HTML, archival PDF/A-3b) from a stored QCR_JSON or a ledger run.

    Example: orthospec report --ledger qc.sqlite --run 2 --out reports/run-2
    """
    from ..reports import document as reportdoc  # WeasyPrint only when this command runs

    fmts = split_formats(formats, REPORT_FORMATS)
    if ledger_target is not None or run_id is not None:
        if ledger_target is None or run_id is None or qcr_json is not None:
            raise click.UsageError("give either QCR_JSON, or --ledger PATH|URL with --run N")
        from ..ledger import open_ledger
        from ..ledger.verify import heads_in_file

        heads = []
        if against is not None:
            heads = heads_in_file(against)
            if not heads:
                raise click.BadParameter(
                    f"{against}: no ledger head hash found in it", param_hint="--against"
                )
        with open_ledger(ledger_target, create=False, allowed_signers=allowed_signers) as led:
            doc = led.report_document(run_id, heads=heads)
        if doc["ledger"]["problems"]:
            click.echo(
                f"WARNING: ledger {ledger_target} is TAMPERED ({doc['ledger']['problems'][0]}); "
                "the report says so on page 1",
                err=True,
            )
        default_target = Path(f"report-run-{run_id}")
    elif against is not None:
        raise click.UsageError("--against needs --ledger PATH|URL with --run N")
    elif qcr_json is None:
        raise click.UsageError("give QCR_JSON, or --ledger PATH|URL with --run N")
    else:
        doc = _read_qcr(qcr_json)
        default_target = qcr_json.parent
    files = (
        reportdoc.render(doc, formats=[f for f in fmts if f != "gpkg"])
        if set(fmts) - {"gpkg"}
        else {}
    )
    if "gpkg" in fmts:
        from ..findings import to_gpkg

        files["findings.gpkg"] = to_gpkg(doc)  # footprints from qcr.json (details.footprints)
    target = out_dir if out_dir is not None else default_target
    for name, data in files.items():
        atomic_write(target / name, data)
    click.echo(
        f"wrote {', '.join(sorted(files))} to {target}/ (qcr.json SHA-256 "
        f"{reportdoc.document_sha256(doc)})"
    )
    head = (doc.get("ledger") or {}).get("head")
    if head:
        click.echo(
            f"ledger head {head} (printed in the report; check later with "
            f"`orthospec ledger verify --head {head[:16]}`)"
        )


@spec.command("render")
@click.argument("profile")
@click.option(
    "--format",
    "formats",
    default="pdf,html,md",
    show_default=True,
    help="Comma-separated: " + ", ".join(ANNEX_FORMATS) + ".",
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for annex-<id>-<version>.<format> (default: reports/annex/ under the current folder, "
    "or under the root of the orthospec checkout it is in; refused inside a delivery).",
)
@click.option(
    "--date",
    "day",
    metavar="YYYY-MM-DD",
    default=None,
    help="Date printed on the annex (default today); fix it for byte-identical output.",
)
@click.option(
    "--sensor",
    type=click.Choice(["aerial", "satellite"]),
    default=None,
    help="The tender's sensor (default: read from the profile's own sensor rules); requirements "
    "that cannot apply to it move to an appendix.",
)
def render_cmd(
    profile: str, formats: str, out_dir: Path | None, day: str | None, sensor: str | None
) -> None:
    """Render PROFILE as the technical-specification annex of an invitation to tender.

    Example: orthospec spec render examples/specs/tender-example.yaml --format md,pdf --out annex/
    """
    from ..profile.loader import load_profile
    from ..reports.annex import default_out_dir, render_annex

    fmts = split_formats(formats, ANNEX_FORMATS)
    if out_dir is None:
        out_dir = default_out_dir()
    if day is not None:
        try:
            Date.fromisoformat(day)
        except ValueError as exc:
            raise click.BadParameter(
                f"{day!r} is not a date YYYY-MM-DD", param_hint="--date"
            ) from exc
    try:
        prof = load_profile(profile)
    except SpecError as exc:
        # The annex documents requirements; a profile whose measures orthospec does not implement
        # yet can still be published as text (`spec validate` reports them).
        try:
            prof = load_profile(profile, check_measures=False)
        except SpecError:
            raise exc from None
        click.echo(f"warning: rendering although the profile does not validate: {exc}", err=True)
    files = render_annex(prof, formats=fmts, day=day, sensor=sensor)
    for name, data in files.items():
        atomic_write(out_dir / name, data)
    click.echo(
        f"wrote {', '.join(sorted(files))} to {out_dir}/ (profile {prof.id} {prof.version}, "
        f"sha256 {prof.sha256})"
    )
