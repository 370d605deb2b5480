"""Edge-target measures (CEOS WGCV IVOS 12 steps, USGS RER, Passini/Jacobsen effective resolution).

Edge targets are listed in the manifest (`edge_targets: [{id, image, roi, band}]`); each ROI is
read with one windowed rasterio read and measured by :func:`orthospec.measures.edge.measure_edge`.
When a health check fails, the estimators of that target are *errors* with the reason, never
values reported as if valid.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import rasterio
from rasterio.windows import Window

from ...errors import OrthospecError
from ...measures.edge import measure_edge
from ...raster.reading import read_only_env
from ..registry import Measured, ProviderContext, provider

HEALTH = {  # measure -> health check name in EdgeResult
    "edge.snr": ("snr", "1"), "edge.dn_difference": ("contrast", "DN"), "edge.angle": ("angle", "deg"),
    "edge.length_px": ("edge_length", "px"), "edge.bright_width_px": ("bright_width", "px"),
    "edge.dark_width_px": ("dark_width", "px"), "edge.straightness_px": ("straightness", "px"),
}
ESTIMATES = {  # measure -> estimator name
    "edge.rer": ("rer", "1"), "edge.fwhm": ("fwhm_px", "px"), "edge.fwhm25": ("width25_px", "px"),
    "edge.width80": ("width80_px", "px"), "edge.mtf_nyquist": ("mtf_nyquist", "1"),
    "edge.slope": ("edge_slope_per_px", "1"),
    "edge.effective_resolution_factor": ("effective_resolution_factor", "1"),
}
MEASURES = {"edge.valid": "bool", "edge.direction": "text",
            **{k: u for k, (_, u) in HEALTH.items()}, **{k: u for k, (_, u) in ESTIMATES.items()}}


def _measure_all(ctx: ProviderContext) -> dict[str, Any]:
    d = ctx.delivery
    imgs = d.table("images")
    files = dict(zip(imgs.ids, imgs.df["file"].astype(str), strict=True)) if imgs is not None else {}
    out: dict[str, Any] = {}
    for t in d.manifest.edge_targets:
        rel = files.get(t.image, t.image)
        x0, y0, x1, y1 = t.roi
        rec: dict[str, Any] = {"file": rel}
        try:
            path = d.path(rel, what=f"edge target {t.id}")
            with read_only_env(), rasterio.open(path) as ds:
                if not 1 <= t.band <= ds.count:
                    raise OrthospecError(f"{rel}: band {t.band} does not exist ({ds.count} bands)")
                if not (0 <= x0 < x1 <= ds.width and 0 <= y0 < y1 <= ds.height):
                    raise OrthospecError(f"{rel}: ROI {t.roi} is outside the image ({ds.width} x {ds.height})")
                roi = ds.read(t.band, window=Window(x0, y0, x1 - x0, y1 - y0), masked=True)
                gsd = abs(ds.transform.a) if ds.crs is not None and ds.crs.is_projected else d.gsd_m
            arr = roi.filled(np.nan).astype(float) if np.ma.isMaskedArray(roi) else roi.astype(float)
            rec["result"] = measure_edge(arr, gsd=gsd)
            rec["evidence"] = (d.manifest_evidence(f"edge_targets.{t.id}"), d.evidence(rel))
        except (OrthospecError, OSError, rasterio.errors.RasterioError) as exc:
            rec["error"] = str(exc)
            rec["evidence"] = (d.manifest_evidence(f"edge_targets.{t.id}"),)
        out[t.id] = rec
    return out


@provider(scope="edge", measures=MEASURES)
def edge_measures(ctx: ProviderContext) -> list[Measured]:
    """Health checks and estimators of every edge target (ESF/LSF/MTF chain)."""
    got = _measure_all(ctx)
    ev = pd.Series({k: v["evidence"] for k, v in got.items()}, dtype=object)
    out = []
    detail = {k: v["result"].to_dict() for k, v in got.items() if "result" in v}
    for name, unit in MEASURES.items():
        vals: dict[str, Any] = {}
        errs: dict[str, str] = {}
        for tid, rec in got.items():
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
                    vals[tid], errs[tid] = None, "edge health checks failed: " + "; ".join(res.reasons)
                else:
                    e = res.estimate(ESTIMATES[name][0])
                    vals[tid] = None if e is None else e.value
        out.append(Measured(name, "edge", unit, pd.Series(vals, dtype=object), ev,
                            detail={"edges": detail} if name == "edge.valid" and detail else None,
                            errors=pd.Series(errs, dtype=object) if errs else None))
    return out


