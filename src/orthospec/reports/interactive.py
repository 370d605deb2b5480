"""The map of the findings in the report, drawn from the findings layers (issue 30).

One SVG drawer serves both reports: the HTML page gets it with a few dozen lines of inline
JavaScript (``reports/templates/map.js``: pan, zoom, click a feature for its QCR records) and the
records as a JSON island; the PDF gets the same SVG, static. Everything is in the page: no request
to any server. Every string from the delivery is escaped: SVG text and attributes by markupsafe,
the JSON island with ``<``, ``>``, ``&`` and every non-ASCII character as ``\\uXXXX`` (so
``</script>`` and U+202E cannot leave it), and controls shown as ``[U+202E]``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import markupsafe

from .. import verdicts as V
from ..findings.layers import FindingsLayers, Layer, visible
from ..findings.styles import COLOURS, OTHER
from ..resources import templates_dir

__all__ = ["MAP_LAYERS", "MAX_FEATURES", "map_html", "map_svg"]

#: drawn bottom to top
MAP_LAYERS = ("blocks", "images", "seamlines", "inspection_cells", "residuals", "checkpoints")
MAX_FEATURES = 3000  # per layer; non-pass features first, the caption says what was left out
MAX_RECORDS = 60     # QCR records shown per feature (the worst first)
WIDTH = 960.0
_LABEL = {
    "blocks": "blocks",
    "images": "image footprints",
    "seamlines": "seamlines",
    "inspection_cells": "inspection cells",
    "residuals": "residual vectors",
    "checkpoints": "check points",
}


_text = visible  # delivery text as shown: controls and bidi overrides made visible, never obeyed


def _colour(verdict: Any) -> str:
    return "#{:02x}{:02x}{:02x}".format(*COLOURS.get(str(verdict), OTHER))


def _chosen(layer: Layer) -> tuple[list[int], int]:
    """Indexes drawn (non-pass first, then in order) and how many were left out."""
    idx = [k for k, (g, _) in enumerate(layer.features) if g is not None]
    if len(idx) <= MAX_FEATURES:
        return idx, 0
    idx.sort(
        key=lambda k: (
            V.severity_rank(str(layer.features[k][1].get("verdict"))) >= V.severity_rank(V.PASS),
            k,
        )
    )
    return sorted(idx[:MAX_FEATURES]), len(idx) - MAX_FEATURES


class _Frame:
    """Map coordinates -> SVG pixels (north up)."""

    def __init__(self, bounds: tuple[float, float, float, float]) -> None:
        x0, y0, x1, y1 = bounds
        span = max(x1 - x0, y1 - y0, 1e-9)
        pad = 0.03 * span
        self.x0, self.y1 = x0 - pad, y1 + pad
        self.k = WIDTH / (x1 - x0 + 2 * pad if x1 > x0 else span + 2 * pad)
        self.height = max(120.0, min(3 * WIDTH, (y1 - y0 + 2 * pad) * self.k))

    def xy(self, x: float, y: float) -> str:
        return f"{(x - self.x0) * self.k:.2f},{(self.y1 - y) * self.k:.2f}"

    def ring(self, coords: Any) -> str:
        return "M" + "L".join(self.xy(x, y) for x, y, *_ in coords) + "Z"


def _path(frame: _Frame, g: Any) -> str:
    if g.geom_type == "Polygon":
        return "".join(frame.ring(r.coords) for r in (g.exterior, *g.interiors))
    if g.geom_type == "MultiPolygon":
        return "".join(_path(frame, p) for p in g.geoms)
    if g.geom_type == "LineString":
        return "M" + "L".join(frame.xy(x, y) for x, y, *_ in g.coords)
    return ""


def _feature_id(layer: str, props: Mapping[str, Any]) -> str:
    if layer == "checkpoints" or layer == "residuals":
        return f"{props.get('block')}/{props.get('point_id')}"
    if layer == "inspection_cells":
        return str(props.get("cell_id"))
    if layer == "seamlines":
        return str(props.get("image_id"))
    return str(props.get("id"))


def _extent(layers: FindingsLayers) -> tuple[float, float, float, float] | None:
    import shapely

    geoms = [g for name in MAP_LAYERS for g, _ in layers[name].features if g is not None]
    if not geoms:
        return None
    x0, y0, x1, y1 = (float(v) for v in shapely.total_bounds(geoms))
    return (x0, y0, x1, y1) if all(math.isfinite(v) for v in (x0, y0, x1, y1)) else None


def map_svg(
    layers: FindingsLayers, *, interactive: bool = False
) -> tuple[markupsafe.Markup, dict[str, Any]]:
    """(the SVG, what it drew: layer -> {verdict: count} and features left out). Each feature is an
    element with ``data-k`` (layer:index into the JSON island) and a ``<title>``."""
    bounds = _extent(layers)
    drawn: dict[str, Any] = {"counts": {}, "omitted": {}}
    if bounds is None:
        return markupsafe.Markup(""), drawn
    fr = _Frame(bounds)
    esc = markupsafe.escape
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" class="findings-map" viewBox="0 0 {WIDTH:.0f} {fr.height:.0f}" '
        f'width="100%" role="img" aria-label="Map of the findings">',
        '<defs><marker id="arrow" viewBox="0 0 6 6" refX="5" refY="3" markerWidth="5" markerHeight="5" '
        'orient="auto-start-reverse"><path d="M0,0L6,3L0,6Z" fill="#222"/></marker></defs>',
        '<g class="view">',
    ]
    r = max(2.5, WIDTH / 260)
    for name in MAP_LAYERS:
        layer = layers[name]
        idx, omitted = _chosen(layer)
        counts: dict[str, int] = {}
        out.append(f'<g class="layer" data-layer="{name}">')
        for k in idx:
            g, props = layer.features[k]
            verdict = props.get("verdict")
            counts[str(verdict)] = counts.get(str(verdict), 0) + 1
            c = _colour(verdict)
            title = (f"<title>{esc(_text(_LABEL[name]))} {esc(_text(_feature_id(name, props)))}: "
                     f"{esc(_text(verdict or 'not judged'))}</title>")
            key = (
                f'data-k="{name}:{k}" data-verdict="{esc(_text(verdict))}"'
                if interactive
                else f'data-verdict="{esc(_text(verdict))}"'
            )
            if name == "checkpoints":
                xy = fr.xy(g.x, g.y).split(",")
                out.append(
                    f'<circle {key} cx="{xy[0]}" cy="{xy[1]}" r="{r:.1f}" fill="{c}" stroke="#222" '
                    f'stroke-width="0.6">{title}</circle>'
                )
            elif name == "residuals":
                out.append(
                    f'<path {key} d="{_path(fr, g)}" stroke="#222" stroke-width="1" fill="none" '
                    f'marker-end="url(#arrow)">{title}</path>'
                )
            else:
                width = "2" if name == "blocks" else "0.8"
                opacity = "0.12" if name == "blocks" else "0.35"
                out.append(
                    f'<path {key} d="{_path(fr, g)}" fill="{c}" fill-opacity="{opacity}" stroke="{c}" '
                    f'stroke-width="{width}" fill-rule="evenodd">{title}</path>'
                )
        out.append("</g>")
        drawn["counts"][name] = counts
        if omitted:
            drawn["omitted"][name] = omitted
    out.append("</g></svg>")
    return markupsafe.Markup("".join(out)), drawn


def _island(layers: FindingsLayers) -> str:
    """Feature key -> what a click shows; JSON safe inside <script> (ASCII, no < > &)."""
    data: dict[str, Any] = {}
    for name in MAP_LAYERS:
        layer = layers[name]
        for k in _chosen(layer)[0]:
            props = layer.features[k][1]
            fid = _feature_id(name, props)
            recs = layers.records.get(name if name != "residuals" else "checkpoints", {}).get(
                fid, []
            )
            recs = sorted(recs, key=lambda r: V.severity_rank(str(r.get("verdict"))))[:MAX_RECORDS]
            data[f"{name}:{k}"] = {
                "layer": _LABEL[name],
                "id": _text(fid),
                "verdict": _text(props.get("verdict") or "not judged"),
                "props": [
                    [_text(a), _text(_shown(v))]
                    for a, v in props.items()
                    if a not in ("reasons", "evidence") and v is not None
                ],
                "records": [
                    [
                        _text(r.get("rule")),
                        _text(r.get("verdict")),
                        _text(r.get("message") or ""),
                        _text(
                            r.get("clause")
                            if isinstance(r.get("clause"), str)
                            else (r.get("clause") or {}).get("section", "")
                        ),
                    ]
                    for r in recs
                ],
            }
    text = json.dumps(data, ensure_ascii=True, sort_keys=True, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _shown(v: Any) -> Any:
    if isinstance(v, float):
        return f"{v:.4g}"
    return v


def map_html(layers: FindingsLayers, *, interactive: bool) -> markupsafe.Markup:
    """The map block of the report: the SVG, its legend and caption, and in HTML the script."""
    svg, drawn = map_svg(layers, interactive=interactive)
    if not svg:
        return markupsafe.Markup("")
    esc = markupsafe.escape
    legend = "".join(
        f'<span class="key"><i style="background:{_colour(v)}"></i>{esc(v)}</span>'
        for v in (*COLOURS,)
        if any(v in c for c in drawn["counts"].values())
    )
    counts = "; ".join(
        f"{_LABEL[n]}: "
        + ", ".join(
            f"{c} {esc(v if v != 'None' else 'not judged')}"
            for v, c in sorted(drawn["counts"][n].items())
        )
        for n in MAP_LAYERS
        if drawn["counts"].get(n)
    )
    left = "".join(
        f" {n} of the {_LABEL[name]} (passing) are not drawn;"
        for name, n in drawn["omitted"].items()
    )
    scale = layers["residuals"].metadata.get("residual_scale", "1")
    cap = (
        f'<p class="small map-caption">Drawn: {counts}.{esc(left)} Residual vectors are drawn {esc(scale)} times '
        f"their length. Coordinates: {esc(_text(layers.crs or 'the delivery CRS'))}."
        + (
            " Drag to pan, wheel to zoom, click a feature for its quality control records."
            if interactive
            else ""
        )
        + "</p>"
    )
    parts = [
        f'<div class="findings-map-box" id="findings-map">{svg}',
        f'<div class="legend">{legend}</div>',
        cap,
    ]
    if interactive:
        script = (templates_dir() / "map.js").read_text(encoding="utf-8")
        parts += [
            '<div class="map-panel" id="map-panel" aria-live="polite"><p class="muted">Click a block, an '
            "image footprint or a check point.</p></div>",
            f'<script type="application/json" id="findings-data">{_island(layers)}</script>',
            f"<script>{script}</script>",
        ]
    parts.append("</div>")
    return markupsafe.Markup("".join(parts))
