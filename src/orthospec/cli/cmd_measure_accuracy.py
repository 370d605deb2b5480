"""``orthospec measure accuracy POINTS.csv``: checkpoint statistics and blunder screening."""

from __future__ import annotations

import json
import math
from typing import Any

import click

from ..delivery.points import PointTable, point_table, read_point_file
from ..errors import OrthospecError
from ..measures.accuracy import AccuracyStats, BlunderResult, detect_blunders
from ..present import fmt_fixed, fmt_value
from .groups import measure

_KEYS = (
    "n", "mean_x", "mean_y", "mean_z", "std_x", "std_y", "std_z", "rmse_x", "rmse_y", "rmse_z",
    "rmse_r", "nssda_horizontal_95", "nssda_ratio", "nssda_approximation_holds", "nssda_method",
    "nssda_vertical_95", "ce90", "ce95", "sigma_c", "mu_h", "std_ratio", "bias_ratio",
    "bias_ratio_x", "bias_negligible", "ce90_empirical", "ce95_empirical", "percentile_method",
    "ce90_selected", "ce95_selected", "ce_method", "max_abs_dx", "max_abs_dy", "max_abs_dz",
    "max_dr",
)


def _clean(v: Any) -> Any:
    """JSON-safe: non-finite floats become null (JSON has no inf), floats to 10 sig. digits."""
    if isinstance(v, float):
        return float(f"{v:.10g}") if math.isfinite(v) else None
    return v


def _stats_dict(s: AccuracyStats) -> dict[str, Any]:
    d = s.to_dict()
    return {k: _clean(d[k]) for k in _KEYS}


def _payload(res: BlunderResult, *, file: str, source_unit: str, gsd: float | None,
             layout: str) -> dict[str, Any]:
    out: dict[str, Any] = {"file": file, "layout": layout, "units": "m",
                           "source_units": source_unit, "gsd": gsd}
    out.update(_stats_dict(res.stats_all))
    out["blunders"] = {
        "basis": res.basis, "factor": res.factor,
        "limit_x": _clean(res.limit_x), "limit_y": _clean(res.limit_y),
        "limit_z": _clean(res.limit_z), "limit_r": _clean(res.limit_r),
        "candidates": list(res.candidates), "excluded": list(res.excluded),
        "errors": list(res.error_ids), "note": res.note,
        "decisions": [
            {"point_id": d.point_id, "dx": _clean(d.dx), "dy": _clean(d.dy), "dz": _clean(d.dz),
             "dr": _clean(d.dr), "exceeds_x": d.exceeds_x, "exceeds_y": d.exceeds_y,
             "exceeds_z": d.exceeds_z, "exceeds_r": d.exceeds_r, "decision": d.decision,
             "reason": d.reason}
            for d in res.decisions
        ],
    }
    kept = res.stats_kept
    out["after_exclusions"] = None if kept is None or kept is res.stats_all else _stats_dict(kept)
    out["in_gsd"] = None if gsd is None else _stats_dict(res.stats_all.in_gsd())
    return out


def _render(payload: dict[str, Any]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False)

    def fmt(v: Any) -> str:
        return fmt_fixed(v, 4) if isinstance(v, float) else fmt_value(v)

    gsd = payload["in_gsd"]
    table = Table(title=f"Checkpoint accuracy: {payload['file']} (n = {payload['n']}, m)")
    table.add_column("statistic")
    table.add_column("value (m)", justify="right")
    if gsd:
        table.add_column("GSD units", justify="right")
    for key in _KEYS[1:]:
        row = [key, fmt(payload[key])]
        if gsd:
            row.append(fmt(gsd[key]) if isinstance(gsd[key], float) and key not in
                       ("nssda_ratio", "std_ratio", "bias_ratio", "bias_ratio_x") else "")
        table.add_row(*row)
    console.print(table)
    b = payload["blunders"]
    console.print(
        f"Blunders (basis {b['basis']}, limits |dx| > {fmt(b['limit_x'])}, "
        f"|dy| > {fmt(b['limit_y'])}): candidates {', '.join(b['candidates']) or 'none'}; "
        f"excluded {', '.join(b['excluded']) or 'none'}"
    )
    if b["note"]:
        console.print(f"  note: {b['note']}")
    for d in b["decisions"]:
        if d["decision"] != "kept":
            console.print(f"  {d['point_id']}: {d['decision']}: {d['reason']}")
    if payload["after_exclusions"]:
        a = payload["after_exclusions"]
        console.print(f"After exclusions: n = {a['n']}, RMSE_x {fmt(a['rmse_x'])}, "
                      f"RMSE_y {fmt(a['rmse_y'])}, RMSE_r {fmt(a['rmse_r'])}")


@measure.command("accuracy")
@click.argument("points", type=click.Path(dir_okay=False))
@click.option("--gsd", type=float, default=None, help="GSD in metres: also report in GSD units.")
@click.option("--units", type=click.Choice(["m", "ft", "usft"]), default=None,
              help="Unit of the coordinate columns (default m, or the file's unit column).")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON object instead of a table.")
@click.option("--blunder-basis", type=click.Choice(["calculated", "target"]), default="calculated",
              show_default=True,
              help="3 x calculated RMSE (JRC §12.6) or 3 x target RMSE (JRC Table 9).")
@click.option("--target-rmse", type=float, default=None,
              help="Target planimetric RMSE in metres (for --blunder-basis target).")
@click.option("--target-rmse-z", type=float, default=None,
              help="Target vertical RMSE in metres (for --blunder-basis target with z).")
@click.option("--percentile", type=click.Choice(["linear", "nearest-rank"]), default="linear",
              show_default=True, help="Percentile definition of the empirical CE90/CE95.")
@click.pass_context
def accuracy_cmd(ctx: click.Context, points: str, gsd: float | None, units: str | None,
                 as_json: bool, blunder_basis: str, target_rmse: float | None,
                 target_rmse_z: float | None, percentile: str) -> None:
    """RMSE, NSSDA, CE90/CE95, bias test and blunder screening of checkpoint discrepancies.

    POINTS.csv has columns id,x,y[,z],x_ref,y_ref[,z_ref] or id,dx,dy[,dz], optionally
    unit, excluded and exclusion_reason; other columns (a delivery's checkpoints table has
    image_id, source, ...) are ignored. With a block column, each block is measured on its own
    (JRC §12.7 is per block). Results are in metres.

    Example: orthospec measure accuracy examples/deliveries/aerial-fail/tables/checkpoints.csv
    """
    try:
        tables, ignored = _split(points, units)
        payloads = {}
        for block, table in tables.items():
            res = detect_blunders(
                table.dx, table.dy, table.dz, ids=table.ids, basis=blunder_basis,  # type: ignore[arg-type]
                target_rmse_xy=target_rmse, target_rmse_z=target_rmse_z,
                exclusions=table.exclusions, gsd=gsd, unit="m",
                percentile_method=percentile,  # type: ignore[arg-type]
            )
            label = points if block is None else f"{points} block {block}"
            payloads[block] = _payload(res, file=label, source_unit=table.source_unit, gsd=gsd,
                                       layout=table.layout)
    except OrthospecError as exc:
        click.echo(f"error: {exc}", err=True)
        ctx.exit(2)
    if ignored and not as_json:
        click.echo(f"ignored column(s): {', '.join(ignored)}", err=True)
    if as_json:
        out = payloads[None] if list(payloads) == [None] else {
            "file": points, "blocks": payloads, "ignored_columns": ignored}
        click.echo(json.dumps(out, indent=2, ensure_ascii=False))
    else:
        for payload in payloads.values():
            _render(payload)


def _split(points: str, units: str | None) -> tuple[dict[str | None, PointTable], list[str]]:
    """{block or None: its points}, and the columns ignored (a delivery's table has image_id,
    source, ...). The file is read once by the one table parser; the whole file is validated
    first (a duplicate id across blocks, mixed units), so every error names the file's own row."""
    import numpy as np

    pf = read_point_file(points)
    whole = point_table(pf, units=units)
    ignored = [c for c in pf.ignored if c != "block"]
    if "block" not in pf.df:
        return {None: whole}, ignored
    blocks = pf.df["block"].fillna("").to_numpy(dtype=object)
    return {str(b): point_table(pf, np.flatnonzero(blocks == b), units=units)
            for b in sorted(set(blocks.tolist()))}, ignored
