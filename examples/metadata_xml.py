"""The producer's metadata XML of the example deliveries (issue 30 item 3), written by generate.py.

Every example delivery carries its metadata as real deliveries do, in the delivery convention's
``metadata/`` folder (docs/METADATA.md): an FGDC CSDGM file (FGDC-STD-001-1998, the XML schema's
short element names) for the aerial deliveries, an ISO 19139 ``gmd:MD_Metadata`` for the
satellite ones. They state what the producer declares (identification, extent, reference system,
lineage, the contractor's own accuracy claim); `orthospec check --format iso19157` writes updated
copies of them to ``--out`` with the checker's measured quality. Nothing here is read by a rule.

Values come from the manifest generate.py writes (the same delivery id, dates, blocks, CRS), so
the files agree with the rest of the delivery; the extent is the blocks' outlines in WGS 84.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from lxml import etree
from pyproj import Transformer

GMD = "http://www.isotc211.org/2005/gmd"
GCO = "http://www.isotc211.org/2005/gco"
GML = "http://www.opengis.net/gml/3.2"
XLINK = "http://www.w3.org/1999/xlink"
CODELISTS = "http://standards.iso.org/iso/19139/resources/gmxCodelists.xml"


def _bbox(manifest: dict[str, Any]) -> tuple[float, float, float, float]:
    """(west, east, south, north) in degrees of every block outline's vertices."""
    to_wgs84 = Transformer.from_crs(manifest["project"]["crs"], 4326, always_xy=True)
    lon, lat = [], []
    for blk in manifest["blocks"]:
        for e, n in blk["polygon"]:
            x, y = to_wgs84.transform(e, n)
            lon.append(x)
            lat.append(y)
    return round(min(lon), 6), round(max(lon), 6), round(min(lat), 6), round(max(lat), 6)


def _day(value: Any) -> str:
    return str(value)[:10]


def _sub(parent: etree._Element, tag: str, text: str | None = None) -> etree._Element:
    el = etree.SubElement(parent, tag)
    if text is not None:
        el.text = text
    return el


def _contact(parent: etree._Element, manifest: dict[str, Any]) -> None:
    info = _sub(parent, "cntinfo")
    _sub(_sub(info, "cntorgp"), "cntorg", manifest["contractor"]["name"])
    addr = _sub(info, "cntaddr")
    _sub(addr, "addrtype", "mailing and physical")
    _sub(addr, "address", "Example Street 1 (fictional)")
    _sub(addr, "city", "Example City")
    _sub(addr, "state", "n/a")
    _sub(addr, "postal", "00000")
    _sub(info, "cntvoice", "+00 000 000 000 (fictional)")
    _sub(info, "cntemail", manifest["contractor"]["contact"])


def fgdc_csdgm(manifest: dict[str, Any]) -> bytes:
    """An FGDC CSDGM (FGDC-STD-001-1998) record of an aerial delivery, short element names."""
    dates = manifest["dates"]
    root = etree.Element("metadata")
    idinfo = _sub(root, "idinfo")
    cite = _sub(_sub(idinfo, "citation"), "citeinfo")
    _sub(cite, "origin", manifest["contractor"]["name"])
    _sub(cite, "pubdate", _day(dates["delivered"]).replace("-", ""))
    _sub(cite, "title", f"{manifest['project']['name']}: orthophotos, delivery {manifest['id']}")
    _sub(cite, "geoform", "remote-sensing image")
    descript = _sub(idinfo, "descript")
    gsd = manifest["product"]["gsd"]["value"]
    _sub(
        descript,
        "abstract",
        f"Digital orthophotos, {gsd} m ground sample distance, bands "
        f"{', '.join(manifest['product']['bands'])}, {len(manifest['blocks'])} "
        f"aerotriangulation blocks, camera {manifest['sensor'].get('camera', '')}.",
    )
    _sub(
        descript,
        "purpose",
        "Orthoimagery for the control of area-based subsidies (fictional example).",
    )
    timeperd = _sub(idinfo, "timeperd")
    rng = _sub(_sub(timeperd, "timeinfo"), "rngdates")
    _sub(rng, "begdate", _day(dates["acquired_from"]).replace("-", ""))
    _sub(rng, "enddate", _day(dates["acquired_to"]).replace("-", ""))
    _sub(timeperd, "current", "ground condition")
    status = _sub(idinfo, "status")
    _sub(status, "progress", "Complete")
    _sub(status, "update", "None planned")
    west, east, south, north = _bbox(manifest)
    bounding = _sub(_sub(idinfo, "spdom"), "bounding")
    for tag, v in (("westbc", west), ("eastbc", east), ("northbc", north), ("southbc", south)):
        _sub(bounding, tag, f"{v:.6f}")
    theme = _sub(_sub(idinfo, "keywords"), "theme")
    _sub(theme, "themekt", "None")
    _sub(theme, "themekey", "orthoimagery")
    _sub(theme, "themekey", "aerial photography")
    _sub(idinfo, "accconst", "None")
    _sub(idinfo, "useconst", "For the contracting agency's control campaign only (fictional).")
    _contact(_sub(idinfo, "ptcontac"), manifest)

    dataqual = _sub(root, "dataqual")
    _sub(_sub(dataqual, "attracc"), "attraccr", "Not applicable: image data, no attributes.")
    _sub(
        dataqual,
        "logic",
        "Every image delivered as one GeoTIFF in the project CRS; names match the image table.",
    )
    _sub(
        dataqual,
        "complete",
        "Full coverage of the area of interest (the contractor's declaration).",
    )
    horizpa = _sub(_sub(dataqual, "posacc"), "horizpa")
    worst = max(
        max(b["reported"]["rmse_x"]["value"], b["reported"]["rmse_y"]["value"])
        for b in manifest["blocks"]
    )
    _sub(
        horizpa,
        "horizpar",
        "Contractor's internal QC: RMSE x/y on independent GNSS check points per block "
        "(declared, not tested by the buyer).",
    )
    q = _sub(horizpa, "qhorizpa")
    _sub(q, "horizpav", f"{worst:.2f}")
    _sub(q, "horizpae", "Largest of the declared per-block RMSE x and RMSE y, metres.")
    step = _sub(_sub(dataqual, "lineage"), "procstep")
    _sub(
        step,
        "procdesc",
        "Aerotriangulation with GNSS/IMU and ground control, orthorectification on the "
        "DTM with cubic resampling, radiometric balancing.",
    )
    _sub(step, "procdate", _day(dates["delivered"]).replace("-", ""))

    spdoinfo = _sub(root, "spdoinfo")
    _sub(spdoinfo, "direct", "Raster")
    zone = (
        int(str(manifest["project"]["crs"]).rsplit(":", 1)[1]) - 25800
    )  # EPSG:258zz: ETRS89 / UTM zz N
    horizsys = _sub(_sub(root, "spref"), "horizsys")
    planar = _sub(horizsys, "planar")
    grid = _sub(planar, "gridsys")
    _sub(grid, "gridsysn", "Universal Transverse Mercator")
    utm = _sub(grid, "utm")
    _sub(utm, "utmzone", str(zone))
    tm = _sub(utm, "transmer")
    for tag, v in (
        ("sfctrmer", "0.9996"),
        ("longcm", str(6 * zone - 183)),
        ("latprjo", "0"),
        ("feast", "500000"),
        ("fnorth", "0"),
    ):
        _sub(tm, tag, v)
    planci = _sub(planar, "planci")
    _sub(planci, "plance", "row and column")
    coord = _sub(planci, "coordrep")
    _sub(coord, "absres", str(gsd))
    _sub(coord, "ordres", str(gsd))
    _sub(planci, "plandu", "meters")
    geodetic = _sub(horizsys, "geodetic")
    _sub(geodetic, "horizdn", "European Terrestrial Reference System 1989")
    _sub(geodetic, "ellips", "GRS 1980")
    _sub(geodetic, "semiaxis", "6378137")
    _sub(geodetic, "denflat", "298.257222101")

    metainfo = _sub(root, "metainfo")
    _sub(metainfo, "metd", _day(dates["delivered"]).replace("-", ""))
    _contact(_sub(metainfo, "metc"), manifest)
    _sub(metainfo, "metstdn", "FGDC Content Standard for Digital Geospatial Metadata")
    _sub(metainfo, "metstdv", "FGDC-STD-001-1998")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _g(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _cs(
    parent: etree._Element, tag: str, text: str, kind: str = "CharacterString"
) -> etree._Element:
    el = etree.SubElement(parent, _g(GMD, tag))
    etree.SubElement(el, _g(GCO, kind)).text = text
    return el


def _codev(parent: etree._Element, tag: str, code: str, value: str) -> None:
    el = etree.SubElement(etree.SubElement(parent, _g(GMD, tag)), _g(GMD, code))
    el.set("codeList", f"{CODELISTS}#{code}")
    el.set("codeListValue", value)
    el.text = value


def _party(parent: etree._Element, tag: str, manifest: dict[str, Any], role: str) -> None:
    rp = etree.SubElement(etree.SubElement(parent, _g(GMD, tag)), _g(GMD, "CI_ResponsibleParty"))
    _cs(rp, "organisationName", manifest["contractor"]["name"])
    ci = etree.SubElement(etree.SubElement(rp, _g(GMD, "contactInfo")), _g(GMD, "CI_Contact"))
    addr = etree.SubElement(etree.SubElement(ci, _g(GMD, "address")), _g(GMD, "CI_Address"))
    _cs(addr, "electronicMailAddress", manifest["contractor"]["contact"])
    _codev(rp, "role", "CI_RoleCode", role)


def iso19139(manifest: dict[str, Any]) -> bytes:
    """An ISO 19139 ``gmd:MD_Metadata`` record of a satellite delivery."""
    dates = manifest["dates"]
    root = etree.Element(
        _g(GMD, "MD_Metadata"), nsmap={"gmd": GMD, "gco": GCO, "gml": GML, "xlink": XLINK}
    )
    _cs(root, "fileIdentifier", manifest["id"])
    lang = etree.SubElement(etree.SubElement(root, _g(GMD, "language")), _g(GMD, "LanguageCode"))
    lang.set("codeList", "http://www.loc.gov/standards/iso639-2/")
    lang.set("codeListValue", "eng")
    lang.text = "eng"
    _codev(root, "characterSet", "MD_CharacterSetCode", "utf8")
    _codev(root, "hierarchyLevel", "MD_ScopeCode", "dataset")
    _party(root, "contact", manifest, "pointOfContact")
    _cs(root, "dateStamp", _day(dates["delivered"]), "Date")
    _cs(root, "metadataStandardName", "ISO 19115:2003/19139")
    _cs(root, "metadataStandardVersion", "1.0")
    rs = etree.SubElement(
        etree.SubElement(root, _g(GMD, "referenceSystemInfo")), _g(GMD, "MD_ReferenceSystem")
    )
    rid = etree.SubElement(
        etree.SubElement(rs, _g(GMD, "referenceSystemIdentifier")), _g(GMD, "RS_Identifier")
    )
    _cs(rid, "code", str(manifest["project"]["crs"]))
    _cs(rid, "codeSpace", "EPSG")

    ident = etree.SubElement(
        etree.SubElement(root, _g(GMD, "identificationInfo")), _g(GMD, "MD_DataIdentification")
    )
    cit = etree.SubElement(etree.SubElement(ident, _g(GMD, "citation")), _g(GMD, "CI_Citation"))
    _cs(cit, "title", f"{manifest['project']['name']}: orthoimages, delivery {manifest['id']}")
    cd = etree.SubElement(etree.SubElement(cit, _g(GMD, "date")), _g(GMD, "CI_Date"))
    _cs(cd, "date", _day(dates["delivered"]), "Date")
    _codev(cd, "dateType", "CI_DateTypeCode", "publication")
    gsd = manifest["product"]["gsd"]["value"]
    _cs(
        ident,
        "abstract",
        f"Orthorectified {manifest['sensor']['platform']} imagery, {gsd} m pixels, "
        f"{len(manifest['blocks'])} control sites (fictional example).",
    )
    _party(ident, "pointOfContact", manifest, "originator")
    _codev(ident, "spatialRepresentationType", "MD_SpatialRepresentationTypeCode", "grid")
    dist = etree.SubElement(
        etree.SubElement(
            etree.SubElement(ident, _g(GMD, "spatialResolution")), _g(GMD, "MD_Resolution")
        ),
        _g(GMD, "distance"),
    )
    d = etree.SubElement(dist, _g(GCO, "Distance"))
    d.set("uom", "m")
    d.text = str(gsd)
    lang2 = etree.SubElement(etree.SubElement(ident, _g(GMD, "language")), _g(GMD, "LanguageCode"))
    lang2.set("codeList", "http://www.loc.gov/standards/iso639-2/")
    lang2.set("codeListValue", "eng")
    lang2.text = "eng"
    etree.SubElement(
        etree.SubElement(ident, _g(GMD, "topicCategory")), _g(GMD, "MD_TopicCategoryCode")
    ).text = "imageryBaseMapsEarthCover"
    ext = etree.SubElement(etree.SubElement(ident, _g(GMD, "extent")), _g(GMD, "EX_Extent"))
    box = etree.SubElement(
        etree.SubElement(ext, _g(GMD, "geographicElement")), _g(GMD, "EX_GeographicBoundingBox")
    )
    west, east, south, north = _bbox(manifest)
    for tag, v in (
        ("westBoundLongitude", west),
        ("eastBoundLongitude", east),
        ("southBoundLatitude", south),
        ("northBoundLatitude", north),
    ):
        _cs(box, tag, f"{v:.6f}", "Decimal")
    tp = etree.SubElement(
        etree.SubElement(
            etree.SubElement(ext, _g(GMD, "temporalElement")), _g(GMD, "EX_TemporalExtent")
        ),
        _g(GMD, "extent"),
    )
    period = etree.SubElement(tp, _g(GML, "TimePeriod"))
    period.set(_g(GML, "id"), "acquisition")
    etree.SubElement(period, _g(GML, "beginPosition")).text = _day(dates["acquired_from"])
    etree.SubElement(period, _g(GML, "endPosition")).text = _day(dates["acquired_to"])

    dq = etree.SubElement(
        etree.SubElement(root, _g(GMD, "dataQualityInfo")), _g(GMD, "DQ_DataQuality")
    )
    scope = etree.SubElement(etree.SubElement(dq, _g(GMD, "scope")), _g(GMD, "DQ_Scope"))
    _codev(scope, "level", "MD_ScopeCode", "dataset")
    lin = etree.SubElement(etree.SubElement(dq, _g(GMD, "lineage")), _g(GMD, "LI_Lineage"))
    _cs(
        lin,
        "statement",
        f"{manifest['sensor']['platform']} Ortho Ready scenes orthorectified with the vendor "
        "RPC model refined on ground control points, on a 10 m DEM; cubic resampling. "
        "Accuracy per site as declared by the producer's internal QC.",
    )
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def write_metadata(root: Path, manifest: dict[str, Any]) -> Path:
    """Write the delivery's metadata file under ``root/metadata/`` (CSDGM for an aerial delivery,
    ISO 19139 for a satellite one) and return its path."""
    folder = root / "metadata"
    folder.mkdir(exist_ok=True)
    if manifest["sensor"]["type"] == "aerial":
        path, data = folder / f"{manifest['id']}_fgdc.xml", fgdc_csdgm(manifest)
    else:
        path, data = folder / f"{manifest['id']}_iso19139.xml", iso19139(manifest)
    path.write_bytes(data)
    return path
