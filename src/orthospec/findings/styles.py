"""Verdict colours, one table for the GeoPackage's QGIS styles and the HTML map.

The styles categorise on the ``verdict`` attribute (a closed vocabulary: no delivery text ever
reaches a style); built with lxml so every value is escaped by the serialiser.
"""

from __future__ import annotations

from lxml import etree

from .. import verdicts as V
from .layers import Layer

__all__ = ["COLOURS", "OTHER", "qml", "sld"]

#: verdict -> RGB (colour-blind safe order: red, orange, purple, yellow, grey, green)
COLOURS: dict[str, tuple[int, int, int]] = {
    V.FAIL: (215, 48, 39), V.ERROR: (153, 52, 4), V.MISSING: (118, 42, 131), V.WARN: (254, 196, 79),
    V.WAIVED: (150, 150, 150), V.PASS: (26, 152, 80), V.NOT_APPLICABLE: (200, 200, 200)}
OTHER = (120, 120, 120)  # not judged (no record)
_KIND = {"Polygon": "fill", "Point": "marker", "LineString": "line"}


def _rgba(rgb: tuple[int, int, int], alpha: int = 255) -> str:
    return f"{rgb[0]},{rgb[1]},{rgb[2]},{alpha}"


def _option(parent: etree._Element, name: str, value: str) -> None:
    etree.SubElement(parent, "Option", name=name, type="QString", value=value)


def _symbol(parent: etree._Element, kind: str, name: str, rgb: tuple[int, int, int]) -> None:
    sym = etree.SubElement(parent, "symbol", type=kind, name=name, alpha="1", clip_to_extent="1",
                           force_rhr="0")
    cls = {"fill": "SimpleFill", "marker": "SimpleMarker", "line": "SimpleLine"}[kind]
    lay = etree.SubElement(
        sym, "layer", attrib={"class": cls, "enabled": "1", "pass": "0", "locked": "0"}
    )
    opts = etree.SubElement(lay, "Option", type="Map")
    if kind == "fill":
        _option(opts, "color", _rgba(rgb, 90))
        _option(opts, "outline_color", _rgba(rgb))
        _option(opts, "outline_width", "0.6")
        _option(opts, "style", "solid")
    elif kind == "marker":
        _option(opts, "name", "circle")
        _option(opts, "color", _rgba(rgb))
        _option(opts, "outline_color", "35,35,35,255")
        _option(opts, "size", "2.6")
    else:
        _option(opts, "line_color", _rgba(rgb))
        _option(opts, "line_width", "0.5")


def qml(layer: Layer) -> str:
    """QGIS QML: a categorised renderer on ``verdict`` (every verdict, plus 'not judged')."""
    kind = _KIND[str(layer.geometry_type)]
    root = etree.Element("qgis", version="3.28.0", styleCategories="Symbology")
    rend = etree.SubElement(
        root,
        "renderer-v2",
        type="categorizedSymbol",
        attr="verdict",
        symbollevels="0",
        enableorderby="0",
        forceraster="0",
    )
    cats = etree.SubElement(rend, "categories")
    syms = etree.SubElement(rend, "symbols")
    for k, (verdict, rgb) in enumerate([*COLOURS.items(), ("", OTHER)]):
        etree.SubElement(
            cats,
            "category",
            symbol=str(k),
            value=verdict,
            label=verdict or "not judged",
            render="true",
        )
        _symbol(syms, kind, str(k), rgb)
    etree.SubElement(root, "layerGeometryType").text = {"marker": "0", "line": "1", "fill": "2"}[
        kind
    ]
    return "<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>\n" + etree.tostring(
        root, encoding="unicode"
    )


_SLD = "http://www.opengis.net/sld"
_OGC = "http://www.opengis.net/ogc"
_SE = "http://www.opengis.net/se"


def sld(layer: Layer) -> str:
    """The same colours as an SLD 1.1 (QGIS stores both; other GIS read the SLD)."""
    kind = _KIND[str(layer.geometry_type)]
    nsmap = {None: _SLD, "ogc": _OGC, "se": _SE}
    root = etree.Element(f"{{{_SLD}}}StyledLayerDescriptor", nsmap=nsmap, version="1.1.0")
    nl = etree.SubElement(root, f"{{{_SLD}}}NamedLayer")
    etree.SubElement(nl, f"{{{_SE}}}Name").text = layer.name
    fts = etree.SubElement(
        etree.SubElement(nl, f"{{{_SLD}}}UserStyle"), f"{{{_SE}}}FeatureTypeStyle"
    )
    for verdict, rgb in COLOURS.items():
        rule = etree.SubElement(fts, f"{{{_SE}}}Rule")
        etree.SubElement(rule, f"{{{_SE}}}Name").text = verdict
        flt = etree.SubElement(rule, f"{{{_OGC}}}Filter")
        eq = etree.SubElement(flt, f"{{{_OGC}}}PropertyIsEqualTo")
        etree.SubElement(eq, f"{{{_OGC}}}PropertyName").text = "verdict"
        etree.SubElement(eq, f"{{{_OGC}}}Literal").text = verdict
        colour = "#{:02x}{:02x}{:02x}".format(*rgb)
        if kind == "fill":
            sym = etree.SubElement(rule, f"{{{_SE}}}PolygonSymbolizer")
            fill = etree.SubElement(sym, f"{{{_SE}}}Fill")
            etree.SubElement(fill, f"{{{_SE}}}SvgParameter", name="fill").text = colour
            etree.SubElement(fill, f"{{{_SE}}}SvgParameter", name="fill-opacity").text = "0.35"
            stroke = etree.SubElement(sym, f"{{{_SE}}}Stroke")
        elif kind == "marker":
            sym = etree.SubElement(rule, f"{{{_SE}}}PointSymbolizer")
            mark = etree.SubElement(etree.SubElement(sym, f"{{{_SE}}}Graphic"), f"{{{_SE}}}Mark")
            etree.SubElement(mark, f"{{{_SE}}}WellKnownName").text = "circle"
            fill = etree.SubElement(mark, f"{{{_SE}}}Fill")
            etree.SubElement(fill, f"{{{_SE}}}SvgParameter", name="fill").text = colour
            stroke = etree.SubElement(mark, f"{{{_SE}}}Stroke")
        else:
            sym = etree.SubElement(rule, f"{{{_SE}}}LineSymbolizer")
            stroke = etree.SubElement(sym, f"{{{_SE}}}Stroke")
        etree.SubElement(stroke, f"{{{_SE}}}SvgParameter", name="stroke").text = colour
    return etree.tostring(root, encoding="unicode")
