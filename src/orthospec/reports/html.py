"""The auditor's report as HTML: a view model computed from qcr.json alone, rendered by Jinja2.

Everything here reads the QCR document (never an ``Evaluation``), so a stored ``qcr.json`` can be
re-rendered years later. The same view model feeds the PDF (``pdf.py``); ``bounded=True`` keeps
its tables short (failing items in full, passing items summarised per rule with counts) because
the complete data travels as attachments.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import jinja2
import markupsafe

from .. import verdicts as V
from ..present import NO_VALUE, cite, fmt_fixed, fmt_measured, fmt_value, unit_suffix
from ..qcr import all_records, dumps, natural_key, point_rows, where_text
from ..resources import templates_dir
from .contract import contract_lines
from .findings import NotApplicableSummary, by_reason, checker_text, unsigned_manual_note
from .findings import findings as find_problems

__all__ = ["ReportOptions", "document_sha256", "environment", "render_html", "report_context"]

# verdicts the auditor must read first, worst first
PROBLEM_VERDICTS = V.PROBLEMS
VERDICT_ORDER = {v: i for i, v in enumerate(V.SEVERITY)}
SCOPE_TITLES = {"delivery": "Delivery", "project": "Project", "block": "Blocks", "image": "Images",
                "band": "Bands", "checkpoint": "Checkpoints", "gcp": "Ground control points",
                "flight": "Flights", "camera": "Cameras", "scanner": "Scanners", "dem": "DEM",
                "mosaic": "Mosaic", "edge": "Edge targets"}


@dataclass(frozen=True)
class ReportOptions:
    """How much of the document the tables show.

    ``bounded`` (the PDF): passing records are summarised per rule; checkpoint tables longer than
    ``max_points`` show their failing points only. Otherwise (HTML) passing records are listed
    up to ``max_pass_rows`` per rule. Figures are drawn for at most ``max_figure_blocks`` blocks
    (rejected blocks first, then by points above the limit and RMSE): drawing and embedding a
    figure costs about a second, so a national delivery shows its worst blocks, and the attached
    checkpoints.csv holds every point. Edge targets likewise: the ESF/LSF/MTF figures of at most
    ``max_figure_edges`` targets (failing or erring targets first), their values all tabulated.
    The HTML's checkpoint table of a block lists every point that did not pass and the first
    passing ones up to ``max_table_points`` rows (30,000 rows were 8 MB of a 26 MB page).
    """

    bounded: bool = False
    max_pass_rows: int = 2000
    max_points: int = 10
    max_rule_rows: int = 8
    max_figure_blocks: int = 6
    max_figure_edges: int = 6
    max_table_points: int = 1000
    figures: bool = True


#: Keys a report may carry beside the QCR document (from the ledger); never part of qcr.json.
CONTEXT_KEYS = ("signoffs", "history", "ledger", "after_signoff")
#: findings shown on page 1 (the rest in section 1)
PAGE1_FINDINGS = 8


def canonical_qcr(doc: dict[str, Any]) -> str:
    """qcr.json text as ``orthospec check`` writes it, without the ledger context added later."""
    return dumps({k: v for k, v in doc.items() if k not in CONTEXT_KEYS})


def document_sha256(doc: dict[str, Any]) -> str:
    """The report checksum: SHA-256 of :func:`canonical_qcr` (``sha256sum qcr.json`` agrees).

    Sign-offs are excluded so a countersignature can cite the checksum of what it signs.
    """
    return hashlib.sha256(canonical_qcr(doc).encode("utf-8")).hexdigest()


# --- formatting filters -------------------------------------------------------------------------

#: where a parameter value came from, in words (helper names: cli, tender, standard, manifest, unset)
PARAMETER_SOURCES = {
    "cli": "command line (--param)",
    "tender": "tender profile",
    "standard": "the standard",
    "default": "the standard",
    "manifest": "contractor's manifest (confirm against the ITT)",
    "unset": "not set",
    "profile": "tender profile",
}


def param_source(v: Any) -> str:
    return PARAMETER_SOURCES.get(str(v), "" if v is None else str(v))


def blank(v: Any) -> str:
    """Empty fields print blank, never 'None'."""
    return "" if v is None else str(v)


def fmt_rows(rows: Iterable[int] | Mapping[str, Any] | None) -> str:
    """[1,2,3,7] -> '1–3, 7' (evidence row lists can be long); a selector standing for many rows
    (qcr.json version 3) -> 'where block = B02 (333412 rows)'."""
    if isinstance(rows, Mapping):
        return where_text(rows)
    rs = sorted(set(rows or ()))
    out: list[str] = []
    i = 0
    while i < len(rs):
        j = i
        while j + 1 < len(rs) and rs[j + 1] == rs[j] + 1:
            j += 1
        out.append(str(rs[i]) if i == j else f"{rs[i]}–{rs[j]}")
        i = j + 1
    return ", ".join(out)


_IDENT_BREAK = re.compile(r"(?<=[_.\-])(?=[^\s_.\-])")


def ident(v: Any) -> markupsafe.Markup:
    """Escaped identifier (rule id, measure or parameter name) breakable only after ``_``, ``.``, ``-``.

    Paired with the ``ident`` CSS class (no break anywhere else, no hyphenation): a PDF table never
    shows ``reported_rmse_toler ance``. Applied to free text it only adds break opportunities.
    """
    text = str(markupsafe.escape("" if v is None else v))
    return markupsafe.Markup(_IDENT_BREAK.sub("<wbr>", text))


def environment() -> jinja2.Environment:
    """Jinja2 over the templates folder with autoescaping on: delivery text is always text."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        autoescape=True,
        undefined=jinja2.ChainableUndefined,  # older qcr.json may lack newer keys
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    # every value and citation through the one vocabulary (orthospec.present)
    env.globals["NO_VALUE"] = NO_VALUE
    env.filters.update(
        value=fmt_value,
        fixed=fmt_fixed,
        measured=fmt_measured,
        clause=cite,
        rows=fmt_rows,
        short=lambda s, n=12: (s or "")[:n],
        blank=blank,
        source=param_source,
        ident=ident,
    )
    return env


# --- view model ---------------------------------------------------------------------------------


@dataclass
class RuleView:
    rule: str
    title: str
    clause: str
    quote: str
    scope: str
    level: str
    consequence: str
    measure: str
    verdict: str
    counts: dict[str, int]
    requirement: str
    shown: list[dict[str, Any]] = field(default_factory=list)  # rows: records not passing, grouped
    n_shown: int = 0
    passing: list[dict[str, Any]] = field(default_factory=list)  # HTML: passing records listed
    pass_count: int = 0
    pass_hidden: int = 0
    pass_range: str = ""
    na_count: int = 0
    rows_hidden: int = 0
    clause_ref: str = ""
    error: str | None = None


def _numeric(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def group_rows(recs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Table rows for records: one per measured record; records without a measured value that
    share verdict, requirement and message (e.g. 300 images lacking the same manual check)
    become one row listing every item, so nothing is dropped and nothing repeats."""
    rows: list[dict[str, Any]] = []
    groups: dict[tuple[str, str, str], dict[str, Any]] = {}
    for r in recs:
        if r["measured"].get("value") is not None:
            rows.append({**r, "item_list": [r["item"]]})
            continue
        key = (r["verdict"], r["requirement"].get("text", ""), r["message"])
        g = groups.get(key)
        if g is None:
            g = groups[key] = {**r, "item_list": [], "evidence": []}
            rows.append(g)
        g["item_list"].append(r["item"])
        for e in r["evidence"]:
            if e not in g["evidence"]:
                g["evidence"].append(e)
    return rows


def _problem_rules(records: list[dict[str, Any]], max_items: int) -> list[dict[str, Any]]:
    """The summary: one row per (rule, verdict) that failed, erred, lacked evidence or warned."""
    out: dict[tuple[str, str], dict[str, Any]] = {}
    for r in records:
        if r["verdict"] not in PROBLEM_VERDICTS:
            continue
        row = out.setdefault(
            (r["rule"], r["verdict"]),
            {
                "rule": r["rule"],
                "title": r["title"],
                "clause": r["clause"],
                "scope": r["scope"],
                "verdict": r["verdict"],
                "requirement": r["requirement"].get("text", ""),
                "consequence": r["consequence"],
                "item_list": [],
                "n": 0,
            },
        )
        row["n"] += 1
        if len(row["item_list"]) < max_items:
            row["item_list"].append(r["item"])
    return sorted(out.values(), key=lambda x: VERDICT_ORDER.get(x["verdict"], 9))


@dataclass
class _RuleRecords:
    """What the report keeps of one rule's records while they stream past: the problems in full,
    the passing ones as a count, a value range and (HTML) the first rows."""

    first: dict[str, Any] | None = None
    reqs: set[str] = field(default_factory=set)
    others: list[dict[str, Any]] = field(default_factory=list)
    passing: list[dict[str, Any]] = field(default_factory=list)
    pass_count: int = 0
    pass_unit: str | None = None
    lo: float | None = None
    hi: float | None = None
    na_count: int = 0


@dataclass
class _Collected:
    """One pass over :func:`~orthospec.qcr.all_records`: memory bounded by the problems and the
    manual records, not by the number of passing items (national deliveries)."""

    by_rule: dict[str, _RuleRecords]
    kept: list[dict[str, Any]]  # every record that is not pass / not applicable
    manual: list[dict[str, Any]]  # every record of a manual rule
    not_applicable: list[dict[str, Any]]


def _collect(doc: dict[str, Any], opts: ReportOptions) -> _Collected:
    by_rule: dict[str, _RuleRecords] = {}
    kept: list[dict[str, Any]] = []
    manual: list[dict[str, Any]] = []
    na = NotApplicableSummary()
    for r in all_records(doc):
        if any("where" in e for e in r["evidence"]):
            r["evidence"] = [_shown_evidence(e) for e in r["evidence"]]
        acc = by_rule.get(r["rule"])
        if acc is None:
            acc = by_rule[r["rule"]] = _RuleRecords(first=r)
        acc.reqs.add(r["requirement"].get("text", ""))
        v = r["verdict"]
        if r.get("manual"):
            manual.append(r)
        if v == V.PASS:
            acc.pass_count += 1
            value = r["measured"].get("value")
            if _numeric(value):
                if acc.lo is None:
                    acc.pass_unit = r["measured"].get("unit")
                    acc.lo = acc.hi = value
                else:
                    acc.lo, acc.hi = min(acc.lo, value), max(acc.hi, value)
            if not opts.bounded and len(acc.passing) < opts.max_pass_rows:
                acc.passing.append(r)
        elif v == V.NOT_APPLICABLE:
            acc.na_count += 1
            na.add(r)
        else:
            acc.others.append(r)
            kept.append(r)
    return _Collected(by_rule, kept, manual, na.result())


def _shown_evidence(e: dict[str, Any]) -> dict[str, Any]:
    """An evidence entry as the report shows it: a selector's rows in words (the ``rows`` filter)."""
    if "where" not in e or e.get("rows"):
        return e
    return {**e, "rows": {"where": e["where"], "rows_count": e.get("rows_count")}}


def _rule_views(
    doc: dict[str, Any], opts: ReportOptions, collected: _Collected | None = None
) -> list[RuleView]:
    by_rule = (collected or _collect(doc, opts)).by_rule
    meta = {r["rule"]: r for r in doc.get("rules", [])}
    order = list(meta) + [r for r in by_rule if r not in meta]
    views = []
    for rid in order:
        acc = by_rule.get(rid) or _RuleRecords()
        m = meta.get(rid, {})
        first = acc.first or {}
        reqs = acc.reqs
        v = RuleView(
            rule=rid,
            title=m.get("title") or first.get("title", ""),
            clause=cite(first.get("clause") or m.get("clause")),
            quote=first.get("quote", ""),
            scope=m.get("scope") or first.get("scope", ""),
            level=m.get("level") or first.get("level", ""),
            consequence=m.get("consequence") or first.get("consequence", ""),
            measure=first.get("measure", ""),
            verdict=m.get("verdict", V.NOT_APPLICABLE),
            counts=m.get("counts", {}),
            requirement=next(iter(reqs)) if len(reqs) == 1 else "per item",
            error=m.get("error"),
            clause_ref=m.get("clause_ref") or "",
        )
        v.na_count = acc.na_count
        shown = sorted(
            acc.others, key=lambda r: VERDICT_ORDER.get(r["verdict"], 9)
        )  # stable: item order kept
        v.shown = group_rows(shown)
        v.n_shown = len(shown)
        if opts.bounded and len(v.shown) > opts.max_rule_rows:
            v.rows_hidden = len(v.shown) - opts.max_rule_rows
            v.shown = v.shown[: opts.max_rule_rows]
        v.pass_count = acc.pass_count
        if acc.lo is not None:
            u = unit_suffix(acc.pass_unit)
            lo, hi = acc.lo, acc.hi
            v.pass_range = (
                fmt_value(lo) + u if lo == hi else f"{fmt_value(lo)} to {fmt_value(hi)}{u}"
            )
        if not opts.bounded:
            v.passing = [{**r, "item_list": [r["item"]]} for r in acc.passing]
            v.pass_hidden = acc.pass_count - len(v.passing)
        views.append(v)
    return views


def _checkpoint_blocks(
    doc: dict[str, Any],
    opts: ReportOptions,
    figure: Callable[[str, str], str] | None,
    cache: dict[str, list[dict[str, str]]],
) -> list[dict[str, Any]]:
    cps = (doc.get("details") or {}).get("checkpoints") or {}
    failing_blocks = set((doc.get("rollup") or {}).get("rejected", {}).get("block", []))
    blocks = []
    for bid in sorted(cps, key=natural_key):
        b = cps[bid]
        if not isinstance(b, dict):
            continue
        pts = point_rows(b.get("points"))
        has_z = any(p.get("dz") is not None for p in pts)
        n_fail = sum(p.get("status") == "fail" for p in pts)
        shown = pts
        if opts.bounded and len(pts) > opts.max_points:
            shown = [p for p in pts if _point_flagged(p)]
        elif not opts.bounded and len(pts) > opts.max_table_points:
            shown = _first_points(pts, opts.max_table_points)
        blocks.append(
            {
                "id": bid,
                "points": shown,
                "n_points": b.get("points_total") or len(pts),
                "n_hidden": len(pts) - len(shown),
                "n_omitted": b.get("points_omitted") or 0,
                "n_fail": n_fail,
                "has_z": has_z,
                "stats": b.get("stats") or {},
                "unit": b.get("unit", "m"),
                "limit_x": b.get("limit_x"),
                "limit_y": b.get("limit_y"),
                "basis": b.get("basis"),
                "n_gcps": len(b.get("gcps") or []),
                "rejected": bid in failing_blocks,
                "area_source": b.get("area_source"),
                "figures": [],
                "n_pass_shown": sum(not _point_flagged(p) for p in shown),
            }
        )
    if figure is not None and opts.figures:

        def worst(b: dict[str, Any]) -> tuple[Any, ...]:
            rmse = max(
                (v for v in (b["stats"].get("rmse_x"), b["stats"].get("rmse_y")) if _numeric(v)),
                default=0.0,
            )
            return (not b["rejected"], -b["n_fail"], -rmse, natural_key(b["id"]))

        ranked = sorted(blocks, key=worst)
        details = doc.get("details") or {}
        for b in ranked[: opts.max_figure_blocks]:
            if b["id"] not in cache:
                cache[b["id"]] = _block_figures(
                    cps[b["id"]],
                    b["id"],
                    details.get("inspection"),
                    (details.get("checker_chips") or {}).get(b["id"]),
                )
            b["figures"] = [{**f, "uri": figure(f["svg"], "image/svg+xml")} for f in cache[b["id"]]]
    return blocks


def _point_flagged(p: dict[str, Any]) -> bool:
    """A point the auditor must see in every table: above the limit, or not simply kept."""
    return p.get("status") == "fail" or p.get("decision") not in (None, "kept")


def _first_points(pts: list[dict[str, Any]], cap: int) -> list[dict[str, Any]]:
    """Every flagged point and the first passing ones, ``cap`` rows in all when the flagged leave
    room; table order kept."""
    room = max(cap - sum(_point_flagged(p) for p in pts), 0)
    out = []
    for p in pts:
        if _point_flagged(p):
            out.append(p)
        elif room:
            out.append(p)
            room -= 1
    return out


def _block_figures(
    b: dict[str, Any],
    bid: str,
    inspection: dict[str, Any] | None = None,
    chips: dict[str, Any] | None = None,
) -> list[dict[str, str]]:
    """JRC §12.6 / Figure 5 graphics for one block, from the JSON point list (SVG data URIs); the checker's
    marked inspection cells of the block on its map, and the image chips of its flagged or hand-measured
    points (issue 29 item 6; details.inspection, details.checker_chips)."""
    from ..figures import accuracy as figs  # matplotlib: imported only when figures are drawn

    pts = [
        p
        for p in point_rows(b.get("points"))
        if all(_numeric(p.get(k)) for k in ("x_ref", "y_ref", "dx", "dy"))
    ]
    if not pts:
        return []
    unit = b.get("unit", "m")
    x = [p["x_ref"] for p in pts]
    y = [p["y_ref"] for p in pts]
    dx = [p["dx"] for p in pts]
    dy = [p["dy"] for p in pts]
    ids = [str(p["point_id"]) for p in pts]
    gcps = [g for g in b.get("gcps") or [] if _numeric(g.get("x")) and _numeric(g.get("y"))]
    out = []
    flagged = [str(p["point_id"]) for p in pts if p.get("status") == "fail"]
    excluded = [
        str(p["point_id"]) for p in pts if p.get("decision") not in (None, "kept")
    ]  # drawn always too
    poly = b.get("polygon")  # the block outline, when the provider stores it in qcr.json
    polygon = (
        [
            (float(v[0]), float(v[1]))
            for v in poly
            if isinstance(v, list | tuple) and len(v) >= 2 and _numeric(v[0]) and _numeric(v[1])
        ]
        if isinstance(poly, list)
        else None
    )
    cells = [
        (c["bounds"], ", ".join(c.get("defects") or []))
        for c in (inspection or {}).get("cells") or []
        if c.get("block") == bid
        and isinstance(c.get("bounds"), list)
        and len(c["bounds"]) == 4
        and all(_numeric(v) for v in c["bounds"])
    ]
    svg = figs.checkpoint_map_svg(
        x,
        y,
        dx,
        dy,
        ids=ids,
        gcp_x=[g["x"] for g in gcps] or None,
        gcp_y=[g["y"] for g in gcps] or None,
        unit=unit,
        flagged=flagged,
        title=f"Block {bid}: check points and discrepancies",
        polygon=polygon if polygon and len(polygon) >= 3 else None,
        always=excluded,
        defect_cells=cells,
    )
    omitted = b.get("points_omitted")
    # a capped point table (B: flagged points + the largest residuals) is not a sample of the block:
    # say so on the map, and draw no distribution from it (the block statistics cover every point)
    total = b.get("points_total")
    subset = (
        f" Shown: {len(pts):,} of {f'{total:,}' if isinstance(total, int) else '?'} points, the "
        f"flagged ones and the largest "
        f"residuals; the statistics cover every point."
        if omitted
        else ""
    )
    must = {*flagged, *excluded}
    drawn = figs.sample_points(x, y, ids, [i in must for i in ids])
    if drawn.thinned:  # the figure draws a sample (issue 14): the caption counts what it drew
        subset += (
            f" Drawn: {drawn.drawn:,} of {'these' if omitted else 'the'} {drawn.total:,} points, "
            f"all {drawn.must:,} flagged or excluded and 1 in {drawn.step:,} of the others (an even "
            f"spatial sample); qcr.json holds every one of the {drawn.total:,}."
        )
    marked = (
        f" Orange: the {len(cells)} cell(s) of the block marked with a defect on the checker's inspection "
        f"grid ({(inspection or {}).get('file')}): "
        + "; ".join(sorted({lab for _, lab in cells}))
        + "."
        if cells
        else ""
    )
    out.append(
        {
            "svg": svg,
            "kind": "map",
            "caption": f"Block {bid}: check points (blue; red = above the maximum tolerable "
            f"discrepancy), discrepancy vectors (exaggerated, see scale arrow) and GCPs "
            f"(green triangles), as JRC Figure 5.{subset}{marked}",
        }
    )
    out += _chip_figures(chips, bid, unit)
    if omitted:
        return out
    dz = [p.get("dz") for p in pts]
    dz_ok = all(_numeric(v) for v in dz)
    svg = figs.residual_histograms_svg(
        dx, dy, dz if dz_ok else None, unit=unit, title=f"Block {bid}: discrepancies"
    )
    out.append(
        {
            "svg": svg,
            "kind": "hist",
            "caption": f"Block {bid}: distribution of the discrepancies per axis with the mean "
            f"(black) and ±RMSE (red dashed)."
            + (f" Every one of the {len(pts):,} points is binned." if drawn.thinned else ""),
        }
    )
    quad = _judged_quadrants(b)
    if quad is not None:
        # the split and shares the provider judged (details.checkpoints.<block>.quadrants), never a
        # recomputation: the figure shows what the verdict used
        centre, shares = quad
        outline = polygon if polygon and len(polygon) >= 3 else None
        svg = figs.quadrant_distribution_svg(
            x,
            y,
            centre=centre,
            shares=shares,
            area=outline,
            unit=unit,
            ids=ids,
            title=f"Block {bid}: distribution by quadrant",
        )
        spread = figs.sample_points(x, y, ids)
        source = b.get("area_source")
        where = (
            "the block polygon"
            if source == "area"
            else f"the points' {str(source or 'convex hull').replace('_', ' ')}"
        ) + (" (grey)" if outline else "")
        drawn_note = (
            f" Drawn: {spread.drawn:,} of the {spread.total:,} points, 1 in {spread.step:,} (an "
            f"even spatial sample); the shares are the measured ones, over every point used."
            if spread.thinned
            else ""
        )
        out.append(
            {
                "svg": svg,
                "kind": "dist",
                "caption": f"Block {bid}: check points per quadrant, split at the centre of {where}; "
                f"the shares are those the distribution rule judged." + drawn_note,
            }
        )
    return out


def _judged_quadrants(b: Mapping[str, Any]) -> tuple[tuple[float, float], dict[str, float]] | None:
    """The quadrant split centre and shares the provider recorded for a block, or None (an older
    qcr.json, or a layout the distribution could not be computed for: the map shows the points)."""
    q = b.get("quadrants")
    if not isinstance(q, Mapping):
        return None
    c, shares = q.get("centre"), q.get("shares")
    if not (isinstance(c, list) and len(c) == 2 and all(_numeric(v) for v in c)):
        return None
    if not isinstance(shares, Mapping) or not all(_numeric(v) for v in shares.values()):
        return None
    return (float(c[0]), float(c[1])), {str(k): float(v) for k, v in shares.items()}


def _chip_figures(chips: dict[str, Any] | None, bid: str, unit: str) -> list[dict[str, str]]:
    """The image chips of a block's flagged or hand-measured check points (details.checker_chips)."""
    if not isinstance(chips, dict) or not chips.get("points"):
        return []
    from ..figures.chips import chip_svg

    out = []
    # a point no delivered image covers (the table says why in qcr.json) gets no figure
    shown = [p for p in chips["points"] if isinstance(p, dict) and p.get("delivered")]
    for p in shown:
        try:
            svg = chip_svg(p, unit=unit)
        except (KeyError, TypeError, ValueError):  # a hand-edited document: the chip is left out
            continue
        why = (
            "flagged"
            if p.get("flagged")
            else ("measured by hand" if p.get("decision") == "by_hand" else "")
        )
        out.append(
            {
                "svg": svg,
                "kind": "chip",
                "caption": f"Block {bid}, check point {p.get('point_id')} ({why}): the delivered image around "
                "the measured position (red cross) and the reference chip around the 'true' "
                "position (green circle); the arrow is the measured shift, to scale.",
            }
        )
    more = int(chips.get("eligible") or 0) - len(out)
    if out and more > 0:
        out[-1]["caption"] += (
            f" Chips are drawn for {len(out)} of the block's {len(out) + more} flagged or "
            "hand-measured points (flagged first, then the largest residuals)."
        )
    return out


def _edge_targets(
    doc: dict[str, Any],
    opts: ReportOptions | None = None,
    figure: Callable[[str, str], str] | None = None,
    cache: dict[str, list[dict[str, str]]] | None = None,
) -> list[dict[str, Any]]:
    """Edge-target results (``details.edges``): health checks, estimators and figures per target.

    The figures (detection, ESF, LSF, MTF) are drawn from the decimated ``curves`` the edge
    provider stores in qcr.json; a document without them (older or hand-made) gets the tables only.
    """
    opts = opts or ReportOptions()
    cache = {} if cache is None else cache
    edges = (doc.get("details") or {}).get("edges")
    if not isinstance(edges, dict):
        return []
    out = []
    for tid in sorted(edges, key=natural_key):
        d = edges[tid]
        if not isinstance(d, dict):
            continue
        checks = []
        for k in d:
            if k.startswith("check.") and k.endswith(".value"):
                name = k[len("check.") : -len(".value")]
                checks.append(
                    {
                        "name": name,
                        "value": d[k],
                        "unit": d.get(f"check.{name}.unit"),
                        "passed": d.get(f"check.{name}.passed"),
                    }
                )
        estimates = []
        for k, v in d.items():
            if k.startswith("check.") or k.endswith((".unit", ".fit")) or not _numeric(v):
                continue
            if f"{k}.unit" in d:
                estimates.append(
                    {
                        "name": k,
                        "value": v,
                        "unit": d.get(f"{k}.unit"),
                        "fit": d.get(f"{k}.fit", ""),
                    }
                )
            elif (
                "." in k and k.rsplit(".", 1)[0] + ".unit" in d
            ):  # an alternative fit of an estimator
                base, fit = k.rsplit(".", 1)
                estimates.append(
                    {"name": base, "value": v, "unit": d.get(f"{base}.unit"), "fit": fit}
                )
        out.append(
            {
                "id": tid,
                "valid": d.get("valid"),
                "reasons": d.get("reasons") or "",
                "direction": d.get("direction"),
                "angle_deg": d.get("angle_deg"),
                "checks": checks,
                "estimates": estimates,
                "has_curves": isinstance(d.get("curves"), dict),
                "figures": [],
            }
        )
    if figure is not None and opts.figures:
        bad = {
            r["item"]
            for r in all_records(doc, compact=False)
            if r.get("scope") == "edge" and r.get("verdict") in (V.FAIL, V.ERROR)
        }
        ranked = sorted(
            (e for e in out if e["has_curves"]), key=lambda e: e["id"] not in bad
        )  # stable
        for e in ranked[: opts.max_figure_edges]:
            key = f"edge:{e['id']}"  # block ids share the cache
            if key not in cache:
                cache[key] = _edge_figures(edges[e["id"]], e["id"])
            e["figures"] = [{**f, "uri": figure(f["svg"], "image/svg+xml")} for f in cache[key]]
    return out


def _floats(v: Any) -> list[float]:
    """A stored curve as floats (None -> NaN; anything that is not a list -> empty)."""
    if not isinstance(v, list):
        return []
    return [float(x) if _numeric(x) else math.nan for x in v]


def _edge_figures(d: dict[str, Any], tid: str) -> list[dict[str, str]]:
    """CEOS steps 5-12 for one edge target, from ``details.edges.<id>.curves`` (SVG)."""
    import numpy as np

    from ..figures import edge as figs  # matplotlib: imported only when figures are drawn

    c = d["curves"]
    status = "valid" if d.get("valid") else "INVALID"
    out = []
    lines = c.get("lines") or {}
    shape = c.get("shape") or [0, 0]
    angle = c.get("angle_deg")
    angle_txt = f", {angle:.2f}°" if _numeric(angle) else ""
    if lines.get("kept_x") or lines.get("rejected_x"):
        svg = figs.detection_svg_from_arrays(
            _floats(lines.get("kept_x")),
            _floats(lines.get("kept_y")),
            shape=(int(shape[0]), int(shape[1])),
            rejected_x=_floats(lines.get("rejected_x")),
            rejected_y=_floats(lines.get("rejected_y")),
            fit_x=_floats(lines.get("fit_x")),
            fit_y=_floats(lines.get("fit_y")),
            title=f"{tid}: edge detection ({c.get('direction', '?')}{angle_txt}) — {status}",
        )
        out.append(
            {
                "svg": svg,
                "kind": "edge detection",
                "caption": f"Edge target {tid}, edge detection: edge location per line (red; orange = "
                f"rejected as outlier) and the fitted edge line (green), in ROI pixels "
                f"(CEOS step 5).",
            }
        )
    n = len(c.get("mtf_freq") or [])
    fits = []
    for name, f in (c.get("fits") or {}).items():
        if not isinstance(f, dict) or not _numeric(f.get("x0")) or not _numeric(f.get("dx")):
            continue
        fit_esf = _floats(f.get("esf"))
        fits.append(
            figs.FitCurves(
                fit=str(name),
                x=np.asarray([f["x0"] + i * f["dx"] for i in range(len(fit_esf))], dtype=float),
                esf=np.asarray(fit_esf, dtype=float),
                lsf=np.asarray(_floats(f.get("lsf")), dtype=float),
                freq=np.asarray(_floats(c.get("mtf_freq")), dtype=float),
                mtf=np.asarray(_floats(f.get("mtf"))[:n], dtype=float),
                centre_px=f.get("centre_px") if _numeric(f.get("centre_px")) else None,
                fwhm_px=f.get("fwhm_px") if _numeric(f.get("fwhm_px")) else None,
                mtf_nyquist=f.get("mtf_nyquist") if _numeric(f.get("mtf_nyquist")) else None,
            )
        )
    esf = c.get("esf") or {}
    if esf or fits:
        svg = figs.esf_svg_from_arrays(
            _floats(esf.get("d")),
            _floats(esf.get("v")),
            fits,
            dark_start_px=esf.get("dark_start_px") if _numeric(esf.get("dark_start_px")) else None,
            bright_start_px=esf.get("bright_start_px")
            if _numeric(esf.get("bright_start_px"))
            else None,
            title=f"{tid}: edge spread function (ESF) — {status}",
        )
        shown = len(esf.get("d") or [])
        out.append(
            {
                "svg": svg,
                "kind": "edge esf",
                "caption": f"Edge target {tid}, ESF: {shown} of the {esf.get('n_samples', shown)} pixel "
                f"samples within the fitted window ±1 px (grey) at their perpendicular "
                f"distance from the edge, normalised "
                f"0 (dark) to 1 (bright), the fitted ESFs and the plateau starts "
                f"(CEOS steps 6-8).",
            }
        )
    if fits:
        fw = "; ".join(f"{f.fit} {f.fwhm_px:.3f} px" for f in fits if f.fwhm_px is not None)
        svg = figs.lsf_svg_from_arrays(fits, title=f"{tid}: line spread function (LSF) — {status}")
        out.append(
            {
                "svg": svg,
                "kind": "edge lsf",
                "caption": f"Edge target {tid}, LSF: derivative of the fitted ESF, the arrow marks "
                f"the full width at half maximum (FWHM {fw or 'n/a'}; CEOS steps 10-11).",
            }
        )
        ny = "; ".join(f"{f.fit} {f.mtf_nyquist:.3f}" for f in fits if f.mtf_nyquist is not None)
        svg = figs.mtf_svg_from_arrays(
            fits, title=f"{tid}: modulation transfer function (MTF) — {status}"
        )
        out.append(
            {
                "svg": svg,
                "kind": "edge mtf",
                "caption": f"Edge target {tid}, MTF: modulus of the Fourier transform of the LSF, "
                f"normalised at zero frequency; Nyquist (0.5 cycles/px) dashed, MTF there "
                f"{ny or 'n/a'} (CEOS step 12).",
            }
        )
    return out


def _bounded_signed(groups: list[dict[str, Any]], max_rows: int) -> list[dict[str, Any]]:
    """PDF: a rule whose signed records carry more than ``max_rows`` different messages (one per
    item) becomes one row per verdict listing every item, quoting the first message; the HTML
    report and qcr.json keep each one."""
    by_key: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for g in groups:
        by_key.setdefault((g["rule"], g["verdict"]), []).append(g)
    out: list[dict[str, Any]] = []
    for gs in by_key.values():
        if len(gs) <= max_rows:
            out.extend(gs)
            continue
        items = [i for g in gs for i in g["item_list"]]
        out.append(
            {
                **gs[0],
                "item_list": items,
                "message": f"{len(gs)} different statements, each in qcr.json and the HTML report; "
                f"the first: {gs[0]['message']}",
            }
        )
    return out


def report_context(
    doc: dict[str, Any],
    opts: ReportOptions | None = None,
    *,
    figure: Callable[[str, str], str] | None = None,
    cache: dict[str, list[dict[str, str]]] | None = None,
    sha256: str | None = None,
    findings_map: Any = None,
) -> dict[str, Any]:
    """Everything the template shows, computed from the QCR document alone.

    ``figure(svg_text, mime)`` turns a figure into a URI (the PDF registers data: URIs with its
    fetcher); ``None`` draws no figures. ``cache`` keeps drawn SVGs between HTML and PDF renders.
    """
    opts = opts or ReportOptions()
    collected = _collect(doc, opts)
    records = collected.kept  # the problems (every verdict but pass / not applicable)
    problems = _problem_rules(records, 30 if opts.bounded else 10**9)
    rules = _rule_views(doc, opts, collected)
    scopes: list[dict[str, Any]] = []
    for v in rules:
        if not scopes or scopes[-1]["scope"] != v.scope:
            scopes.append(
                {
                    "scope": v.scope,
                    "title": SCOPE_TITLES.get(v.scope, v.scope.title()),
                    "rules": [],
                    "quiet": [],
                }
            )
        # bounded: rules with nothing to show (all passing / not applicable) become one table row
        quiet = opts.bounded and not v.shown and not v.error
        if quiet and not v.pass_count and not v.counts.get("waived"):
            continue  # not applicable throughout: summarised per condition, never row by row
        scopes[-1]["quiet" if quiet else "rules"].append(v)
    failing_rules = [v for v in rules if v.verdict in (V.ERROR, V.FAIL)]
    manual = collected.manual
    to_sign: dict[str, dict[str, Any]] = {}
    for r in manual:
        if r["verdict"] == V.MISSING:
            to_sign.setdefault(r["rule"], {**r, "item_list": []})["item_list"].append(r["item"])
    decided = {d["rule"] for d in (doc.get("after_signoff") or {}).get("decisions", [])}
    to_sign = {k: v for k, v in to_sign.items() if k not in decided}
    signed_groups: dict[tuple[str, str, str], dict[str, Any]] = {}
    for r in manual:
        if r["verdict"] in (V.MISSING, V.NOT_APPLICABLE):
            continue
        key = (r["rule"], r["verdict"], r["message"])
        signed_groups.setdefault(key, {**r, "item_list": []})["item_list"].append(r["item"])
    signed = list(signed_groups.values())
    if opts.bounded:
        signed = _bounded_signed(signed, opts.max_rule_rows)
    stated_findings = find_problems(records)
    found = [f.as_dict() for f in stated_findings]
    scopes = [s for s in scopes if s["rules"] or s["quiet"]]
    d = doc.get("delivery", {})
    p = doc.get("profile", {})
    return {
        "doc": doc,
        "opts": opts,
        "sha256": sha256 or document_sha256(doc),
        "delivery": d,
        "profile": p,
        "summary": doc.get("summary", {}),
        "verdict": doc.get("verdict", V.REJECTED),
        "reasons": (doc.get("rollup") or {}).get("reasons", []),
        "incomplete": (doc.get("rollup") or {}).get("incomplete", []),
        "rejected": (doc.get("rollup") or {}).get("rejected", {}),
        "problems": problems,
        "failing_rules": failing_rules,
        "findings": found,
        "findings_by_reason": by_reason(stated_findings),
        # the checker's open items are listed above the findings on page 1: not a second time there
        "page1_findings": [f for f in found if f.get("consequence") != V.INCOMPLETE][
            : max(3, PAGE1_FINDINGS - len((doc.get("rollup") or {}).get("incomplete", [])))
        ],
        "not_applicable": collected.not_applicable,
        "unsigned_manual": unsigned_manual_note(records, checker=doc.get("checker")),
        "contract": contract_lines(doc),
        "checker": checker_text(doc),
        "qa_operator": d.get("operator") or {},
        "after_signoff": doc.get("after_signoff"),
        "missing": [r for r in records if r["verdict"] == V.MISSING],
        "waived": [r for r in records if r["verdict"] == V.WAIVED],
        "waivers_unused": doc.get("waivers_unused") or [],
        "manual_unused": doc.get("manual_unused") or [],
        "scopes": scopes,
        "checkpoints": _checkpoint_blocks(doc, opts, figure, {} if cache is None else cache),
        "edges": _edge_targets(doc, opts, figure, {} if cache is None else cache),
        "to_sign": list(to_sign.values()),
        "signed": signed,
        "signoffs": doc.get("signoffs") or [],
        "history": doc.get("history") or [],
        "ledger": doc.get("ledger"),
        "parameters": sorted((p.get("parameters") or {}).items()),
        "files": d.get("files") or [],
        "title": f"Quality control report — delivery {d.get('id', '?')}",
        "findings_map": findings_map,
    }


def render_html(
    doc: dict[str, Any],
    opts: ReportOptions | None = None,
    *,
    figure: Callable[[str, str], str] | None = None,
    pdf: bool = False,
    cache: dict[str, list[dict[str, str]]] | None = None,
    sha256: str | None = None,
) -> str:
    """The report as one self-contained HTML page (figures inlined as data: URIs)."""
    findings_map = None
    if figure is not None and (opts is None or opts.figures):  # the map of the findings (issue 30)
        from ..findings import build_layers
        from .interactive import map_html

        findings_map = map_html(build_layers(doc), interactive=not pdf)
    ctx = report_context(
        doc, opts, figure=figure, cache=cache, sha256=sha256, findings_map=findings_map
    )
    return environment().get_template("report.html.j2").render(**ctx, pdf=pdf)
