"""Edge-target measures (CEOS WGCV IVOS 12 steps, USGS RER, Passini/Jacobsen effective resolution).

Edge targets are listed in the manifest (`edge_targets: [{id, image, roi, band}]`); each ROI is
read by :func:`orthospec.raster.roi.read_roi` (as `orthospec measure edge` reads it) and measured
by :func:`orthospec.measures.edge.measure_edge`.
A target without an ROI is searched for straight edges (issue 16 item 2,
:func:`orthospec.measures.edge_detect.measure_target`): every edge found feeds the USGS
combined RER, and the target's item reports its least sharp valid edge.
When a health check fails, the estimators of that target are *errors* with the reason, never
values reported as if valid.

Each target's detail also carries ``curves`` (:func:`edge_curves`): the detection, ESF, LSF and
MTF decimated and rounded so that the report can draw them from qcr.json alone (the report must
re-render from the stored document) while the document stays small (< ~30 kB per target).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ...errors import OrthospecError
from ...raster.roi import PixelWindow, RasterRoi, read_roi
from ..registry import Measured, ProviderContext, provider

if TYPE_CHECKING:  # the edge chain loads only to measure an edge
    from ...measures.edge import EdgeResult
    from ...measures.edge_detect import FoundEdge

HEALTH = {  # measure -> health check name in EdgeResult
    "edge.snr": ("snr", "1"),
    "edge.dn_difference": ("contrast", "DN"),
    "edge.angle": ("angle", "deg"),
    "edge.length_px": ("edge_length", "px"),
    "edge.bright_width_px": ("bright_width", "px"),
    "edge.dark_width_px": ("dark_width", "px"),
    "edge.straightness_px": ("straightness", "px"),
}
ESTIMATES = {  # measure -> estimator name
    "edge.rer": ("rer", "1"),
    "edge.fwhm": ("fwhm_px", "px"),
    "edge.fwhm25": ("width25_px", "px"),
    "edge.width80": ("width80_px", "px"),
    "edge.mtf_nyquist": ("mtf_nyquist", "1"),
    "edge.slope": ("edge_slope_per_px", "1"),
    "edge.effective_resolution_factor": ("effective_resolution_factor", "1"),
}
MEASURES = {
    "edge.valid": "bool",
    "edge.direction": "text",
    **{k: u for k, (_, u) in HEALTH.items()},
    **{k: u for k, (_, u) in ESTIMATES.items()},
}

# bounds of the stored curves: enough to draw them legibly, small enough for qcr.json
CURVE_DIGITS = 6  # significant digits of every stored number
MAX_ESF_SAMPLES = 300  # ESF pixel samples (of typically ~10^4)
MAX_LINES = 150  # per-line edge locations
FIT_STEP_PX = 0.05  # grid of the fitted ESF/LSF (a multiple of it for wide windows)
MAX_FIT_POINTS = 161
MTF_STEP = 0.02  # cycles/px, MTF stored at 0..1
MTF_MAX = 1.0


def _r(a: Any) -> list[float | None]:
    """Rounded to CURVE_DIGITS significant digits, NaN/inf -> None (JSON-safe, deterministic)."""
    return [
        float(f"{x:.{CURVE_DIGITS}g}") if np.isfinite(x) else None
        for x in np.asarray(a, dtype=float).ravel().tolist()
    ]


def _r1(x: float | None) -> float | None:
    return None if x is None else _r([x])[0]


def _pick(n: int, most: int) -> np.ndarray:
    """``most`` indices spread evenly over ``range(n)`` (all when n <= most), first and last kept."""
    if n <= most:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, most)).astype(int))


def edge_curves(res: EdgeResult) -> dict[str, Any]:
    """The curves of one edge for the report, from the result of the chain.

    ``lines``: per-line edge locations in ROI pixels (kept and rejected lines) and the end points
    of the fitted line; ``esf``: normalised pixel samples (0 dark, 1 bright) at their perpendicular
    distance within the fitted window +-1 px; ``fits``: per fit (primary first) the ESF and LSF on
    the grid ``x0 + i * dx`` px and the MTF at ``mtf_freq`` cycles/px, with the FWHM, its centre and
    the MTF at Nyquist. Everything is decimated deterministically (evenly spaced samples).
    """
    out: dict[str, Any] = {
        "shape": [int(res.shape[0]), int(res.shape[1])],
        "direction": res.direction,
        "angle_deg": _r1(res.angle_deg),
    }
    fin = np.isfinite(res.line_x) & np.isfinite(res.line_y)
    lines: dict[str, Any] = {}
    for key, sel in (("kept", res.line_kept & fin), ("rejected", ~res.line_kept & fin)):
        idx = np.flatnonzero(sel)
        idx = idx[_pick(idx.size, MAX_LINES)]
        lines[f"{key}_x"], lines[f"{key}_y"] = _r(res.line_x[idx]), _r(res.line_y[idx])
    ok = np.flatnonzero(np.isfinite(res.fitted_x) & np.isfinite(res.fitted_y))
    if ok.size:
        ends = ok[[0, -1]]
        lines["fit_x"], lines["fit_y"] = _r(res.fitted_x[ends]), _r(res.fitted_y[ends])
    out["lines"] = lines
    if (
        res.dark_level is not None
        and res.bright_level is not None
        and res.window_px
        and res.bright_level > res.dark_level
    ):
        lo, hi = res.window_px
        sel = (res.esf_d >= lo - 1) & (res.esf_d <= hi + 1)
        d = res.esf_d[sel]
        v = (res.esf_dn[sel] - res.dark_level) / (res.bright_level - res.dark_level)
        k = _pick(d.size, MAX_ESF_SAMPLES)
        out["esf"] = {
            "d": _r(d[k]),
            "v": _r(v[k]),
            "n_samples": int(d.size),
            "window_px": _r(res.window_px),
            "dark_start_px": _r1(res.dark_start_px),
            "bright_start_px": _r1(res.bright_start_px),
        }
    fits = _curve_fits(res)
    if fits:
        nf = round(MTF_MAX / MTF_STEP) + 1
        freq = np.round(np.arange(nf) * MTF_STEP, 10)
        out["mtf_freq"] = _r(freq)
        out["fits"] = {}
        from ...measures.edge import NYQUIST

        for f in fits:
            grid = float(np.median(np.diff(f.x))) if f.x.size > 1 else FIT_STEP_PX
            stride = max(1, round(FIT_STEP_PX / grid))
            stride *= max(1, int(np.ceil((f.x.size - 1) / stride / (MAX_FIT_POINTS - 1))))
            idx = np.arange(0, f.x.size, stride)
            out["fits"][f.fit] = {
                "x0": _r1(float(f.x[0])),
                "dx": _r1(grid * stride),
                "esf": _r(f.esf[idx]),
                "lsf": _r(f.lsf[idx]),
                "mtf": _r(np.interp(freq, f.mtf_freq, f.mtf)),
                "centre_px": _r1(f.centre_px),
                "fwhm_px": _r1(f.fwhm_px),
                "rer": _r1(f.rer),
                "mtf_nyquist": _r1(f.mtf_nyquist),
                "nyquist": NYQUIST,
            }
    return out


def _curve_fits(res: EdgeResult) -> list[Any]:
    """The primary fit and one to compare it with: the model-free spline, or (when the
    spline is primary) the PSF model, else the Fermi-Dirac fit. Every fit's values stay in
    the estimates; only two sets of curves are stored, to keep qcr.json bounded."""
    from ...measures.edge import PSF_FITS

    if res.primary_fit not in res.fits:
        return []
    order = ["spline", *PSF_FITS, *sorted(res.fits)]
    other = next((n for n in order if n in res.fits and n != res.primary_fit), None)
    return [res.fits[res.primary_fit], *([res.fits[other]] if other else [])]


def _measure_all(ctx: ProviderContext) -> dict[str, Any]:
    """Every edge target measured once per run (shared by the edge and delivery providers)."""
    if "edge.targets" not in ctx.memo:
        ctx.memo["edge.targets"] = _measure_targets(ctx)
    return ctx.memo["edge.targets"]


def _measure_targets(ctx: ProviderContext) -> dict[str, Any]:
    """Target id -> record (``result``, ``error`` or ``missing``, ``evidence``, ``file``).

    Each target is read by :func:`orthospec.raster.roi.read_roi`, as ``orthospec measure edge``
    reads it (validity from the file's nodata, mask or alpha band; GSD from a projected raster's
    transform, else the delivery's declared GSD), so both report the same numbers for one ROI.
    A target without an ROI (issue 16 item 2) is searched for straight edges
    (:func:`_auto_target`); its record adds ``edges`` (every edge found) and ``found`` (their
    summary, stored in the detail); no edge found is an error with the reason.
    """
    d = ctx.delivery
    imgs = d.table("images")
    files = (
        dict(zip(imgs.ids, imgs.df["file"].astype(str), strict=True)) if imgs is not None else {}
    )
    out: dict[str, Any] = {}
    for t in d.manifest.edge_targets:
        rel = files.get(t.image, t.image)
        rec: dict[str, Any] = {"file": rel}
        try:
            path = d.path(rel, what=f"edge target {t.id}")
            window = PixelWindow(*t.roi) if t.roi is not None else None
            got = read_roi(
                path,
                window=window,
                band=t.band,
                name=rel,
                max_pixels=None if window is not None else MAX_AUTO_PIXELS,
                too_large=f"edge target {t.id} has no ROI and the automatic edge search "
                "reads the whole band: give the target an roi [x0, y0, x1, y1] "
                "around its edges",
            )
            gsd = got.gsd_m if got.gsd_m is not None else d.gsd_m
            if window is None:
                out[t.id] = _auto_target(d, t, rel, got, gsd)
                continue
            from ...measures.edge import measure_edge

            rec["result"] = measure_edge(got.data, gsd=gsd)
            rec["evidence"] = (d.manifest_evidence(f"edge_targets.{t.id}"), d.evidence(rel))
        except (OrthospecError, OSError) as exc:
            rec["error"] = str(exc)
            rec["evidence"] = (d.manifest_evidence(f"edge_targets.{t.id}"),)
        out[t.id] = rec
    return out


def _auto_target(d: Any, t: Any, rel: str, got: RasterRoi, gsd: float | None) -> dict[str, Any]:
    """The record of a target image without an ROI: its edges found and measured.

    The whole band is read masked (declared nodata and masks bound the search); without any,
    :func:`measure_target` detects a zero fill connected to the border.
    Every edge found is kept in ``edges`` (the USGS combined RER uses them all); the target's
    own item reports the valid edge with the lowest RER (the least sharp edge: a per-target
    ``>=`` RER or ``<=`` width rule then judges the worst edge, never a flattering one), or,
    when none is valid, the first edge found (its failed health checks are the reason).
    """
    from ...measures.edge_detect import measure_target

    target = measure_target(got.data, gsd=gsd)
    ev = (d.manifest_evidence(f"edge_targets.{t.id}"), d.evidence(rel))
    found = [e for e in target.edges if e.result is not None]
    if not found:
        return {
            "file": rel,
            "evidence": ev,
            "missing": f"{rel}: no straight edge found in band {t.band} (edge target {t.id} has "
            "no ROI, so its edges are searched automatically)",
        }

    def rer(e: FoundEdge) -> float:
        return (
            float(e.result.rer)
            if e.result is not None and e.result.rer is not None
            else float("inf")
        )

    valid = [
        e for e in found if e.result is not None and e.result.valid and e.result.rer is not None
    ]
    pick = min(valid, key=rer) if valid else found[0]
    summary = [{k: v for k, v in e.to_dict().items() if k in _FOUND_KEYS} for e in found]
    return {
        "file": rel,
        "evidence": ev,
        "result": pick.result,
        "edges": [e.result for e in found],
        "found": {
            "edges": summary,
            "reported": found.index(pick),
            "rer_x": target.rer_x,
            "rer_y": target.rer_y,
            "rer_combined": target.rer_combined,
            "choice": "the valid edge with the lowest RER (else the first edge found)",
        },
    }


# a target without ROI is read whole (float64 plus the Canny/Hough work arrays): a target chip,
# not an orthophoto tile; 2048 x 2048 px keeps it to ~100 MB and a few seconds
MAX_AUTO_PIXELS = 2048 * 2048
_FOUND_KEYS = (
    "segment",
    "line_angle_deg",
    "axis",
    "direction",
    "roi",
    "half_width_px",
    "valid",
    "rer",
    "fwhm_px",
    "mtf_nyquist",
    "angle_deg",
    "reasons",
)


@provider(scope="edge", measures=MEASURES)
def edge_measures(ctx: ProviderContext) -> list[Measured]:
    """Health checks and estimators of every edge target (ESF/LSF/MTF chain)."""
    got = _measure_all(ctx)
    ev = pd.Series({k: v["evidence"] for k, v in got.items()}, dtype=object)
    out = []
    detail = {
        k: {
            **v["result"].to_dict(),
            "curves": edge_curves(v["result"]),
            **({"found": v["found"]} if "found" in v else {}),
        }
        for k, v in got.items()
        if "result" in v
    }
    for name, unit in MEASURES.items():
        vals: dict[str, Any] = {}
        errs: dict[str, str] = {}
        why: dict[str, str] = {}
        for tid, rec in got.items():
            if "missing" in rec:  # nothing to measure (no edge found): missing, not an input error
                vals[tid], why[tid] = None, rec["missing"]
                continue
            if "error" in rec:
                vals[tid], errs[tid] = None, rec["error"]
                continue
            res = rec["result"]
            if name == "edge.valid":
                vals[tid] = res.valid
            elif name == "edge.direction":
                vals[tid] = res.direction
            elif name in HEALTH:
                vals[tid] = res.check(HEALTH[name][0]).value
            else:
                if not res.valid:
                    vals[tid], errs[tid] = (
                        None,
                        "edge health checks failed: " + "; ".join(res.reasons),
                    )
                else:
                    e = res.estimate(ESTIMATES[name][0])
                    vals[tid] = None if e is None else e.value
        out.append(
            Measured(
                name,
                "edge",
                unit,
                pd.Series(vals, dtype=object),
                ev,
                detail={"edges": detail} if name == "edge.valid" and detail else None,
                errors=pd.Series(errs, dtype=object) if errs else None,
                notes=pd.Series(why, dtype=object) if why else None,
            )
        )
    return out


COMBINED = {"edge.rer_combined": "1", "edge.giqe4_niirs": "1"}


@provider(scope="delivery", measures=COMBINED)
def edge_combined(ctx: ProviderContext) -> list[Measured]:
    """USGS two-direction RER and the GIQE 4 NIIRS it predicts, over the delivery's edge targets.

    USGS (seed 000): RER = sqrt([ER_x(0.5) - ER_x(-0.5)][ER_y(0.5) - ER_y(-0.5)]). RER_x is
    the median RER of the valid targets profiled along x (``direction`` across: edge near
    the columns), RER_y of those profiled along y. GIQE 4 (Leachtenauer et al. 1997) from
    the GSD, that RER, the geometric-mean overshoot H of the same fits, G = 1 (no declared
    sharpening) and the median edge SNR; its inputs are recorded in the note.
    """
    from ...measures.edge import rer_two_directions
    from ...measures.giqe import giqe4

    d = ctx.delivery
    got = _measure_all(ctx)
    ev = tuple(e for rec in got.values() for e in rec["evidence"])
    by_axis: dict[str, list[Any]] = {"across": [], "along": []}
    for rec in got.values():
        for res in rec.get("edges", [rec.get("result")]):  # a target without ROI: all its edges
            if res is not None and res.valid and res.rer is not None:
                by_axis[res.direction].append(res)
    vals: dict[str, Any] = dict.fromkeys(COMBINED)
    notes: dict[str, str] = {}
    if not got:
        why = "no edge targets listed"
    elif not by_axis["across"] or not by_axis["along"]:
        missing = [
            n
            for n, k in (("X (profile along x)", "across"), ("Y (profile along y)", "along"))
            if not by_axis[k]
        ]
        why = f"no valid edge target measured in {' and '.join(missing)}"
    else:
        why = ""
        rx = float(np.median([r.rer for r in by_axis["across"]]))
        ry = float(np.median([r.rer for r in by_axis["along"]]))
        rer = float(rer_two_directions(rx, ry))
        vals["edge.rer_combined"] = rer
        notes["edge.rer_combined"] = (
            f"sqrt(RER_x {rx:.4f} x RER_y {ry:.4f}) over "
            f"{len(by_axis['across'])} + {len(by_axis['along'])} edges"
        )
        h = [r.estimate("overshoot_h") for r in by_axis["across"] + by_axis["along"]]
        hx = [e.value for e in h if e is not None]
        gsds = [r.gsd_m for r in by_axis["across"] + by_axis["along"] if r.gsd_m]
        gsd = float(np.median(gsds)) if gsds else d.gsd_m
        snr = float(np.median([r.check("snr").value for r in by_axis["across"] + by_axis["along"]]))
        if gsd and hx:
            hgm = float(np.exp(np.mean(np.log(hx))))
            g = giqe4(gsd_m=float(gsd), rer=rer, overshoot=hgm, noise_gain=1.0, snr=snr)
            vals["edge.giqe4_niirs"] = g.niirs
            notes["edge.giqe4_niirs"] = (
                "GIQE 4 (Leachtenauer et al. 1997): "
                + ", ".join(f"{k} {v:.4g}" for k, v in g.inputs.items())
                + "; G = 1 assumed (no declared "
                "sharpening), SNR = median edge SNR"
            )
        else:
            notes["edge.giqe4_niirs"] = "no GSD known for the edge targets"
    for n in COMBINED:
        if vals[n] is None and why:
            notes[n] = why
    item = d.id
    return [
        Measured(
            n,
            "delivery",
            u,
            pd.Series({item: vals[n]}, dtype=object),
            pd.Series({item: ev}, dtype=object),
            notes=pd.Series({item: notes[n]}, dtype=object) if n in notes else None,
        )
        for n, u in COMBINED.items()
    ]
