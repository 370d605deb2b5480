"""What a producer's XML metadata states: ISO 19115/19139 (INSPIRE, with ISO 19115-2 ``gmi``) and
FGDC CSDGM (NAIP-style), read with lxml.

Why lxml and XPath rather than OWSLib's objects: the draft must say, for each value it fills, the
file and the XPath it came from (the evidence a checker can open and read); OWSLib returns values
without the node they were read from. OWSLib parses the same files independently in the tests,
as the reference the values here are compared with.

Hostile XML: the parser never touches the network, never loads a DTD, never substitutes an
entity; a document that *declares* entities (the billion-laughs and external-entity attacks both
need one) is refused with a line in the draft's report, never parsed further. Files larger than
``ORTHOSPEC_MAX_XML_BYTES`` (16 MiB) are refused before parsing.
"""

from __future__ import annotations

import datetime as dt
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..limits import env_limit

NS = {
    "gmd": "http://www.isotc211.org/2005/gmd",
    "gco": "http://www.isotc211.org/2005/gco",
    "gmi": "http://www.isotc211.org/2005/gmi",
    "gmx": "http://www.isotc211.org/2005/gmx",
    "gml": "http://www.opengis.net/gml/3.2",
    "gml31": "http://www.opengis.net/gml",
    "xlink": "http://www.w3.org/1999/xlink",
}
XML_BYTES = 16 << 20

#: platform, mission and instrument names whose sensor type is not in doubt (words matched case-
#: insensitively at word starts); a name matching neither list states no type
SATELLITE_NAMES = ("landsat", "sentinel", "spot", "pleiades", "pléiades", "worldview", "geoeye",
                   "quickbird", "ikonos", "kompsat", "rapideye", "planetscope", "skysat", "deimos",
                   "cartosat", "resourcesat", "gaofen", "superview", "triplesat", "aster", "modis",
                   "satellite", "spacecraft")
AERIAL_NAMES = ("aircraft", "airplane", "aeroplane", "helicopter", "uav", "drone", "aerial")
#: named digital aerial cameras (their type is aerial, their sensor digital)
DIGITAL_CAMERAS = ("ultracam", "dmc", "ads40", "ads80", "ads100", "rcd30", "a3 edge", "phase one",
                   "phaseone", "citymapper", "rmk d")
#: named film cameras (aerial, not digital)
FILM_CAMERAS = ("rc30", "rc20", "rc10", "rmk top", "rmk a")


@dataclass(frozen=True)
class Stated:
    """One value a metadata file states: the draft field it fills and where it was read."""

    field: str
    value: Any
    file: str
    xpath: str
    line: int | None = None

    @property
    def where(self) -> str:
        return f"{self.file}{f':{self.line}' if self.line else ''} {self.xpath}"


@dataclass
class MetadataRead:
    """A metadata file's statements, or why it was not read."""

    file: str
    standard: str | None = None  # "ISO 19139" | "FGDC CSDGM"
    stated: list[Stated] = field(default_factory=list)
    refused: str | None = None
    notes: list[str] = field(default_factory=list)


def safe_parse(path: Path, name: str) -> tuple[Any, str | None]:
    """(lxml tree, None) or (None, why the file is refused). Never reads the network or a DTD and
    never expands an entity."""
    from lxml import etree

    limit = env_limit("ORTHOSPEC_MAX_XML_BYTES", XML_BYTES)
    try:
        size = path.stat().st_size
    except OSError as exc:
        return None, f"cannot be read: {exc.strerror or exc}"
    if size > limit:
        return None, f"{size} bytes, larger than ORTHOSPEC_MAX_XML_BYTES ({limit}): not parsed"
    parser = etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_comments=True,
        remove_pis=True,
    )
    try:
        data = path.read_bytes()
        tree = etree.fromstring(data, parser).getroottree()
    except etree.XMLSyntaxError as exc:
        return None, f"is not well-formed XML ({exc.msg}, line {exc.lineno})"
    except (OSError, ValueError) as exc:
        return None, f"cannot be parsed: {exc}"
    dtd = tree.docinfo.internalDTD
    if dtd is not None and (list(dtd.iterentities()) or list(dtd.elements())):
        return None, (
            "declares a DTD with entities or elements (<!ENTITY>/<!ELEMENT>): refused unread, "
            "entities are never expanded (external entities, billion laughs)"
        )
    return tree, None


def _text(node: Any) -> str | None:
    if node is None:
        return None
    t = node if isinstance(node, str) else "".join(node.itertext())
    t = " ".join(t.split())
    return t or None


class _Reader:
    """XPath look-ups that remember where each value came from."""

    def __init__(self, tree: Any, file: str, ns: dict[str, str] | None) -> None:
        self.tree, self.file, self.ns = tree, file, ns
        self.out: list[Stated] = []

    def first(self, *xpaths: str) -> tuple[str | None, str | None, int | None]:
        """(text, xpath, line) of the first non-empty match of the first xpath that matches."""
        for xp in xpaths:
            for node in self.tree.xpath(xp, namespaces=self.ns):
                t = _text(node)
                if t:
                    # a text() or @attr match is lxml's "smart string": its line is its element's
                    parent = getattr(node, "getparent", None) if isinstance(node, str) else None
                    line = getattr(parent() if parent else node, "sourceline", None)
                    return t, xp, line
        return None, None, None

    def state(self, field_: str, value: Any, xpath: str | None, line: int | None) -> None:
        if value is not None and value != "" and xpath is not None:
            self.out.append(Stated(field_, value, self.file, xpath, line))

    def take(self, field_: str, *xpaths: str, convert: Any = None) -> Any:
        t, xp, line = self.first(*xpaths)
        if t is None:
            return None
        v = convert(t) if convert else t
        self.state(field_, v, xp, line)
        return v


def _date(text: str) -> dt.date | None:
    """A date from ISO 8601 (``2026-04-09``, ``2026-04-09T10:00:00Z``) or FGDC (``20260409``)."""
    t = text.strip()
    m = re.fullmatch(r"(\d{4})-?(\d{2})-?(\d{2})(?:[T ].*)?", t)
    if not m:
        return None
    try:
        return dt.date(int(m[1]), int(m[2]), int(m[3]))
    except ValueError:
        return None


def _number(text: str) -> float | None:
    try:
        v = float(text.strip())
    except ValueError:
        return None
    return v if v == v and abs(v) != float("inf") else None


_UOM = {
    "9001": "m",
    "9002": "ft",
    "9003": "usft",
    "m": "m",
    "metre": "m",
    "metres": "m",
    "meter": "m",
    "meters": "m",
    "cm": "cm",
    "mm": "mm",
    "ft": "ft",
    "feet": "ft",
    "foot": "ft",
    "international feet": "ft",
    "survey feet": "usft",
    "us survey feet": "usft",
    "usft": "usft",
    "ft_us": "usft",
}


def _uom(text: str | None) -> str | None:
    if not text:
        return None
    t = text.strip().lower()
    t = t.rsplit("#", 1)[-1].rsplit("/", 1)[-1] if ("#" in t or "/" in t) else t
    return _UOM.get(t)


def sensor_of(names: list[str]) -> tuple[str | None, bool | None]:
    """(sensor type, digital) stated by platform and instrument names (docs/INGEST.md lists the
    words): a type only when every name that names one agrees, ``digital`` only for a satellite or
    a named camera; None where the names do not say."""
    types: set[str] = set()
    digital: set[bool] = set()
    for n in names:
        low = n.lower()

        def has(words: tuple[str, ...], low: str = low) -> bool:
            return any(re.search(rf"(?<![a-z]){re.escape(w)}", low) for w in words)

        if has(SATELLITE_NAMES):
            types.add("satellite")
            digital.add(True)
        if has(AERIAL_NAMES):
            types.add("aerial")
        if has(DIGITAL_CAMERAS):
            types.add("aerial")
            digital.add(True)
        if has(FILM_CAMERAS):
            types.add("aerial")
            digital.add(False)
    return (types.pop() if len(types) == 1 else None), (
        digital.pop() if len(digital) == 1 else None
    )


def _epsg_from_code(text: str) -> str | None:
    m = re.search(r"(?:EPSG\D{0,12}|/EPSG/\d+/|^)(\d{4,6})\s*$", text.strip(), flags=re.IGNORECASE)
    return f"EPSG:{m[1]}" if m else None


def read_iso(tree: Any, file: str) -> MetadataRead:
    r = _Reader(tree, file, NS)
    root = (
        "/gmi:MI_Metadata"
        if tree.getroot().tag == f"{{{NS['gmi']}}}MI_Metadata"
        else "/gmd:MD_Metadata"
    )
    ident = f"{root}/gmd:identificationInfo/*"
    r.take(
        "id",
        f"{root}/gmd:fileIdentifier/gco:CharacterString",
        f"{root}/gmd:fileIdentifier/gmx:Anchor",
    )
    r.take("project.id", f"{root}/gmd:parentIdentifier/gco:CharacterString")
    r.take("project.name", f"{ident}/gmd:citation/gmd:CI_Citation/gmd:title/gco:CharacterString")
    for role in ("originator", "processor", "author"):
        party = (
            f"{ident}/gmd:pointOfContact/gmd:CI_ResponsibleParty"
            f"[gmd:role/gmd:CI_RoleCode/@codeListValue='{role}']"
        )
        if (
            r.take("contractor.name", f"{party}/gmd:organisationName/gco:CharacterString")
            is not None
        ):
            r.take(
                "contractor.contact",
                f"{party}/gmd:contactInfo/gmd:CI_Contact/gmd:address/gmd:CI_Address/"
                "gmd:electronicMailAddress/gco:CharacterString",
            )
            break
    code, xp, line = r.first(
        f"{root}/gmd:referenceSystemInfo/gmd:MD_ReferenceSystem/gmd:referenceSystemIdentifier/"
        "gmd:RS_Identifier/gmd:code/gco:CharacterString",
        f"{root}/gmd:referenceSystemInfo/gmd:MD_ReferenceSystem/gmd:referenceSystemIdentifier/"
        "gmd:RS_Identifier/gmd:code/gmx:Anchor",
        f"{root}/gmd:referenceSystemInfo/gmd:MD_ReferenceSystem/gmd:referenceSystemIdentifier/"
        "gmd:RS_Identifier/gmd:code/gmx:Anchor/@xlink:href",
    )
    if code is not None:
        r.state("project.crs", _epsg_from_code(code), xp, line)
    dist = f"{ident}/gmd:spatialResolution/gmd:MD_Resolution/gmd:distance/gco:Distance"
    value, xp, line = r.first(dist)
    if value is not None:
        uom = _uom(tree.xpath(f"string({dist}/@uom)", namespaces=NS))
        v = _number(value)
        if v is not None and uom is not None:
            r.state("product.gsd", {"value": v, "unit": uom}, xp, line)
    temporal = (
        f"{ident}/gmd:extent/gmd:EX_Extent/gmd:temporalElement/gmd:EX_TemporalExtent/gmd:extent"
    )
    for key, tag in (
        ("dates.acquired_from", "beginPosition"),
        ("dates.acquired_to", "endPosition"),
    ):
        r.take(
            key,
            f"{temporal}/gml:TimePeriod/gml:{tag}",
            f"{temporal}/gml31:TimePeriod/gml31:{tag}",
            convert=_date,
        )
    report = (
        f"{root}/gmd:dataQualityInfo/gmd:DQ_DataQuality/gmd:report/"
        "gmd:DQ_AbsoluteExternalPositionalAccuracy"
    )
    acc, xp, line = r.first(f"{report}/gmd:result/gmd:DQ_QuantitativeResult/gmd:value/gco:Record")
    if acc is not None:
        measure = _text(
            next(
                iter(tree.xpath(f"{report}/gmd:nameOfMeasure/gco:CharacterString", namespaces=NS)),
                None,
            )
        )
        unit = (
            tree.xpath(
                f"string({report}/gmd:result/gmd:DQ_QuantitativeResult/gmd:valueUnit/@xlink:href)",
                namespaces=NS,
            )
            or ""
        )
        unit = _uom(unit) or unit.rsplit("#", 1)[-1] or ""
        r.state(
            "product.accuracy_statement",
            f"{measure + ': ' if measure else ''}{acc}{' ' + unit if unit else ''}",
            xp,
            line,
        )
    r.take(
        "lineage",
        f"{root}/gmd:dataQualityInfo/gmd:DQ_DataQuality/gmd:lineage/gmd:LI_Lineage/gmd:statement/"
        "gco:CharacterString",
    )
    acq = f"{root}/gmi:acquisitionInformation/gmi:MI_AcquisitionInformation"
    platform = r.take(
        "sensor.platform",
        f"{acq}/gmi:platform/gmi:MI_Platform/gmi:identifier/gmd:MD_Identifier/"
        "gmd:code/gco:CharacterString",
        f"{acq}/gmi:platform/gmi:MI_Platform/gmi:description/gco:CharacterString",
    )
    camera = r.take(
        "sensor.camera",
        f"{acq}/gmi:instrument/gmi:MI_Instrument/gmi:identifier/gmd:MD_Identifier/"
        "gmd:code/gco:CharacterString",
        f"{acq}/gmi:platform/gmi:MI_Platform/gmi:instrument/gmi:MI_Instrument/gmi:identifier/"
        "gmd:MD_Identifier/gmd:code/gco:CharacterString",
        f"{acq}/gmi:instrument/gmi:MI_Instrument/gmi:type/gco:CharacterString",
    )
    _sensor(r, [x for x in (platform, camera) if x])
    bits = r.first(
        f"{root}/gmd:contentInfo/*/gmd:dimension/gmd:MD_Band/gmd:bitsPerValue/gco:Integer"
    )
    if bits[0] is not None and bits[0].isdigit():
        r.state("product.bit_depth", int(bits[0]), bits[1], bits[2])
    return MetadataRead(file, "ISO 19139", r.out)


def _sensor(r: _Reader, names: list[str]) -> None:
    """sensor.type / sensor.digital from the platform and instrument names just read (same evidence)."""
    kind, digital = sensor_of(names)
    src = [s for s in r.out if s.field in ("sensor.platform", "sensor.camera")]
    if not src:
        return
    where = src[0]
    if kind is not None:
        r.out.append(
            Stated("sensor.type", kind, where.file, " + ".join(s.xpath for s in src), where.line)
        )
    if digital is not None:
        r.out.append(
            Stated(
                "sensor.digital", digital, where.file, " + ".join(s.xpath for s in src), where.line
            )
        )


_UTM_DATUM = {
    "north american datum of 1983": "NAD83",
    "nad83": "NAD83",
    "nad 83": "NAD83",
    "world geodetic system 1984": "WGS 84",
    "wgs84": "WGS 84",
    "wgs 84": "WGS 84",
    "european terrestrial reference system 1989": "ETRS89",
    "etrs89": "ETRS89",
    "etrs 89": "ETRS89",
}


def read_fgdc(tree: Any, file: str) -> MetadataRead:
    r = _Reader(tree, file, None)
    cite = "/metadata/idinfo/citation/citeinfo"
    r.take("project.name", f"{cite}/title")
    r.take("contractor.name", f"{cite}/origin")
    r.take("contractor.contact", "/metadata/idinfo/ptcontac/cntinfo/cntemail")
    tp = "/metadata/idinfo/timeperd/timeinfo"
    r.take("dates.acquired_from", f"{tp}/rngdates/begdate", f"{tp}/sngdate/caldate", convert=_date)
    r.take("dates.acquired_to", f"{tp}/rngdates/enddate", f"{tp}/sngdate/caldate", convert=_date)
    planar = "/metadata/spref/horizsys/planar"
    zone, zxp, zline = r.first(f"{planar}/gridsys/utm/utmzone")
    datum, dxp, _ = r.first("/metadata/spref/horizsys/geodetic/horizdn")
    if zone is not None and datum is not None:
        z = _number(zone)
        name = _UTM_DATUM.get(datum.strip().lower())
        if z is not None and name and 1 <= abs(z) <= 60 and z == int(z):
            crs = _crs_epsg(f"{name} / UTM zone {abs(int(z))}{'N' if z > 0 else 'S'}")
            r.state("project.crs", crs, f"{zxp} + {dxp}", zline)
    absres, axp, aline = r.first(f"{planar}/planci/coordrep/absres")
    ordres = r.first(f"{planar}/planci/coordrep/ordres")[0]
    unit = _uom(r.first(f"{planar}/planci/plandu")[0])
    if absres is not None and unit is not None:
        a, o = _number(absres), _number(ordres) if ordres else None
        if a is not None and (o is None or o == a):
            r.state("product.gsd", {"value": a, "unit": unit}, axp, aline)
    pa = "/metadata/dataqual/posacc/horizpa"
    value, xp, line = r.first(f"{pa}/qhorizpa/horizpav")
    if value is not None:
        expl = r.first(f"{pa}/qhorizpa/horizpae")[0]
        r.state(
            "product.accuracy_statement", f"{value}{' (' + expl + ')' if expl else ''}", xp, line
        )
    else:
        r.take("product.accuracy_statement", f"{pa}/horizpar")
    r.take("lineage", "/metadata/dataqual/lineage/procstep/procdesc")
    platform = r.take(
        "sensor.platform",
        "/metadata/idinfo/plainsid/platflnm",
        "/metadata/idinfo/plainsid/missname",
    )
    camera = r.take(
        "sensor.camera", "/metadata/idinfo/plainsid/instshnm", "/metadata/idinfo/plainsid/instflnm"
    )
    _sensor(r, [x for x in (platform, camera) if x])
    return MetadataRead(file, "FGDC CSDGM", r.out)


def _crs_epsg(name: str) -> str | None:
    from ..delivery.crs import CrsProblem, epsg_name

    try:
        return epsg_name(name)
    except CrsProblem:
        return None


def read_metadata(path: Path, name: str) -> MetadataRead | None:
    """The statements of one XML file; None when it is XML of neither standard (not metadata)."""
    tree, why = safe_parse(path, name)
    if tree is None:
        return MetadataRead(name, refused=why)
    root = tree.getroot()
    qname = root.tag if isinstance(root.tag, str) else ""
    if qname in (f"{{{NS['gmd']}}}MD_Metadata", f"{{{NS['gmi']}}}MI_Metadata"):
        return read_iso(tree, name)
    if qname == "metadata" and root.find("idinfo") is not None:
        return read_fgdc(tree, name)
    return None
