"""``orthospec measure radiometry IMAGE``: file checks and exact radiometry of one image."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import click

from ..present import fmt_fixed, fmt_value
from .groups import measure

if TYPE_CHECKING:  # the raster stack (numpy, rasterio) loads only when an image is measured
    from ..raster.parallel import ImageReport


def _fmt(v: object) -> str:
    """Measured values with 3 decimals, counts as they are."""
    return fmt_fixed(v, 3) if isinstance(v, float) else fmt_value(v)


def _render(rep: ImageReport, findings: list[str]) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = Console()
    c = rep.checks
    console.print(f"[bold]{escape(rep.path)}[/bold]  sha256 {rep.sha256}", soft_wrap=True)
    for f in findings:
        console.print(f"[yellow]file check:[/yellow] {escape(f)}", soft_wrap=True)
    console.print(
        f"{c.get('driver')} {c.get('width')}x{c.get('height')} x{c.get('band_count')} "
        f"{','.join(c.get('dtypes') or [])}  compression {c.get('compression')} "
        f"(lossless: {c.get('lossless')})  {c.get('layout')} "
        f"{c.get('block_width')}x{c.get('block_height')}  CRS {c.get('crs')} (ok: {c.get('crs_ok')})"
        f"  pixel {_fmt(c.get('pixel_size_x'))} x {_fmt(c.get('pixel_size_y'))} "
        f"{c.get('pixel_size_unit')} (gsd ok: {c.get('gsd_ok')})  name ok: {c.get('name_ok')}"
    )
    rad = rep.radiometry or {}
    console.print(f"statistics: {rad.get('statistics')}")
    cols = [
        "band",
        "min",
        "max",
        "mean",
        "std",
        "bit_depth",
        "used_bits",
        "saturation_low_pct",
        "saturation_high_pct",
        "dark_margin_pct",
        "bright_margin_pct",
        "cv_percent",
        "nodata_fraction",
        "noise_sigma_homogeneous",
    ]
    bands = list(rad.get("bands", []))
    if rad.get("luminosity"):
        bands.append(rad["luminosity"])
    t = Table("measure", *[str(b.get("band")) for b in bands])
    for k in cols[1:]:
        t.add_row(k.replace("_", " "), *[_fmt(b.get(k)) for b in bands])
    console.print(t)
    for idx, m in (rad.get("misregistration") or {}).items():
        console.print(
            f"band {idx} vs band {rad.get('misregistration_reference_band')}: "
            f"misregistration {m['magnitude_px']:.2f} px "
            f"(dy {m['dy_px']:.2f}, dx {m['dx_px']:.2f})"
        )


@measure.command("radiometry")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the full report as JSON.")
@click.option(
    "--full",
    is_flag=True,
    help="Also the rest of the JRC §6.3 scan: noise (two estimators), luminosity, "
    "band misregistration, and the facts `check` compares declarations with "
    "(content hash of the decoded pixels, thumbnail, measured cloud cover); same "
    "single read, slower.",
)
@click.option(
    "--bit-depth",
    type=click.IntRange(1, 32),
    default=None,
    help="Real radiometric resolution (e.g. 11 for 11-bit data in 16-bit files); "
    "default: the NBITS tag, else the data type.",
)
@click.option("--expect-epsg", type=int, default=None, help="EPSG code the CRS must equal.")
@click.option(
    "--expect-gsd",
    type=float,
    default=None,
    help="Specified GSD in CRS units (m); pixel size must match within tolerance.",
)
@click.option(
    "--gsd-tolerance",
    type=float,
    default=0.01,
    show_default=True,
    help="Relative tolerance of the pixel size against --expect-gsd.",
)
@click.option(
    "--cloud-mask",
    type=click.Path(dir_okay=False),
    default=None,
    help="Delivered cloud mask raster (non-zero = cloud).",
)
@click.pass_context
def radiometry_cmd(
    ctx: click.Context,
    image: str,
    as_json: bool,
    full: bool,
    bit_depth: int | None,
    expect_epsg: int | None,
    expect_gsd: float | None,
    gsd_tolerance: float,
    cloud_mask: str | None,
) -> None:
    """Exact per-band statistics, histograms and JRC §6.3 measures plus file checks of IMAGE.

    By default the job of ``gdalinfo -stats -hist`` plus the file's SHA-256: statistics are
    exact (no overviews), with population std and nodata excluded per band, as GDAL computes
    them, and the §6.3 measures the histograms give (saturation, margins, CV). ``--full`` adds
    the rest of the JRC §6.3 scan (noise, luminosity, band misregistration) and the pixel facts
    ``check`` measures (content hash, thumbnail, cloud cover) to the same single read of the
    pixels. Radiometry needs no georeference: a missing or unparseable CRS is
    reported as a file-check finding, not refused. Exit code 2 when the pixels cannot be read.
    """
    import gc
    import os
    import sys
    from concurrent.futures import ThreadPoolExecutor

    from ..provenance import sha256_file

    if "numpy" not in sys.modules:
        # nothing here multiplies large matrices (the misregistration DFTs use einsum, not
        # BLAS): OpenBLAS need not start a thread per core when numpy loads (start-up time)
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    # No cyclic garbage collection while the raster stack is imported and the pixels scanned:
    # importing numpy, rasterio and Pillow allocates enough objects to trigger dozens of
    # collections (about 8 % of the command's CPU in a profile), and the scan makes no cycles
    # worth collecting. Reference counting still frees every array; re-enabled on the way out.
    collecting = gc.isenabled()
    gc.disable()
    # The hash thread takes the GIL back after each 4 MiB it hashes; while this thread imports
    # the raster stack (pure Python) it would wait up to the 5 ms default switch interval each
    # time, slowing the hash, the command's longest task, about 1.5x (measured)
    switching = sys.getswitchinterval()
    sys.setswitchinterval(0.0002)
    try:
        # the file's SHA-256 is computed while the raster stack is imported and the pixels
        # scanned (hashlib releases the GIL): it adds no wall time
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="orthospec-sha256") as pool:
            hashing = pool.submit(sha256_file, image)
            from ..raster.parallel import ScanOptions, scan_image
            from ..raster.reading import ScanSettings

            settings = ScanSettings(
                bit_depth=bit_depth,
                noise=full,
                luminosity=full,
                misregistration=full,
                signature=full,
            )
            opts = ScanOptions(
                settings=settings,
                expect_epsg=expect_epsg,
                expect_gsd=expect_gsd,
                gsd_tolerance=gsd_tolerance,
            )
            rep = scan_image(image, opts, cloud_mask=cloud_mask, sha256=hashing)
    finally:
        # Everything allocated so far (the modules of the raster stack, the report) lives until
        # the process ends: frozen, no collection walks it again, neither the first one after
        # re-enabling nor the interpreter's full collection at exit (about 40 ms of the
        # command's wall time on a 2-core machine). Frozen objects are still freed by reference
        # counting; an in-process caller (tests) keeps working, with these objects exempt from
        # cycle collection.
        gc.freeze()
        if collecting:
            gc.enable()
        sys.setswitchinterval(switching)
    if rep.error and rep.radiometry is None:
        click.echo(f"error: {rep.error}", err=True)
        ctx.exit(2)
    # pixels measured despite a header error (no CRS...): that error is a finding on the file
    findings = [rep.error] if rep.error else []
    if as_json:
        doc = {
            "path": rep.path,
            "sha256": rep.sha256,
            "bytes": rep.bytes,
            "checks": rep.checks,
            "findings": findings,
            "radiometry": rep.radiometry,
            "cloud_cover_pct": rep.cloud_cover_pct,
        }
        click.echo(json.dumps(doc, indent=2, sort_keys=True))
    else:
        _render(rep, findings)
