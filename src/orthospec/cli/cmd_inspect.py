"""orthospec inspect grid: the visual inspection grid over the sampled images (inspection/grid.py)."""

from __future__ import annotations

from pathlib import Path

import click

from .groups import inspect


@inspect.command("grid")
@click.argument("delivery", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--cell",
    required=True,
    metavar="SIZE",
    help="Cell edge: metres in the images' map projection (250, 250m) or image pixels (512px).",
)
@click.option(
    "--sample",
    "sample",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="A sample table (`orthospec sample`): grid only those images (or the images of those "
    "blocks); every image without it.",
)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    metavar="CHECKER_DIR/inspection.gpkg",
    help="The GeoPackage to write (outside the delivery).",
)
def grid_cmd(delivery: Path, cell: str, sample: Path | None, out: Path) -> None:
    """Write the inspection grid (GeoPackage) over the sampled images of DELIVERY into the checker's folder.

    One square cell per step over each image's footprint, with the image id and SHA-256 and a 0/1
    field per defect class (specs/inspection.yaml: smear, seam, ghosting, colour_break, haze, cloud,
    saturation, missing_data, blur, artefact); mark them in QGIS (inspected, classes, comment), then
    `orthospec check DELIVERY ... --checker CHECKER_DIR` reads the marks (docs/CHECKER.md).

    Example: orthospec inspect grid examples/deliveries/aerial-pass --cell 8 --out qc/inspection.gpkg
    """
    from .. import __version__
    from ..api import refuse_inside_delivery
    from ..delivery.reader import open_delivery
    from ..engine.sample import read_sample
    from ..inspection.grid import CellSize, make_grid

    size = CellSize.parse(cell)
    refuse_inside_delivery(out, delivery, what="--out")
    d = open_delivery(delivery)
    d.load_all_tables()
    picked = read_sample(sample) if sample is not None else None
    got = make_grid(
        d,
        size,
        out,
        sample=picked,
        sample_name=sample.name if sample is not None else None,
        version=__version__,
    )
    click.echo(
        f"wrote {out}: {got['cells']} cells of {got['cell']} over {got['images']} images "
        f"({got['sample']}); mark them (inspected, defect classes, comment) in a GIS"
    )
