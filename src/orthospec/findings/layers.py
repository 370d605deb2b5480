"""The findings layers, built from what the QCR document judged (never a recomputation).

Each item layer carries the item's verdict (the worst of its records), its most consequential
failing rule (returns the delivery, rejects a block, rejects an item, the checker's, then warnings;
the worst verdict first among equals), the reasons text and the evidence of its non-pass records.
Geometries: block outlines, check point locations and the checker's inspection cells come from
``details`` of the document; image footprints and seamlines from :class:`DeliveryGeometry`. A
feature whose geometry is not known is still written (null geometry), so no finding is lost.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from .. import verdicts as V
from ..controls import _TEXT as _CONTROLS
from ..qcr import all_records, evidence_text, natural_key, point_rows
from .geometry import DeliveryGeometry

__all__ = ["LAYER_NAMES", "FindingsLayers", "Layer", "build_layers", "nice_scale", "visible"]

LAYER_NAMES = (
    "blocks",
    "images",
    "seamlines",
    "inspection_cells",
    "checkpoints",
    "residuals",
    "rules",
)
_CONSEQUENCE_RANK = {
    V.RETURN_DELIVERY: 0,
    V.REJECT_BLOCK: 1,
    V.REJECT_ITEM: 2,
    V.INCOMPLETE: 3,
    V.WARN: 4,
}
#: the block measures shown beside the block statistics when a profile judges them
BLOCK_MEASURES = (
    "checkpoints.ce90",
    "checkpoints.ce95",
    "checkpoints.nssda_horizontal_95",
    "checkpoints.nssda_vertical_95",
)
MAX_REASONS = 20  # reasons listed per feature; the count says how many there are
#: the residual arrows' longest vector as a share of the extent's diagonal
RESIDUAL_SHARE = 0.05
ITEM_FIELDS = (
    ("verdict", "str"),
    ("rejected", "int"),
    ("rule", "str"),
    ("consequence", "str"),
    ("clause", "str"),
    ("reasons", "str"),
    ("problems", "int"),
    ("evidence", "str"),
)


def visible(v: Any) -> str:
    """Text as every findings output shows it: control and bidi-override characters (U+202E) made
    visible as ``[U+202E]``, never obeyed (the delivery's readers refuse them; a hand-made qcr.json
    may still carry them)."""
    return _CONTROLS.sub(lambda m: f"[U+{ord(m.group()):04X}]", "" if v is None else str(v))


@dataclass
class Layer:
    """One layer: features as (geometry or None, attributes), fields as (name, type)."""

    name: str
    geometry_type: str | None  # "Polygon", "Point", "LineString"; None: attribute table
    fields: tuple[tuple[str, str], ...]
    features: list[tuple[Any, dict[str, Any]]] = field(default_factory=list)
    description: str = ""
    metadata: dict[str, str] = field(default_factory=dict)

    def verdict_counts(self) -> dict[str, int]:
        counts: dict[str, int] = defaultdict(int)
        for _, props in self.features:
            counts[str(props.get("verdict"))] += 1
        return dict(counts)


@dataclass
class FindingsLayers:
    crs: str | None
    layers: dict[str, Layer]
    records: dict[str, dict[str, list[dict[str, Any]]]]  # layer -> feature id -> its QCR records

    def __getitem__(self, name: str) -> Layer:
        return self.layers[name]


@dataclass
class _Item:
    records: list[dict[str, Any]] = field(default_factory=list)

    def props(self, rules: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        problems = [r for r in self.records if r.get("verdict") in V.PROBLEMS]
        problems.sort(
            key=lambda r: (
                _CONSEQUENCE_RANK.get(str(r.get("consequence")), 9),
                V.severity_rank(str(r.get("verdict"))),
                natural_key(str(r.get("rule"))),
            )
        )
        top = problems[0] if problems else None
        rule = rules.get(str(top.get("rule")), {}) if top else {}
        reasons = [
            f"{r.get('rule')}: {r.get('verdict')}: {r.get('message') or ''}".rstrip(": ")
            for r in problems[:MAX_REASONS]
        ]
        if len(problems) > MAX_REASONS:
            reasons.append(f"... and {len(problems) - MAX_REASONS} more (qcr.json)")
        evidence = sorted(
            {
                evidence_text(e)
                for r in problems
                for e in (r.get("evidence") or [])
                if isinstance(e, Mapping)
            }
        )
        return {
            "verdict": V.worst(str(r.get("verdict")) for r in self.records)
            if self.records
            else None,
            "rule": top.get("rule") if top else None,
            "consequence": top.get("consequence") if top else None,
            "clause": rule.get("clause") if top else None,
            "reasons": "\n".join(reasons) or None,
            "problems": len(problems),
            "evidence": "\n".join(evidence) or None,
        }


def _box(b: Iterable[float] | None) -> Any:
    import shapely

    if b is None:
        return None
    x0, y0, x1, y1 = (float(v) for v in b)
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or x1 <= x0 or y1 <= y0:
        return None
    return shapely.box(x0, y0, x1, y1)


def _polygon(ring: Any) -> Any:
    import shapely

    try:
        pts = [(float(x), float(y)) for x, y in ring]
    except (TypeError, ValueError):
        return None
    if len(pts) < 3 or not all(math.isfinite(v) for p in pts for v in p):
        return None
    return shapely.Polygon(pts)


def _num(v: Any) -> float | None:
    if isinstance(v, Mapping):
        v = v.get("value")
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v) if math.isfinite(v) else None


def nice_scale(raw: float) -> float:
    """The largest 1-2-5 number not above ``raw`` (the residual arrows' exaggeration)."""
    if not math.isfinite(raw) or raw <= 0:
        return 1.0
    exp = math.floor(math.log10(raw))
    for m in (5, 2, 1):
        if m * 10**exp <= raw:
            return float(m * 10**exp)
    return float(10**exp)


def _point_status(p: Mapping[str, Any]) -> str:
    """used / blunder candidate / excluded, from the §12.6 decision the check recorded."""
    if p.get("decision") == "excluded":
        return "excluded"
    if p.get("status") == "fail" or p.get("decision") not in (None, "kept"):
        return "blunder candidate"
    return "used"


def build_layers(
    doc: Mapping[str, Any], geometry: DeliveryGeometry | None = None
) -> FindingsLayers:
    """The findings layers of ``doc`` (a QCR document); ``geometry`` adds footprints and seamlines."""
    import shapely

    rules = {str(r.get("rule")): r for r in doc.get("rules") or [] if isinstance(r, Mapping)}
    items: dict[str, dict[str, _Item]] = defaultdict(lambda: defaultdict(_Item))
    for rec in all_records(doc):
        scope = str(rules.get(str(rec.get("rule")), {}).get("scope") or rec.get("scope") or "")
        items[scope][str(rec.get("item"))].records.append(rec)
    details = doc.get("details") or {}
    cps = details.get("checkpoints") or {}
    geometry = geometry or DeliveryGeometry()
    if not geometry.footprints and isinstance(details.get("footprints"), Mapping):  # qcr.json alone
        geometry = DeliveryGeometry(
            footprints={str(k): v for k, v in details["footprints"].items()},
            seamlines=geometry.seamlines,
            seamlines_file=geometry.seamlines_file,
        )
    crs = ((doc.get("delivery") or {}).get("project") or {}).get("crs")
    recs: dict[str, dict[str, list[dict[str, Any]]]] = defaultdict(dict)
    rejected = {
        scope: {str(i) for i in ids}
        for scope, ids in ((doc.get("rollup") or {}).get("rejected") or {}).items()
        if isinstance(ids, list)
    }

    def item_layer(
        name: str,
        gtype: str,
        scope: str,
        ids: Iterable[str],
        geom_of: Any,
        extra: tuple[tuple[str, str], ...] = (),
        extra_of: Any = None,
        description: str = "",
    ) -> Layer:
        layer = Layer(name, gtype, (("id", "str"), *ITEM_FIELDS, *extra), description=description)
        for iid in sorted(set(ids), key=natural_key):
            it = items[scope].get(iid) or _Item()
            props = {
                "id": iid,
                **it.props(rules),
                "rejected": int(iid in rejected.get(scope, ())),
                **(extra_of(iid) if extra_of else {}),
            }
            layer.features.append((geom_of(iid), props))
            recs[name][iid] = it.records
        return layer

    # blocks: the outline in force, the §12.7 statistics and the figures the profile judged
    block_stats = tuple(
        (k, "float") for k in ("rmse_x", "rmse_y", "rmse_z", "mean_x", "mean_y", "max_dr")
    )
    block_more = tuple((m.split(".", 1)[1], "float") for m in BLOCK_MEASURES)

    def block_extra(bid: str) -> dict[str, Any]:
        b = cps.get(bid) or {}
        stats = b.get("stats") or {}
        out: dict[str, Any] = {
            "n_checkpoints": stats.get("n"),
            **{k: _num(stats.get(k)) for k, _ in block_stats},
        }
        measured = {
            str(r.get("measure")): _num(r.get("measured"))
            for r in (items["block"].get(bid) or _Item()).records
        }
        out.update({m.split(".", 1)[1]: measured.get(m) for m in BLOCK_MEASURES})
        return out

    blocks = item_layer(
        "blocks",
        "Polygon",
        "block",
        [*cps, *items["block"]],
        lambda bid: _polygon((cps.get(bid) or {}).get("polygon") or []),
        (("n_checkpoints", "int"), *block_stats, *block_more),
        block_extra,
        "Blocks: outline in force, check point statistics, verdict and consequence",
    )
    images = item_layer(
        "images",
        "Polygon",
        "image",
        [*geometry.footprints, *items["image"]],
        lambda iid: _box(geometry.footprints.get(iid)),
        description="Image footprints (raster headers) with the verdict of each image's records",
    )
    image_verdict = {p["id"]: p.get("verdict") for _, p in images.features}

    seam = Layer(
        "seamlines",
        "Polygon",
        (("image_id", "str"), ("verdict", "str"), ("source", "str")),
        description="Seamline polygons with the verdict of the image each shows",
    )
    for g, img in geometry.seamlines:
        seam.features.append(
            (
                g,
                {
                    "image_id": img,
                    "verdict": image_verdict.get(img) if img else None,
                    "source": geometry.seamlines_file,
                },
            )
        )

    cells = Layer(
        "inspection_cells",
        "Polygon",
        (
            ("cell_id", "str"),
            ("image_id", "str"),
            ("block", "str"),
            ("defects", "str"),
            ("comment", "str"),
            ("verdict", "str"),
        ),
        description="The checker's marked inspection cells (details.inspection) and the image's verdict",
    )
    for c in (details.get("inspection") or {}).get("cells") or []:
        if isinstance(c, Mapping):
            cells.features.append(
                (
                    _box(c.get("bounds")),
                    {
                        "cell_id": c.get("cell_id"),
                        "image_id": c.get("image_id"),
                        "block": c.get("block"),
                        "defects": ", ".join(str(d) for d in c.get("defects") or []),
                        "comment": c.get("comment"),
                        "verdict": image_verdict.get(str(c.get("image_id"))),
                    },
                )
            )

    # check points and their residual vectors
    pfields = (
        ("block", "str"),
        ("point_id", "str"),
        ("dx", "float"),
        ("dy", "float"),
        ("dz", "float"),
        ("dr", "float"),
        ("status", "str"),
        ("decision", "str"),
        ("row", "int"),
        ("verdict", "str"),
        ("reasons", "str"),
    )
    points = Layer(
        "checkpoints",
        "Point",
        pfields,
        description="Check points in force at their reference "
        "location: discrepancies (image minus reference), §12.6 status and verdict",
    )
    for bid in sorted(cps, key=natural_key):
        for p in point_rows((cps[bid] or {}).get("points")):
            pid = str(p.get("point_id"))
            it = items["checkpoint"].get(pid) or _Item()
            judged = it.props(rules)
            x, y = _num(p.get("x_ref")), _num(p.get("y_ref"))
            props = {
                "block": bid,
                "point_id": pid,
                **{k: _num(p.get(k)) for k in ("dx", "dy", "dz", "dr")},
                "status": _point_status(p),
                "decision": p.get("decision"),
                "row": p.get("row") if isinstance(p.get("row"), int) else None,
                "verdict": judged["verdict"],
                "reasons": judged["reasons"],
            }
            points.features.append((None if x is None or y is None else shapely.Point(x, y), props))
            recs["checkpoints"][f"{bid}/{pid}"] = it.records
    geoms = [g for lay in (blocks, images, points) for g, _ in lay.features if g is not None]
    if geoms:
        x0, y0, x1, y1 = shapely.total_bounds(geoms)
        diag = math.hypot(x1 - x0, y1 - y0)
    else:
        diag = 0.0
    longest = max(
        (p["dr"] or 0.0 for _, p in points.features if p.get("dr") is not None), default=0.0
    )
    scale = nice_scale(RESIDUAL_SHARE * diag / longest) if diag > 0 and longest > 0 else 1.0
    resid = Layer(
        "residuals",
        "LineString",
        (
            ("block", "str"),
            ("point_id", "str"),
            ("dx", "float"),
            ("dy", "float"),
            ("dr", "float"),
            ("scale", "float"),
            ("status", "str"),
            ("verdict", "str"),
        ),
        description=f"Residual vectors from the reference location, drawn {scale:g} times their length",
        metadata={"residual_scale": f"{scale:g}", "residual_units": "map units per map unit"},
    )
    for g, p in points.features:
        if g is None or p["dx"] is None or p["dy"] is None:
            continue
        end = (g.x + p["dx"] * scale, g.y + p["dy"] * scale)
        resid.features.append(
            (
                shapely.LineString([(g.x, g.y), end]),
                {
                    "block": p["block"],
                    "point_id": p["point_id"],
                    "dx": p["dx"],
                    "dy": p["dy"],
                    "dr": p["dr"],
                    "scale": scale,
                    "status": p["status"],
                    "verdict": p["verdict"],
                },
            )
        )

    table = Layer(
        "rules",
        None,
        (
            ("rule", "str"),
            ("title", "str"),
            ("scope", "str"),
            ("level", "str"),
            ("consequence", "str"),
            ("clause", "str"),
            ("quote", "str"),
            ("verdict", "str"),
            ("failing_items", "int"),
        ),
        description="Each rule's clause and quote; features join on their rule column",
    )
    for rid in sorted(rules, key=natural_key):
        r = rules[rid]
        counts = r.get("counts") or {}
        table.features.append(
            (
                None,
                {
                    "rule": rid,
                    "title": r.get("title"),
                    "scope": r.get("scope"),
                    "level": r.get("level"),
                    "consequence": r.get("consequence"),
                    "clause": r.get("clause"),
                    "quote": r.get("quote"),
                    "verdict": r.get("verdict"),
                    "failing_items": sum(
                        int(counts.get(v, 0))
                        for v in V.PROBLEMS
                        if isinstance(counts.get(v, 0), int)
                    ),
                },
            )
        )
    layers = {lay.name: lay for lay in (blocks, images, seam, cells, points, resid, table)}
    return FindingsLayers(crs=crs, layers=layers, records=dict(recs))
