"""``orthospec measure checkpoints DELIVERY --reference REF --points SURVEY --out CHECKER_DIR``."""

from __future__ import annotations

import json
from collections import Counter
from typing import TYPE_CHECKING, Any

import click

from .groups import measure

if TYPE_CHECKING:  # the raster stack loads only when the command runs
    from ..raster.checkpoints import Run


def _payload(run: Run) -> dict[str, Any]:
    def num(v: float | None) -> float | None:
        return None if v is None or v != v else float(f"{v:.10g}")

    points = []
    for r in run.results:
        m = r.match
        points.append({
            "point_id": r.point.point_id, "row": r.point.row, "decision": r.decision,
            "reason_code": r.reason_code or None, "reason": r.reason, "image_id": r.image_id,
            "x": num(r.x), "y": num(r.y), "x_ref": r.point.x, "y_ref": r.point.y,
            "dx_px": num(m.dx_px) if m else None, "dy_px": num(m.dy_px) if m else None,
            "score": num(m.score) if m else None, "peak_ratio": num(m.peak_ratio) if m else None,
            "sigma_px": num(m.sigma_px) if m else None, "reference_file": r.reference_file or None,
        })
    counts = Counter(r.decision for r in run.results)
    return {"table": str(run.table) if run.table else None,
            "hand_list": str(run.hand_list) if run.hand_list else None,
            "survey_crs": run.survey_crs, "counts": dict(sorted(counts.items())),
            "warnings": run.warnings, "points": points}


def _render(run: Run) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = Console(highlight=False)
    counts = Counter(r.decision for r in run.results)
    console.print(
        f"{len(run.results)} surveyed point(s): {counts['accepted']} measured automatically, "
        f"{counts['by_hand']} by hand, {counts['to_measure']} to measure by hand, "
        f"{counts['unusable']} unusable, {counts['outside']} outside every image"
    )
    hand = [r for r in run.results if r.decision == "to_measure"]
    if hand:
        t = Table("point", "image", "reason", title="To measure by hand")
        for r in hand:
            t.add_row(escape(r.point.point_id), escape(r.image_id or "-"), escape(r.reason))
        console.print(t)
    if run.table:
        console.print(f"wrote {escape(str(run.table))}", soft_wrap=True)
    if run.hand_list:
        console.print(
            f"wrote {escape(str(run.hand_list))} (move each point onto its mark in a GIS, set "
            "status to 'measured' or 'unusable', then run again)",
            soft_wrap=True,
        )


@measure.command("checkpoints")
@click.argument("delivery", type=click.Path(file_okay=False))
@click.option(
    "--reference",
    required=True,
    type=click.Path(),
    help="The checker's reference: a folder of GeoTIFF chips around the points (named "
    "<point_id>.tif, or found by location), or one reference orthoimage.",
)
@click.option(
    "--points",
    "survey",
    required=True,
    type=click.Path(dir_okay=False),
    help="Survey CSV: point_id, x, y (true coordinates) [, z, block, image_id, source, "
    "precision_xy, chip].",
)
@click.option(
    "--out",
    required=True,
    type=click.Path(file_okay=False),
    help="The checker folder (outside the delivery): writes tables/checkpoints.csv and "
    "the hand list checkpoints-to-measure.gpkg.",
)
@click.option(
    "--hand",
    type=click.Path(dir_okay=False),
    default=None,
    help="The completed hand list (GeoPackage written by this command, or CSV with "
    "point_id, status, x, y); default: the one in --out when present.",
)
@click.option(
    "--chip",
    "chip_px",
    type=click.IntRange(16, 512),
    default=64,
    show_default=True,
    help="Template side in image pixels (smaller when the chip covers less).",
)
@click.option(
    "--search",
    "search_px",
    type=click.IntRange(1, 256),
    default=16,
    show_default=True,
    help="Largest shift searched, in image pixels, either way.",
)
@click.option(
    "--method",
    type=click.Choice(["phase", "ncc"]),
    default="phase",
    show_default=True,
    help="Subpixel estimator (benchmarks/matching.py compares them).",
)
@click.option(
    "--crs",
    default=None,
    help="CRS of the survey coordinates (default: the delivered images' CRS).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the per-point results as JSON.")
@click.pass_context
def checkpoints_cmd(
    ctx: click.Context,
    delivery: str,
    reference: str,
    survey: str,
    out: str,
    hand: str | None,
    chip_px: int,
    search_px: int,
    method: str,
    crs: str | None,
    as_json: bool,
) -> None:
    """Measure surveyed check points on the delivered orthoimages by subpixel image matching.

    For each point of the survey (true coordinates) the reference around it is resampled onto
    the delivered image's grid and located there (normalised cross-correlation, refined by
    iterated upsampled phase correlation); a match the tool cannot vouch for (low texture,
    cloud, change, edge of image, ambiguous) goes to the hand list with its reason, never into
    the table. Writes OUT/tables/checkpoints.csv with the provenance of every measurement.
    Exit 2 when the input is bad or nothing can be measured.

    Example: orthospec measure checkpoints delivery/ --reference chips/ --points survey.csv
    --out checker/
    """
    from ..errors import OrthospecError
    from ..measures.matching import MatchSettings
    from ..raster.checkpoints import MeasureOptions, measure_checkpoints

    try:
        options = MeasureOptions(
            chip_px=chip_px, crs=crs, settings=MatchSettings(method=method, search_px=search_px)  # type: ignore[arg-type]
        )
        run = measure_checkpoints(delivery, reference, survey, out, hand=hand, options=options)
    except OrthospecError as exc:
        click.echo(f"error: {exc}", err=True)
        ctx.exit(2)
    for w in run.warnings:
        click.echo(f"warning: {w}", err=True)
    if as_json:
        click.echo(json.dumps(_payload(run), indent=2, ensure_ascii=False))
    else:
        _render(run)
