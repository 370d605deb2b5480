"""`orthospec measure edge`: spatial quality (RER, FWHM, MTF) of one edge-target ROI."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import click

from ..errors import MeasureError, OrthospecError
from .groups import measure


class _CouldNotRun(click.ClickException):
    """Bad input: print ``error: <message>`` and exit 2 (the CLI's 'could not evaluate')."""

    exit_code = 2

    def show(self, file: Any = None) -> None:
        click.echo(f"error: {self.message}", err=True)


def _parse_map_roi(text: str, pixel_roi: str | None) -> Any:
    from ..raster.roi import MapWindow

    if pixel_roi is not None:
        raise MeasureError("give --roi (pixels) or --map-roi (map coordinates), not both")
    try:
        vals = [float(p) for p in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != 4:
        raise MeasureError(
            f"--map-roi {text!r}: expected four numbers xmin,ymin,xmax,ymax in the raster's CRS"
        )
    return MapWindow(*vals)


def _parse_roi(text: str | None) -> Any:
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    try:
        vals = [int(p) for p in parts]
    except ValueError:
        vals = []
    if len(vals) != 4:
        raise MeasureError(
            f"--roi {text!r}: expected four integers x0,y0,x1,y1 (pixels, x1/y1 exclusive)"
        )
    x0, y0, x1, y1 = vals
    if x1 <= x0 or y1 <= y0 or x0 < 0 or y0 < 0:
        raise MeasureError(f"--roi {text!r}: expected 0 <= x0 < x1 and 0 <= y0 < y1")
    from ..raster.roi import PixelWindow

    return PixelWindow(x0, y0, x1, y1)


def _fmt(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return "inf" if math.isinf(value) else f"{value:.4g}"
    return str(value)


@measure.command("edge")
@click.argument("image", type=click.Path(dir_okay=False))
@click.option(
    "--roi",
    multiple=True,
    help="Pixel window x0,y0,x1,y1 (x1, y1 exclusive) holding one edge; "
    "repeat it to measure many ROIs in one call (in parallel with --workers). "
    "Default: find the straight edges automatically and measure each one.",
)
@click.option(
    "--map-roi",
    help="The window in the raster's CRS instead: xmin,ymin,xmax,ymax (read as the "
    "pixels it touches).",
)
@click.option("--whole", is_flag=True, help="Measure the whole image as one ROI (no edge search).")
@click.option("--band", type=int, default=1, show_default=True, help="Band to read (1-based).")
@click.option(
    "--gsd",
    type=float,
    help="Ground sample distance (m/px): adds metre values "
    "(default: the pixel size of a projected raster, as `check` uses it).",
)
@click.option(
    "--nodata", type=float, help="DN to ignore (default: the file's nodata, mask or alpha band)."
)
@click.option("--bit-depth", type=int, help="Radiometric depth for the saturation check.")
@click.option(
    "--min-snr",
    type=float,
    default=50.0,
    show_default=True,
    help="Health check: SNR = dDN / mean(std) must exceed this (seed: 50).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the flat JSON result.")
@click.option(
    "--plots",
    type=click.Path(file_okay=False),
    help="Write detection/ESF/LSF/MTF SVGs into this directory.",
)
@click.option(
    "--workers",
    type=click.IntRange(1, 64),
    default=None,
    help="Processes for several --roi (default: one per CPU, at most one per ROI).",
)
def edge_command(
    image: str,
    roi: tuple[str, ...],
    map_roi: str | None,
    whole: bool,
    band: int,
    gsd: float | None,
    nodata: float | None,
    bit_depth: int | None,
    min_snr: float,
    as_json: bool,
    plots: str | None,
    workers: int | None,
) -> None:
    """Measure RER, FWHM, MTF at Nyquist and effective resolution on an edge target.

    Runs the CEOS 12-step edge method (health checks first: an ROI that fails
    them reports the measured values and why, and no estimator). The window is read
    as `orthospec check` reads an edge target (nodata, mask, GSD from the transform).
    Without --roi or --map-roi (and without --whole) the straight edges are found
    automatically, an ROI that
    passes the health checks is grown around each, and the USGS combined
    RER = sqrt(RER_x * RER_y) is reported. Exit code 0 when the edge (or at least
    one found edge) is valid, 1 when the health checks fail, 2 when IMAGE, --roi
    or --band cannot be used.
    """
    from ..measures.edge import EdgeLimits, measure_edge
    from ..raster.roi import read_roi

    limits = EdgeLimits(min_snr=min_snr)
    if len(roi) > 1:
        _many(
            image,
            roi,
            band=band,
            gsd=gsd,
            nodata=nodata,
            bit_depth=bit_depth,
            limits=limits,
            as_json=as_json,
            workers=workers,
            map_roi=map_roi,
        )
        return
    roi1 = roi[0] if roi else None
    try:
        wanted = _parse_map_roi(map_roi, roi1) if map_roi is not None else _parse_roi(roi1)
        got = read_roi(image, window=wanted, band=band, nodata=nodata)
        window = got.window if wanted is not None else None
        gsd = gsd if gsd is not None else got.gsd_m
        if window is None and not whole:
            _auto(
                image,
                band,
                got.data,
                gsd=gsd,
                bit_depth=bit_depth,
                limits=limits,
                as_json=as_json,
                plots=plots,
            )
            return
        result = measure_edge(got.data, gsd=gsd, bit_depth=bit_depth, limits=limits)
        written: list[str] = []
        if plots:
            from ..figures.edge import edge_figures

            out = Path(plots)
            out.mkdir(parents=True, exist_ok=True)
            for stem, svg in edge_figures(got.values, result).items():
                target = out / f"edge_{stem}.svg"
                target.write_text(svg, encoding="utf-8")
                written.append(str(target))
    except OrthospecError as exc:
        raise _CouldNotRun(str(exc)) from exc
    except OSError as exc:
        raise _CouldNotRun(f"{image}: {exc}") from exc

    if as_json:
        doc = {
            "image": image,
            "band": band,
            "roi": list(window) if window else None,
            **result.to_dict(),
            "plots": written,
        }
        click.echo(json.dumps(doc, indent=2, sort_keys=True))
    else:
        _print_rich(image, window, band, result, written)
    if not result.valid:
        click.get_current_context().exit(1)


def _measure_one(job: tuple[Any, dict[str, Any]]) -> dict[str, Any]:
    """One ROI in a worker process: the flat JSON of its result (small to send back)."""
    from ..measures.edge import measure_edge

    data, kw = job
    return measure_edge(data, **kw).to_dict()


def _many(
    image: str,
    rois: tuple[str, ...],
    *,
    band: int,
    gsd: float | None,
    nodata: float | None,
    bit_depth: int | None,
    limits: Any,
    as_json: bool,
    workers: int | None,
    map_roi: str | None,
) -> None:
    """Several ROIs of one image in one call: read in order, measured in parallel processes
    (issue 31), reported in the order given."""
    import os
    from concurrent.futures import ProcessPoolExecutor

    from ..raster.roi import read_roi
    from ..workers import die_with_parent, mp_context

    if map_roi is not None:
        raise _CouldNotRun("give several --roi or one --map-roi, not both")
    try:
        windows = [_parse_roi(r) for r in rois]
        got = [read_roi(image, window=w, band=band, nodata=nodata) for w in windows]
    except OrthospecError as exc:
        raise _CouldNotRun(str(exc)) from exc
    except OSError as exc:
        raise _CouldNotRun(f"{image}: {exc}") from exc
    jobs = [
        (
            g.data,
            {"gsd": gsd if gsd is not None else g.gsd_m, "bit_depth": bit_depth, "limits": limits},
        )
        for g in got
    ]
    n = min(len(jobs), workers or os.cpu_count() or 1)
    try:
        if n > 1:
            with ProcessPoolExecutor(
                max_workers=n,
                mp_context=mp_context(),
                initializer=die_with_parent,
                initargs=(os.getpid(),),
            ) as pool:
                docs = list(pool.map(_measure_one, jobs))
        else:
            docs = [_measure_one(j) for j in jobs]
    except OrthospecError as exc:
        raise _CouldNotRun(str(exc)) from exc
    windows = [g.window for g in got]
    if as_json:
        out = {
            "image": image,
            "band": band,
            "workers": n,
            "rois": [{"roi": list(w), **d} for w, d in zip(windows, docs, strict=True)],
        }
        click.echo(json.dumps(out, indent=2, sort_keys=True))
    else:
        from rich.console import Console
        from rich.table import Table

        tab = Table(
            title=f"{image} band {band}: {len(docs)} ROIs ({n} worker(s)); value ± standard uncertainty"
        )
        for col in (
            "ROI x0,y0,x1,y1",
            "valid",
            "angle",
            "RER",
            "FWHM px",
            "MTF@Ny",
            "fit",
            "why not valid",
        ):
            tab.add_column(col)
        for w, d in zip(windows, docs, strict=True):
            tab.add_row(
                ",".join(map(str, w)),
                "yes" if d["valid"] else "no",
                _fmt(d["angle_deg"]),
                _pm(d, "rer"),
                _pm(d, "fwhm_px"),
                _pm(d, "mtf_nyquist"),
                d["primary_fit"] if d["valid"] else "",
                (d["reasons"] or "").split(";")[0],
            )
        Console(width=140).print(tab)
    if not any(d["valid"] for d in docs):
        click.get_current_context().exit(1)


def _pm(d: dict[str, Any], name: str) -> str:
    """value ± u of one estimator of a flat result."""
    if d.get(name) is None:
        return "n/a"
    u = d.get(f"{name}.u")
    return _fmt(d[name]) + ("" if u is None else f" ± {u:.2g}")


def _auto(
    image: str,
    band: int,
    arr: Any,
    *,
    gsd: float | None,
    bit_depth: int | None,
    limits: Any,
    as_json: bool,
    plots: str | None,
) -> None:
    """No ROI: find the edges, measure each, print them and the combined RER."""
    from ..measures.edge_detect import measure_target

    target = measure_target(arr, gsd=gsd, bit_depth=bit_depth, limits=limits)
    ok = any(e.result is not None and e.result.valid for e in target.edges)
    written: list[str] = []
    if plots:
        from ..figures.edge import edge_figures

        out = Path(plots)
        out.mkdir(parents=True, exist_ok=True)
        for i, e in enumerate(target.edges, start=1):
            if e.result is None or e.roi is None:
                continue
            for stem, svg in edge_figures(e.roi, e.result).items():
                path = out / f"edge{i}_{e.axis}_{stem}.svg"
                path.write_text(svg, encoding="utf-8")
                written.append(str(path))
    if as_json:
        doc = {
            "image": image,
            "band": band,
            "roi": None,
            "mode": "auto",
            **target.to_dict(),
            "plots": written,
        }
        click.echo(json.dumps(doc, indent=2, sort_keys=True))
    else:
        from rich.console import Console
        from rich.table import Table

        console = Console(width=120)
        console.print(
            f"{image} band {band}: {len(target.edges)} straight edge(s) found "
            "(no ROI given: automatic search)"
        )
        tab = Table(title="Edges (estimators normal to the edge; X = easting, Y = northing)")
        for col in (
            "profile",
            "line angle",
            "ROI x0,y0,x1,y1",
            "valid",
            "angle",
            "RER",
            "FWHM px",
            "MTF@Ny",
            "fit",
            "why not valid",
        ):
            tab.add_column(col)
        for e in target.edges:
            r = e.result
            if r is None:
                continue
            d = r.to_dict()
            tab.add_row(
                e.axis.upper(),
                f"{e.line_angle_deg:.2f}°",
                ",".join(map(str, e.window)),
                "yes" if r.valid else "no",
                _fmt(r.angle_deg),
                _pm(d, "rer"),
                _pm(d, "fwhm_px"),
                _pm(d, "mtf_nyquist"),
                r.primary_fit if r.valid else "",
                "; ".join(x.split(";")[0] for x in r.reasons),
            )
        console.print(tab)
        console.print(
            f"RER_x {_fmt(target.rer_x)}, RER_y {_fmt(target.rer_y)}, combined "
            f"sqrt(RER_x RER_y) {_fmt(target.rer_combined)} (USGS, seed 000)"
            + (f": {target.reason}" if target.reason else "")
        )
        for plot in written:
            console.print(f"wrote {plot}")
    if not ok:
        click.get_current_context().exit(1)


def _print_rich(image: str, window: Any, band: int, result: Any, written: list[str]) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from ..measures.edge import PSF_FITS

    console = Console(width=110)
    where = f"ROI {','.join(map(str, window))}" if window else "whole image"
    verdict = "[green]valid[/green]" if result.valid else "[red]INVALID[/red]"
    angle = "n/a" if result.angle_deg is None else f"{result.angle_deg:.3f}°"
    console.print(
        f"{image} band {band}, {where}: {verdict} — {result.direction} edge, "
        f"{result.polarity.replace('_', ' ')}, angle {angle}"
    )
    checks = Table(title="Health checks (seed 003 step 3)")
    for col in ("check", "measured", "limit", "unit", "result"):
        checks.add_column(col)
    for c in result.checks:
        lim = (
            f"[{c.limit[0]:g}, {c.limit[1]:g}]"
            if isinstance(c.limit, tuple)
            else f"{c.op} {c.limit:g}"
        )
        checks.add_row(
            c.name,
            _fmt(c.value),
            lim,
            c.unit,
            "[green]pass[/green]" if c.passed else "[red]fail[/red]",
        )
    console.print(checks)
    for reason in result.reasons:
        console.print(f"[red]- {reason}[/red]")
    for warning in result.warnings:
        console.print(f"[yellow]warning: {escape(warning)}[/yellow]")
    if result.estimates:
        fits = [
            result.primary_fit,
            *sorted({e.fit for e in result.estimates} - {result.primary_fit}),
        ]
        est = Table(title="Estimators (seed 003 steps 9-12; effective resolution: seed 004)")
        est.add_column("estimator")
        for fit in fits:
            est.add_column(f"{fit}{' (primary)' if fit == result.primary_fit else ''}")
            if fit == result.primary_fit:
                est.add_column("± u (standard)")
        est.add_column("unit")
        for e in result.estimates:
            if e.fit != result.primary_fit:
                continue
            row = [e.name]
            for fit in fits:
                other = result.estimate(e.name, fit)
                row.append(_fmt(other.value) if other is not None else "n/a")
                if fit == result.primary_fit:
                    row.append("" if e.u is None else f"± {e.u:.2g}")
            est.add_row(*row, e.unit)
        console.print(est)
        model = next((result.fits[n] for n in PSF_FITS if n in result.fits), None)
        if model is not None:
            q = model.params
            sig = ", ".join(f"{x:.4g}" for x in sorted(set(q["sigma_px"])))
            if "disk_radius_px" in q:
                sig += f"; disk radius {q['disk_radius_px']:.4g}"
            if "usm_amount" in q:
                sig += f"; unsharp mask amount {q['usm_amount']:.3g}, sigma {q['usm_sigma_px']:.3g}"
            console.print(
                f"PSF model {model.fit}: {escape(q['model'])}; sigma {sig} px; lack-of-fit "
                f"F = {q['lack_of_fit_f']:.3g}, p = {q['p_value']:.3g} "
                f"({'adequate' if q['adequate'] else 'rejected (p < 0.001): the spline is primary'})"
            )
            if q.get("candidates"):
                console.print(
                    "models the data cannot tell apart (leave-one-out error within one SE; "
                    "their spread is part of u): " + ", ".join(sorted(q["candidates"]))
                )
    for path in written:
        console.print(f"wrote {path}")
