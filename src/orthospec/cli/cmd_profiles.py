"""orthospec profiles / spec show / spec validate / spec diff / explain / measures."""

from __future__ import annotations

from pathlib import Path

import click
import yaml
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from ..errors import OrthospecError
from ..profile.loader import available, load_profile, validate_file
from .groups import main, spec


@main.command("profiles")
@click.argument("paths", nargs=-1, type=click.Path(exists=True, path_type=Path))
def profiles_cmd(paths: tuple[Path, ...]) -> None:
    """List shipped profiles (and those in PATHS: files or folders) with version."""
    from ..profile.loader import plugin_profiles

    extra = [p for p in paths if p.is_dir()]
    rows = available(extra)
    seen = {r[3].resolve() for r in rows}
    rows += [
        r for r in plugin_profiles() if r[3].resolve() not in seen
    ]  # profiles installed plugins ship
    for p in paths:
        if p.is_file():
            prof = load_profile(p, check_measures=False)
            rows.append((prof.id, prof.version, prof.title, p))
    t = Table("id", "version", "rules", "title", "file", box=None, header_style="bold")
    t.columns[3].ratio = 3
    for pid, ver, title, path in rows:
        try:
            n = str(len(load_profile(path).rules))
        except (OrthospecError, OSError) as exc:  # list broken profiles too, saying why
            n = f"invalid ({type(exc).__name__})"
        t.add_row(escape(pid), escape(ver), n, escape(title), escape(_short(path)))
    Console(highlight=False).print(t)


def _short(path: Path) -> str:
    from ..resources import specs_dir

    if path.resolve().parent == specs_dir().resolve():
        return "shipped"
    try:
        return path.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return path.name


@spec.command("show")
@click.argument("profile")
@click.option("--json", "as_json", is_flag=True, help="Print the canonical resolved JSON.")
def show_cmd(profile: str, as_json: bool) -> None:
    """Print the resolved profile (extends applied) and its SHA-256."""
    p = load_profile(profile)
    if as_json:
        click.echo(p.canonical_json())
        return
    click.echo(f"# {p.id} {p.version}  sha256 {p.sha256}")
    click.echo(f"# resolved from: {' <- '.join(f'{i} {v}' for i, v, _ in p.chain)}")
    click.echo(yaml.safe_dump(p.canonical, sort_keys=False, allow_unicode=True, width=100))


@spec.command("validate")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
def validate_cmd(files: tuple[Path, ...]) -> None:
    """Validate profile FILES (schema, models, units, expressions, measures); exit 2 on problems."""
    bad = 0
    for f in files:
        problems = validate_file(f)
        if problems:
            bad += 1
            for pr in problems:
                click.echo(f"error: {pr}", err=True)
        else:
            p = load_profile(f)
            click.echo(f"{f}: valid ({p.id} {p.version}, {len(p.rules)} rules, sha256 {p.sha256})")
    click.get_current_context().exit(2 if bad else 0)


def _show(v: object) -> str:
    """A profile value as written in YAML, not as a Python repr (None -> '—')."""
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list | dict):
        import json

        return json.dumps(v, ensure_ascii=False)
    return str(v)


@spec.command("diff")
@click.argument("a")
@click.argument("b")
@click.option("--json", "as_json", is_flag=True)
@click.option(
    "--all", "show_all", is_flag=True, help="Also show changed prose (descriptions, notes, titles)."
)
def diff_cmd(a: str, b: str, as_json: bool, show_all: bool) -> None:
    """What changed from profile A to profile B: rules and thresholds added, removed, changed.

    Parameters are shown with their units and effective values (the tender's value, else the
    standard's default); changed rules with their effective requirement before and after.
    Example: orthospec spec diff jrc-v3 examples/specs/tender-example.yaml
    """
    import json

    from ..api import diff
    from ..profile.wording import param_value, unit_suffix
    from ..reports.annex import requirement_text

    pa, pb = load_profile(a), load_profile(b)
    d = diff(pa, pb, prose=show_all)
    warning = d.get("warning")
    if as_json:
        click.echo(json.dumps(d, indent=1, ensure_ascii=False))
        return
    if warning:
        click.echo(warning, err=True)
    click.echo(f"{d['a']} -> {d['b']}")
    for w in d["weakened"]:
        why = w["justification"] or "no justification recorded"
        click.echo(
            f"! mandatory rule {w['id']} checks less: {'; '.join(w['changes'])} (justification: {why})"
        )

    def eff(p: object, name: str) -> str:
        par = p.parameters.get(name)  # type: ignore[attr-defined]
        if par is None:
            return "—"
        v = param_value(par)
        return "—" if v is None else f"{_show(v)}{unit_suffix(par.unit)}"

    for kind in ("parameters", "rules"):
        for name in d[kind]["added"]:
            extra = (
                f" = {eff(pb, name)}"
                if kind == "parameters"
                else f": {requirement_text(pb.rule(name).requirement, dict(pb.parameters))}"
            )
            click.echo(f"+ {kind[:-1]} {name}{extra}")
        for name in d[kind]["removed"]:
            click.echo(f"- {kind[:-1]} {name}")
        for name, changes in d[kind]["changed"].items():
            if kind == "parameters":
                click.echo(f"~ parameter {name}: effective {eff(pa, name)} -> {eff(pb, name)}")
            else:
                ra = requirement_text(pa.rule(name).requirement, dict(pa.parameters))
                rb = requirement_text(pb.rule(name).requirement, dict(pb.parameters))
                click.echo(f"~ rule {name}" + (f": requirement {ra} -> {rb}" if ra != rb else ""))
            for field, (old, new) in changes.items():
                click.echo(f"    {field}: {_show(old)} -> {_show(new)}")
    for t in d["through_parameters"]:  # rules whose threshold changed only through a parameter
        click.echo(f"~ rule {t['id']}: requirement {t['before']} -> {t['after']} (through its parameters)")
    if not any(d[k][c] for k in ("parameters", "rules") for c in ("added", "removed", "changed")):
        click.echo("no differences in rules or parameters")


@main.command("explain")
@click.argument("rule_id")
@click.option("--profile", "-p", default="jrc-v3", show_default=True)
def explain_cmd(rule_id: str, profile: str) -> None:
    """Clause, quote, requirement and the evidence a rule reads."""
    from ..profile.catalog import measure_info  # the shipped catalog: no engine import
    from ..profile.wording import profile_requirement_text

    p = load_profile(profile)
    try:
        r = p.rule(rule_id)
    except KeyError:
        near = [x.id for x in p.rules if rule_id.lower() in x.id.lower()][:10]
        raise click.ClickException(
            f"no rule {rule_id!r} in {p.id} {p.version}"
            + (f"; did you mean {', '.join(near)}?" if near else "")
        ) from None
    info = measure_info(r.measure)
    c = Console(highlight=False)
    c.print(f"[bold]{escape(r.id)}[/] {escape(r.title)}")
    c.print(f"clause:      {escape(r.clause.text())}")
    c.print(f"quote:       “{escape(r.quote)}”")
    c.print(f"scope:       {r.scope}" + (f"   when: {escape(r.when)}" if r.when else ""))
    c.print(
        f"measure:     {escape(r.measure)}"
        + (f" ({info[1]})" if info else "")
        + ("  [manual: recorded human verdict]" if r.manual else "")
    )
    # worded as the QCR and the annex word it; thresholds from the profile's parameters (an
    # expression is shown as written: evaluating it would import numpy for one line)
    req = r.requirement
    text = profile_requirement_text(req, p.parameters)
    written = [
        f"{k}: {v}"
        for k, v in (("value", req.value), ("min", req.min), ("max", req.max))
        if isinstance(v, str) and v not in text
    ]
    c.print(
        f"requirement: {escape(text)}" + (f"   ({escape(', '.join(written))})" if written else "")
    )
    c.print(f"level:       {r.level}   consequence: {r.consequence}")
    if r.audit:
        c.print(f"audit:       {escape(str(r.audit.model_dump(exclude_none=True)))}")
    if r.note:
        c.print(f"note:        {escape(r.note)}")
    for w in p.weakened:  # a mandatory rule of the standard this tender made check less
        if w.id == r.id:
            c.print(
                f"[yellow]weakened:[/]    {escape('; '.join(w.changes))} by {escape(w.profile)} "
                f"(justification: {escape(w.justification or 'none recorded')})"
            )
    c.print(f"evidence:    {escape(_evidence_hint(r.measure))}")


def _evidence_hint(measure: str) -> str:
    from ..delivery.convention import table_specs

    head = measure.split(".")[0]
    if head == "manual":
        return "tables.manual_checks (check, item, inspector, date, verdict)"
    if head == "manifest":
        return f"delivery.yaml: {measure[len('manifest.') :]}"
    if head in table_specs():
        return f"tables.{head} ({table_specs()[head].description})"
    if head == "raster":
        return "the image files listed in tables.images (read with rasterio)"
    if head == "rollup":
        return "the verdicts of the item-level rules of this run"
    return "computed from the delivered files and tables"


@main.command("measures")
def measures_cmd() -> None:
    """List the measures rules may read (besides the generic <table>.<column> ones)."""
    from ..engine.catalog import known_measures
    from ..engine.registry import ROLLUP, describe

    cols = ("measure", "scope", "unit", "provider", "description")
    rows = [
        (
            name,
            specx.scope,
            specx.measures[name],
            specx.fn.__module__.rsplit(".", 1)[-1],
            describe(name),
        )
        for name, specx in known_measures().items()
    ]
    rows += [
        (name, scope, unit, "evaluator roll-up", describe(name))
        for name, (scope, unit) in ROLLUP.items()
    ]
    t = Table(box=None, header_style="bold")
    for col in cols:
        t.add_column(col, no_wrap=True, overflow="fold")  # names are copied from here: never cut
    for row in rows:
        t.add_row(*row)
    # one line per measure, never cut: the table is as wide as its widest row (pad 1 each side)
    need = sum(max(len(c), *(len(r[i]) for r in rows)) + 2 for i, c in enumerate(cols))
    Console(highlight=False, width=max(need, Console().width), soft_wrap=True).print(t)
    click.echo(
        "plus <table>.<column>, <table>.present, <table>.count, <table>.count_per_block, "
        "<table>.<column>.complete and manifest.<path> for every table in specs/delivery-tables.yaml"
    )
