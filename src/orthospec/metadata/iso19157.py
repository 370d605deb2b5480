"""ISO 19157 data-quality elements as ISO 19139 XML (issue 30 item 3).

From a QCR document's judged records and rule summaries (never recomputed):

* one ``gmd:DQ_AbsoluteExternalPositionalAccuracy`` per accuracy figure measured on check points
  (a record whose measure starts with ``checkpoints.`` and whose unit is metres: RMSE, CE90, CE95,
  LE, NSSDA Accuracy_r / Accuracy_z), with measure identification, evaluation method and a
  ``gmd:DQ_QuantitativeResult`` with its unit;
* one ``gmd:DQ_DomainConsistency`` per rule with a ``gmd:DQ_ConformanceResult``: the specification
  cited is the profile and the clause, the explanation the rule's title and verdict, ``gmd:pass``
  true only when the rule's worst verdict is pass (or waived); a rule that was not applicable to
  any item is left out (no conformance was tested).

Inserted as ``gmd:dataQualityInfo`` into a copy of the delivery's ``gmd:MD_Metadata`` when one is
given, else a standalone ``gmd:DQ_DataQuality`` document. lxml escapes every string.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from lxml import etree

from ..qcr import all_records

GMD = "http://www.isotc211.org/2005/gmd"
GCO = "http://www.isotc211.org/2005/gco"
XLINK = "http://www.w3.org/1999/xlink"
XSI = "http://www.w3.org/2001/XMLSchema-instance"
XS = "http://www.w3.org/2001/XMLSchema"
NSMAP = {"gmd": GMD, "gco": GCO, "xlink": XLINK, "xsi": XSI, "xs": XS}
CODELISTS = "http://standards.iso.org/iso/19139/resources/gmxCodelists.xml"
METRE = "http://www.opengis.net/def/uom/EPSG/0/9001"
PASSING = {"pass", "waived"}


def _q(ns: str, tag: str) -> str:
    return f"{{{ns}}}{tag}"


def _text(
    parent: etree._Element, tag: str, value: str, kind: str = "CharacterString"
) -> etree._Element:
    el = etree.SubElement(parent, _q(GMD, tag))
    etree.SubElement(el, _q(GCO, kind)).text = value
    return el


def _code(parent: etree._Element, tag: str, code: str, value: str) -> None:
    el = etree.SubElement(etree.SubElement(parent, _q(GMD, tag)), _q(GMD, code))
    el.set("codeList", f"{CODELISTS}#{code}")
    el.set("codeListValue", value)
    el.text = value


def _positional(parent: etree._Element, rec: Mapping[str, Any], value: float) -> None:
    el = etree.SubElement(
        etree.SubElement(parent, _q(GMD, "report")),
        _q(GMD, "DQ_AbsoluteExternalPositionalAccuracy"),
    )
    _text(el, "nameOfMeasure", f"{rec['measure']} ({rec['item']})")
    ident = etree.SubElement(
        etree.SubElement(el, _q(GMD, "measureIdentification")), _q(GMD, "MD_Identifier")
    )
    _text(ident, "code", str(rec["measure"]))
    _text(el, "measureDescription", f"{rec['title']} (rule {rec['rule']}, item {rec['item']})")
    _code(el, "evaluationMethodType", "DQ_EvaluationMethodTypeCode", "directExternal")
    _text(
        el,
        "evaluationMethodDescription",
        "Measured by orthospec on the check points of the checker's external quality control "
        "(independent reference coordinates)",
    )
    res = etree.SubElement(
        etree.SubElement(el, _q(GMD, "result")), _q(GMD, "DQ_QuantitativeResult")
    )
    etree.SubElement(res, _q(GMD, "valueUnit")).set(_q(XLINK, "href"), METRE)
    rec_el = etree.SubElement(etree.SubElement(res, _q(GMD, "value")), _q(GCO, "Record"))
    rec_el.set(_q(XSI, "type"), "xs:double")
    rec_el.text = repr(float(value))


def _conformance(
    parent: etree._Element, rule: Mapping[str, Any], profile: Mapping[str, Any], date: str
) -> None:
    el = etree.SubElement(
        etree.SubElement(parent, _q(GMD, "report")), _q(GMD, "DQ_DomainConsistency")
    )
    ident = etree.SubElement(
        etree.SubElement(el, _q(GMD, "measureIdentification")), _q(GMD, "MD_Identifier")
    )
    _text(ident, "code", str(rule["rule"]))
    res = etree.SubElement(etree.SubElement(el, _q(GMD, "result")), _q(GMD, "DQ_ConformanceResult"))
    cit = etree.SubElement(etree.SubElement(res, _q(GMD, "specification")), _q(GMD, "CI_Citation"))
    _text(
        cit, "title", f"{profile.get('title') or profile.get('id', '')}: {rule.get('clause', '')}"
    )
    cd = etree.SubElement(etree.SubElement(cit, _q(GMD, "date")), _q(GMD, "CI_Date"))
    _text(cd, "date", date, "Date")
    _code(cd, "dateType", "CI_DateTypeCode", "publication")
    counts = ", ".join(f"{k} {v}" for k, v in sorted((rule.get("counts") or {}).items()) if v)
    _text(res, "explanation", f"{rule['title']}: {rule['verdict']} ({counts})")
    _text(res, "pass", "true" if rule["verdict"] in PASSING else "false", "Boolean")


def data_quality(doc: Mapping[str, Any]) -> etree._Element:
    """The ``gmd:DQ_DataQuality`` element of a QCR document."""
    dq = etree.Element(_q(GMD, "DQ_DataQuality"), nsmap=NSMAP)
    scope = etree.SubElement(etree.SubElement(dq, _q(GMD, "scope")), _q(GMD, "DQ_Scope"))
    _code(scope, "level", "MD_ScopeCode", "dataset")
    for rec in all_records(doc):
        measured = rec["measured"]
        value = measured.get("value") if isinstance(measured, Mapping) else measured
        unit = measured.get("unit") if isinstance(measured, Mapping) else rec.get("unit")
        if (
            str(rec.get("measure", "")).startswith("checkpoints.")
            and unit == "m"
            and isinstance(value, (int, float))
            and not isinstance(value, bool)
            and value == value
        ):
            _positional(dq, rec, float(value))
    profile = doc.get("profile") or {}
    date = str(doc.get("date", ""))
    for rule in doc.get("rules", []):
        if rule["verdict"] != "not_applicable":
            _conformance(dq, rule, profile, date)
    lineage = etree.SubElement(etree.SubElement(dq, _q(GMD, "lineage")), _q(GMD, "LI_Lineage"))
    who = f"{profile.get('title') or profile.get('id', '')}".strip()
    _text(
        lineage,
        "statement",
        f"{MARK} of delivery {(doc.get('delivery') or {}).get('id', '')} against "
        f"{who} on {date}: verdict {doc.get('verdict', '')}",
    )
    return dq


#: ISO 19115-2 (gmi): MI_Metadata extends MD_Metadata; its own elements follow MD_Metadata's
GMI = "http://www.isotc211.org/2005/gmi"
ROOTS = (_q(GMD, "MD_Metadata"), _q(GMI, "MI_Metadata"))
#: MD_Metadata's elements after dataQualityInfo (ISO 19139 sequence), then MI_Metadata's own
_AFTER = tuple(
    _q(GMD, t)
    for t in (
        "portrayalCatalogueInfo",
        "metadataConstraints",
        "applicationSchemaInfo",
        "metadataMaintenance",
        "series",
        "describes",
        "propertyType",
        "featureType",
        "featureAttribute",
    )
) + tuple(_q(GMI, t) for t in ("acquisitionInformation",))
#: the title of orthospec's DQ_DataQuality (its lineage statement), so a copy of a copy replaces
#: it rather than adding a second one
MARK = "orthospec external quality control"


def _ours(holder: etree._Element) -> bool:
    return any(
        MARK in (t.text or "")
        for t in holder.iter(_q(GCO, "CharacterString"))
        if t.getparent() is not None and t.getparent().tag == _q(GMD, "statement")
    )


def iso19139_document(doc: Mapping[str, Any], source: bytes | None = None) -> bytes:
    """A standalone DQ_DataQuality document, or the delivery's metadata (``source``: a
    ``gmd:MD_Metadata`` or ISO 19115-2 ``gmi:MI_Metadata`` document) with orthospec's
    ``gmd:dataQualityInfo`` added after the producer's own (kept: their lineage and declared
    figures are the producer's record; a catalogue shows both, orthospec's marked by its lineage
    statement), in ISO 19139's sequence (before portrayal/application-schema/maintenance elements,
    else at the end). An earlier orthospec dataQualityInfo (a copy of a copy) is replaced. The
    parser resolves no entities, loads no DTD and reads nothing from the network."""
    dq = data_quality(doc)
    if source is None:
        return etree.tostring(dq, xml_declaration=True, encoding="UTF-8", pretty_print=True)
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, remove_blank_text=True
    )
    root = etree.fromstring(source, parser)
    if root.tag not in ROOTS:
        raise ValueError(f"not an ISO 19139 gmd:MD_Metadata document (root {root.tag!r})")
    for old in root.findall(_q(GMD, "dataQualityInfo")):
        if _ours(old):
            root.remove(old)
    holder = etree.Element(_q(GMD, "dataQualityInfo"))
    holder.append(dq)
    nxt = next((c for c in root if c.tag in _AFTER), None)
    if nxt is not None:
        nxt.addprevious(holder)
    else:
        root.append(holder)
    return etree.tostring(
        root.getroottree(), xml_declaration=True, encoding="UTF-8", pretty_print=True
    )
