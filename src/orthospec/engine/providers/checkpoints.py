"""Block-level checkpoint statistics (JRC §12.5-§12.7, USGS, NSSDA) and per-point blunder decisions.

Adapts the delivery's checkpoints (and GCPs, block polygons, contractor-reported values) to the pure
functions of :mod:`orthospec.measures.accuracy` and :mod:`orthospec.measures.distribution`.
Official block statistics drop only *justified* blunder exclusions (§12.6); ``*_all`` keep every point.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from shapely.geometry import Polygon

from ...errors import MeasureError
from ...measures.accuracy import AccuracyStats, bias_significance, detect_blunders
from ...measures.distribution import checkpoint_distribution
from ...provenance import Evidence
from ...units import convert
from ..registry import Measured, ProviderContext, RowEvidence, provider

_STATS = {
    "n": "1", "rmse_x": "L", "rmse_y": "L", "rmse_z": "L", "rmse_r": "L", "mean_x": "L", "mean_y": "L",
    "mean_z": "L", "std_x": "L", "std_y": "L", "std_z": "L", "max_abs_dx": "L", "max_abs_dy": "L",
    "max_abs_dz": "L", "max_dr": "L", "ce90": "L", "ce95": "L", "ce90_selected": "L",
    "ce95_selected": "L", "ce90_empirical": "L", "ce95_empirical": "L", "nssda_horizontal_95": "L",
    "nssda_vertical_95": "L", "nssda_ratio": "1", "bias_ratio": "1",
}
BLOCK_MEASURES: dict[str, str] = {f"checkpoints.{k}": ("m" if u == "L" else u) for k, u in _STATS.items()}
BLOCK_MEASURES.update({
    "checkpoints.rmse_x_all": "m", "checkpoints.rmse_y_all": "m", "checkpoints.rmse_z_all": "m",
    "checkpoints.n_all": "1", "checkpoints.excluded": "1", "checkpoints.blunders": "1",
    "checkpoints.blunders_unjustified": "1", "checkpoints.blunders_uninspected": "1",
    "checkpoints.bias_negligible": "bool",
    "checkpoints.nssda_approximation_holds": "bool",
    "checkpoints.rmse_x_gsd": "px", "checkpoints.rmse_y_gsd": "px",
    "checkpoints.quadrant_min_share": "%", "checkpoints.spacing_ratio": "1",
    "checkpoints.min_gcp_distance": "m", "checkpoints.near_gcp": "1", "checkpoints.outside_block": "1",
    "checkpoints.reported_diff_x": "m", "checkpoints.reported_diff_y": "m",
    "checkpoints.reported_diff_z": "m",
    "checkpoints.asprs_rmse_h": "m", "checkpoints.asprs_rmse_v": "m",
    # systematic error (JRC §12.4; seed 000 bias): Student t of the mean error and its p-value
    "checkpoints.bias_t_x": "1", "checkpoints.bias_t_y": "1", "checkpoints.bias_t_z": "1",
    "checkpoints.bias_p_x": "1", "checkpoints.bias_p_y": "1", "checkpoints.bias_p_z": "1",
})
POINT_MEASURES = {
    "checkpoint.dx": "m", "checkpoint.dy": "m", "checkpoint.dz": "m", "checkpoint.dr": "m",
    "checkpoint.blunder_ok": "bool", "checkpoint.decision": "text",
}


def _param(ctx: ProviderContext, name: str, default: Any, unit: str | None = None) -> Any:
    v = ctx.parameters.get(name)
    if v is None:
        return default
    if unit and hasattr(v, "to"):
        return float(v.to(unit).magnitude)
    return getattr(v, "magnitude", v)


def _compute(ctx: ProviderContext) -> dict[str, Any]:
    if "checkpoints" not in ctx.memo:
        ctx.memo["checkpoints"] = _compute_once(ctx)
    return ctx.memo["checkpoints"]


def _compute_once(ctx: ProviderContext) -> dict[str, Any]:
    d = ctx.delivery
    t = d.table("checkpoints")
    if t is None:
        return {"missing": "the manifest declares no 'checkpoints' table"}
    df = t.df
    unit = t.units.get("x", "m")
    to_m = float(convert([1.0], unit, "m")[0])
    gcps = d.table("gcps")
    polys = {}
    bad_polygon: dict[str, str] = {}
    for b in d.manifest.blocks:
        if b.polygon and len(b.polygon) >= 3:
            xy = np.asarray(b.polygon, dtype=float)
            if not np.isfinite(xy).all():
                row = int(np.flatnonzero(~np.isfinite(xy).all(axis=1))[0])
                # a broken outline makes the block's statistics untrustworthy: error, never a pass
                bad_polygon[b.id] = (f"delivery.yaml blocks[{b.id}].polygon vertex {row + 1} is not a finite "
                                     f"number ({b.polygon[row]}): the block cannot be checked")
                continue
            polys[b.id] = Polygon([(float(x) * to_m, float(y) * to_m) for x, y in b.polygon])
    basis = str(_param(ctx, "blunder_basis", "calculated"))
    factor = float(_param(ctx, "blunder_factor", 3.0))
    target = _param(ctx, "tolerance_xy", None, "m")
    target_z = _param(ctx, "tolerance_z", None, "m")
    min_gcp = float(_param(ctx, "min_checkpoint_gcp_distance", 0.0, "m") or 0.0)
    min_count = int(_param(ctx, "min_checkpoints", 20))
    gsd = d.gsd_m
    blocks: dict[str, dict[str, Any]] = {}
    # per-point results as arrays, one entry per block in block order (no Python object per point)
    points: list[dict[str, Any]] = []
    table_detail: dict[str, list[dict[str, Any]]] = {}
    for block, g in df.groupby(df["block"].astype(str), sort=True):
        row_arr = g["_row"].to_numpy()
        rows = tuple(row_arr.astype(np.int64).tolist())
        ev = (Evidence(t.file, t.sha256, rows),)
        ids = g["point_id"].astype(str).to_numpy()
        dx = (g["x"].to_numpy(float) - g["x_ref"].to_numpy(float)) * to_m
        dy = (g["y"].to_numpy(float) - g["y_ref"].to_numpy(float)) * to_m
        dz = None
        if "z" in g and "z_ref" in g:
            zz = (g["z"].astype(float) - g["z_ref"].astype(float)).to_numpy(float) * to_m
            dz = None if np.isnan(zz).all() else zz
        excl: dict[str, str | None] = {}
        if "excluded" in g:
            flags = _is_true(g["excluded"])
            if flags.any():
                whys = (g["exclusion_reason"][flags].tolist() if "exclusion_reason" in g
                        else [None] * int(flags.sum()))
                excl = dict(zip(ids[flags].tolist(), whys, strict=True))
        out: dict[str, Any] = {"evidence": ev}
        if block in bad_polygon:
            out["error"] = bad_polygon[block]
            blocks[block] = out
            continue
        try:
            br = detect_blunders(dx, dy, dz, ids=ids, basis=basis if basis in ("calculated", "target")
                                 else "calculated", factor=factor, target_rmse_xy=target,
                                 target_rmse_z=target_z, exclusions=excl, gsd=gsd, unit="m")
        except MeasureError as exc:
            out["error"] = f"{t.file}: block {block}: {exc}"
            blocks[block] = out
            continue
        st: AccuracyStats = br.stats_kept or br.stats_all
        for k in _STATS:
            out[f"checkpoints.{k}"] = getattr(st, k) if k in st.__dataclass_fields__ else st.to_dict().get(k)
        out["checkpoints.ce90_selected"] = st.ce90_selected
        out["checkpoints.ce95_selected"] = st.ce95_selected
        out["checkpoints.bias_negligible"] = st.bias_negligible
        out["checkpoints.nssda_approximation_holds"] = st.nssda_approximation_holds
        for axis in ("x", "y", "z"):
            t_stat, p_val = bias_significance(getattr(st, f"mean_{axis}"), getattr(st, f"std_{axis}"), st.n)
            out[f"checkpoints.bias_t_{axis}"], out[f"checkpoints.bias_p_{axis}"] = t_stat, p_val
        out["checkpoints.rmse_x_all"] = br.stats_all.rmse_x
        out["checkpoints.rmse_y_all"] = br.stats_all.rmse_y
        out["checkpoints.rmse_z_all"] = br.stats_all.rmse_z
        out["checkpoints.n_all"] = br.stats_all.n
        out["checkpoints.excluded"] = len(br.excluded)
        out["checkpoints.blunders"] = len(br.candidates)
        out["checkpoints.blunders_unjustified"] = len(br.error_ids)
        # a candidate excluded with a documented justification has been inspected (§12.6)
        out["checkpoints.blunders_uninspected"] = len(set(br.candidates) - set(br.excluded))
        # ASPRS Ed. 2: product accuracy combines the checkpoint survey's own error (RMSE_H2, RMSE_V2)
        survey_h = float(_param(ctx, "survey_rmse_h", 0.0, "m") or 0.0)
        survey_v = float(_param(ctx, "survey_rmse_v", 0.0, "m") or 0.0)
        out["checkpoints.asprs_rmse_h"] = float(np.sqrt(st.rmse_x ** 2 + st.rmse_y ** 2 + survey_h ** 2))
        out["checkpoints.asprs_rmse_v"] = (None if st.rmse_z is None
                                           else float(np.sqrt(st.rmse_z ** 2 + survey_v ** 2)))
        if gsd:
            out["checkpoints.rmse_x_gsd"] = st.rmse_x / gsd
            out["checkpoints.rmse_y_gsd"] = st.rmse_y / gsd
        gx = gy = gids = None
        if gcps is not None:
            gg = gcps.df[gcps.df["block"].astype(str) == block]
            gunit = float(convert([1.0], gcps.units.get("x", "m"), "m")[0])
            gx, gy = gg["x"].to_numpy(float) * gunit, gg["y"].to_numpy(float) * gunit
            gids = gg["point_id"].astype(str).to_numpy()
        try:
            dist = checkpoint_distribution(
                g["x_ref"].to_numpy(float) * to_m, g["y_ref"].to_numpy(float) * to_m, ids=ids,
                area=polys.get(block), gcp_x=gx, gcp_y=gy, gcp_ids=gids, min_gcp_distance=min_gcp,
                footprint=polys.get(block), min_count=min_count)
            out["checkpoints.quadrant_min_share"] = dist.min_quadrant_share * 100.0
            out["checkpoints.spacing_ratio"] = dist.nn_min_ratio
            out["checkpoints.min_gcp_distance"] = dist.gcp_min_distance
            out["checkpoints.near_gcp"] = len(dist.too_close_to_gcp) + len(dist.identical_to_gcp)
            out["checkpoints.outside_block"] = len(dist.outside_footprint) if polys.get(block) else None
            out["distribution_source"] = dist.split_source
        except MeasureError as exc:
            out["distribution_error"] = str(exc)
        limit = (br.limit_x, br.limit_y)
        points.append({"ids": ids, "dx": dx, "dy": dy, "dz": dz, "dr": br.dr, "ok": ~br.is_error,
                       "decision": br.decision, "reason": br.reasons, "rows": row_arr})
        xr = (g["x_ref"].to_numpy(float) * to_m).tolist()
        yr = (g["y_ref"].to_numpy(float) * to_m).tolist()
        dzl = [None] * len(ids) if dz is None else dz.tolist()
        status = np.where(br.candidate, "fail", "pass").tolist()
        detail = [
            {"point_id": pid, "dx": a, "dy": b, "dz": c, "dr": r, "x_ref": xx, "y_ref": yy, "status": st_,
             "decision": dec, "row": row}
            for pid, a, b, c, r, xx, yy, st_, dec, row in zip(
                ids.tolist(), dx.tolist(), dy.tolist(), dzl, br.dr.tolist(), xr, yr, status,
                br.decision.tolist(), row_arr.tolist(), strict=True)]
        table_detail[block] = {
            "points": detail,
            "limit_x": limit[0], "limit_y": limit[1], "basis": br.basis, "unit": "m",
            "stats": {k: out.get(f"checkpoints.{k}") for k in ("n", "mean_x", "mean_y", "std_x", "std_y",
                                                               "rmse_x", "rmse_y", "rmse_z", "max_abs_dx",
                                                               "max_abs_dy", "max_dr")},
            "gcps": [] if gx is None else [{"point_id": str(a), "x": float(b), "y": float(c)}
                                           for a, b, c in zip(gids, gx, gy, strict=True)],
            "area_source": out.get("distribution_source"),
            # the block outline (manifest blocks[].polygon, same units as x_ref/y_ref) for the report's map
            "polygon": ([[float(px), float(py)] for px, py in polys[block].exterior.coords[:-1]]
                        if block in polys else None),
        }
        # reported vs recomputed (a disagreement is itself a finding)
        rep = next((b.reported for b in d.manifest.blocks if b.id == block and b.reported), None)
        for axis in ("x", "y", "z"):
            key = f"rmse_{axis}"
            if rep and key in rep and getattr(st, key) is not None:
                rv = float(convert([rep[key].value], rep[key].unit, "m")[0])
                out[f"checkpoints.reported_diff_{axis}"] = abs(rv - float(getattr(st, key)))
                out[f"reported_{axis}"] = rv
        blocks[block] = out
    return {"blocks": blocks, "points": points, "detail": table_detail}


def _is_true(col: pd.Series) -> np.ndarray:
    """Mask of cells that are the boolean True (the table parser's value), never a truthy string."""
    v = col.to_numpy()
    if v.dtype.kind == "b":
        return v.astype(bool, copy=False)
    if v.dtype == object:
        return np.fromiter((f is True or f is np.True_ for f in v), dtype=bool, count=len(v))
    return np.zeros(len(v), dtype=bool)


@provider(scope="block", measures=BLOCK_MEASURES)
def block_checkpoint_stats(ctx: ProviderContext) -> list[Measured]:
    """Checkpoint statistics per block (RMSE, CE, NSSDA, bias, blunders, distribution)."""
    got = _compute(ctx)
    d = ctx.delivery
    items = d.block_ids
    out = []
    if "missing" in got:
        note = pd.Series({b: got["missing"] for b in items}, dtype=object)
        for name, unit in BLOCK_MEASURES.items():
            out.append(Measured(name, "block", unit, pd.Series({b: None for b in items}, dtype=object),
                                pd.Series({b: (d.manifest_evidence("tables"),) for b in items}, dtype=object),
                                notes=note))
        return out
    blocks = got["blocks"]
    for name, unit in BLOCK_MEASURES.items():
        vals, evs, notes, errs, na = {}, {}, {}, {}, {}
        for b in items:
            rec = blocks.get(b)
            if rec is None:
                vals[b], evs[b] = None, (d.manifest_evidence("blocks"),)
                notes[b] = f"no checkpoints for block {b}"
                continue
            evs[b] = rec["evidence"]
            if "error" in rec:
                vals[b], errs[b] = None, rec["error"]
                continue
            vals[b] = rec.get(name)
            if name.startswith("checkpoints.reported_diff_"):
                axis = name[-1]
                if vals[b] is None and axis in ("x", "y"):
                    # the checkpoint RMSE is a QCR field the contractor must record (JRC §9.5): not
                    # reporting it must not switch the cross-check off - missing evidence
                    notes[b] = (f"delivery.yaml blocks[{b}].reported gives no rmse_{axis}: the contractor's "
                                "QCR value to cross-check is missing")
                elif vals[b] is None:
                    na[b] = f"block {b} reports no rmse_{axis}"
                else:
                    notes[b] = (f"reported RMSE_{axis} {rec[f'reported_{axis}']:.4g} m vs recomputed "
                                f"{rec[f'checkpoints.rmse_{axis}']:.4g} m")
            elif vals[b] is None and "distribution_error" in rec and name in (
                    "checkpoints.quadrant_min_share", "checkpoints.spacing_ratio"):
                notes[b] = rec["distribution_error"]
        out.append(Measured(
            name, "block", unit, pd.Series(vals, dtype=object), pd.Series(evs, dtype=object),
            detail={"checkpoints": got["detail"]} if name == "checkpoints.rmse_x" else None,
            notes=pd.Series(notes, dtype=object) if notes else None,
            errors=pd.Series(errs, dtype=object) if errs else None,
            na=pd.Series(na, dtype=object) if na else None))
    return out


@provider(scope="checkpoint", measures=POINT_MEASURES)
def point_decisions(ctx: ProviderContext) -> list[Measured]:
    """Per-checkpoint discrepancies and blunder/exclusion decisions (one QCR per point, §12.6)."""
    got = _compute(ctx)
    parts: list[dict[str, Any]] = got.get("points", [])
    ids = _cat([p["ids"] for p in parts], object)
    # a point id repeated across blocks: one item, at its first position, with the last block's values
    keep = None
    if len(ids) and pd.Index(ids).has_duplicates:
        idx = pd.Index(ids)
        last = np.flatnonzero(~idx.duplicated(keep="last"))
        first_ids = idx[~idx.duplicated(keep="first")]
        keep = last[pd.Index(ids[last]).get_indexer(first_ids)]
    rows = _cat([p["rows"] for p in parts], np.int64)
    dz_parts = [p["dz"] for p in parts]
    if all(z is not None for z in dz_parts):
        dz = _cat(dz_parts, float)
    else:
        dz = _cat([np.full(len(p["ids"]), None, dtype=object) if p["dz"] is None
                   else p["dz"].astype(object) for p in parts], object)
    cols: dict[str, np.ndarray] = {
        "checkpoint.dx": _cat([p["dx"] for p in parts], float),
        "checkpoint.dy": _cat([p["dy"] for p in parts], float),
        "checkpoint.dz": dz,
        "checkpoint.dr": _cat([p["dr"] for p in parts], float),
        # Python booleans, as the rules' `true`/`false` comparisons and the records expect
        "checkpoint.blunder_ok": _cat([p["ok"] for p in parts], bool).astype(object),
        "checkpoint.decision": _cat([p["decision"] for p in parts], object),
    }
    reason = _cat([p["reason"] for p in parts], object)
    if keep is not None:
        ids, rows, reason = ids[keep], rows[keep], reason[keep]
        cols = {k: v[keep] for k, v in cols.items()}
    index = pd.Index(ids, dtype=object)
    t = ctx.delivery.table("checkpoints")
    ev = RowEvidence(t.file, t.sha256, pd.Series(rows, index=index)) if t is not None else \
        pd.Series([], dtype=object)
    notes = pd.Series(reason, index=index, dtype=object)
    return [Measured(name, "checkpoint", unit, pd.Series(cols[name], index=index), ev,
                     notes=notes if name in ("checkpoint.blunder_ok", "checkpoint.decision") else None)
            for name, unit in POINT_MEASURES.items()]


def _cat(arrays: list[np.ndarray], dtype: Any) -> np.ndarray:
    return np.concatenate(arrays).astype(dtype, copy=False) if arrays else np.empty(0, dtype=dtype)
