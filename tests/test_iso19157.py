"""ISO 19157 quality elements as ISO 19139 XML (issue 30 item 3): a structural test of every element
written and validation against the ISO/TS 19139:2007 schemas (tests/metadata_xsd.py), the figures equal
to the QCR's, hostile strings escaped, a copy of the delivery's MD_Metadata with orthospec's
dataQualityInfo."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
from lxml import etree
from tests import metadata_xsd

from orthospec import api
from orthospec.metadata.iso19157 import CODELISTS, GCO, GMD, MARK, iso19139_document
from orthospec.qcr import all_records

ROOT = Path(__file__).resolve().parents[1]
NS = {
    "gmd": GMD,
    "gco": GCO,
    "xlink": "http://www.w3.org/1999/xlink",
    "xsi": "http://www.w3.org/2001/XMLSchema-instance",
}


@pytest.fixture(scope="module")
def doc():
    return api.check(
        ROOT / "examples/deliveries/aerial-pass",
        ROOT / "specs/fgdc-nssda-1998.yaml",
        params=["accuracy_h95=1.0"],
        checker=ROOT / "examples/checker/aerial-pass",
        date="2026-01-01",
    ).document


def test_standalone_structure(doc):
    root = etree.fromstring(iso19139_document(doc))
    assert root.tag == f"{{{GMD}}}DQ_DataQuality"
    assert (
        root.find("gmd:scope/gmd:DQ_Scope/gmd:level/gmd:MD_ScopeCode", NS).get("codeListValue")
        == "dataset"
    )
    for code in root.iter(
        f"{{{GMD}}}MD_ScopeCode",
        f"{{{GMD}}}DQ_EvaluationMethodTypeCode",
        f"{{{GMD}}}CI_DateTypeCode",
    ):
        assert code.get("codeList") == f"{CODELISTS}#{etree.QName(code).localname}"
        assert code.get("codeListValue") in {"dataset", "directExternal", "publication"}
    pos = root.findall("gmd:report/gmd:DQ_AbsoluteExternalPositionalAccuracy", NS)
    expected = {
        (r["item"], r["measure"]): r["measured"]["value"]
        for r in all_records(doc)
        if r["measure"].startswith("checkpoints.")
        and r["measured"]["unit"] == "m"
        and isinstance(r["measured"]["value"], float)
    }
    assert len(pos) == len(expected) >= 3
    for el in pos:
        assert [etree.QName(c).localname for c in el] == [
            "nameOfMeasure",
            "measureIdentification",
            "measureDescription",
            "evaluationMethodType",
            "evaluationMethodDescription",
            "result",
        ]
        res = el.find("gmd:result/gmd:DQ_QuantitativeResult", NS)
        assert res.find("gmd:valueUnit", NS).get(f"{{{NS['xlink']}}}href").endswith("/9001")
        value = res.find("gmd:value/gco:Record", NS)
        assert value.get(f"{{{NS['xsi']}}}type") == "xs:double"
        code = el.findtext(
            "gmd:measureIdentification/gmd:MD_Identifier/gmd:code/gco:CharacterString",
            namespaces=NS,
        )
        item = (
            el.findtext("gmd:nameOfMeasure/gco:CharacterString", namespaces=NS)
            .rsplit("(", 1)[1]
            .rstrip(")")
        )
        assert float(value.text) == expected[(item, code)]
    conf = root.findall("gmd:report/gmd:DQ_DomainConsistency", NS)
    judged = {r["rule"]: r["verdict"] for r in doc["rules"] if r["verdict"] != "not_applicable"}
    assert len(conf) == len(judged)
    for el in conf:
        rule = el.findtext(
            "gmd:measureIdentification/gmd:MD_Identifier/gmd:code/gco:CharacterString",
            namespaces=NS,
        )
        cr = el.find("gmd:result/gmd:DQ_ConformanceResult", NS)
        assert [etree.QName(c).localname for c in cr] == ["specification", "explanation", "pass"]
        assert cr.find("gmd:specification/gmd:CI_Citation/gmd:title/gco:CharacterString", NS).text
        assert (
            cr.find(
                "gmd:specification/gmd:CI_Citation/gmd:date/gmd:CI_Date/gmd:date/gco:Date", NS
            ).text
            == "2026-01-01"
        )
        assert cr.findtext("gmd:pass/gco:Boolean", namespaces=NS) == (
            "true" if judged[rule] == "pass" else "false"
        )
    # the example is rejected under the NSSDA (no §3.2.3 statement): at least one false
    assert any(
        c.findtext("gmd:result/gmd:DQ_ConformanceResult/gmd:pass/gco:Boolean", namespaces=NS)
        == "false"
        for c in conf
    )


def test_hostile_strings_escaped(doc):
    d = copy.deepcopy(doc)
    evil = 'R<script>alert("x")</script>\u202e\'&'
    d["rules"][0]["title"] = evil
    d["rules"][0]["verdict"] = "fail"
    xml = iso19139_document(d)
    assert b"<script>" not in xml
    root = etree.fromstring(xml)
    texts = [t.text for t in root.iter(f"{{{GCO}}}CharacterString")]
    assert any(t and t.startswith(evil) for t in texts)


def test_standalone_validates_against_iso19139_schema(doc):
    # ISO/TS 19139:2007 schemas (gmd/gco/GML 3.2.1), read locally: tests/metadata_xsd.py
    assert metadata_xsd.errors(metadata_xsd.iso19139(), iso19139_document(doc)) == []
    # the validation is not vacuous: an element out of ISO 19139's sequence is refused
    root = etree.fromstring(iso19139_document(doc))
    root.append(root[0])  # scope moved after the reports
    assert metadata_xsd.errors(metadata_xsd.iso19139(), root)


def test_inserted_into_copy_of_md_metadata(doc):
    src = (
        f'<gmd:MD_Metadata xmlns:gmd="{GMD}" xmlns:gco="{GCO}"><gmd:fileIdentifier><gco:CharacterString>id-1'
        "</gco:CharacterString></gmd:fileIdentifier><gmd:dataQualityInfo><gmd:DQ_DataQuality><gmd:scope>"
        '<gmd:DQ_Scope><gmd:level><gmd:MD_ScopeCode codeList="x" codeListValue="dataset">dataset'
        "</gmd:MD_ScopeCode></gmd:level></gmd:DQ_Scope></gmd:scope><gmd:lineage><gmd:LI_Lineage>"
        "<gmd:statement><gco:CharacterString>producer lineage</gco:CharacterString></gmd:statement>"
        "</gmd:LI_Lineage></gmd:lineage></gmd:DQ_DataQuality></gmd:dataQualityInfo>"
        "<gmd:metadataMaintenance/></gmd:MD_Metadata>"
    ).encode()
    copy1 = iso19139_document(doc, src)
    root = etree.fromstring(copy1)
    names = [etree.QName(c).localname for c in root]
    # the producer's dataQualityInfo (their lineage) is kept; orthospec's follows it, before maintenance
    assert names == ["fileIdentifier", "dataQualityInfo", "dataQualityInfo", "metadataMaintenance"]
    dqs = root.findall("gmd:dataQualityInfo/gmd:DQ_DataQuality", NS)
    assert (
        dqs[0].findtext(
            "gmd:lineage/gmd:LI_Lineage/gmd:statement/gco:CharacterString", namespaces=NS
        )
        == "producer lineage"
    )
    assert dqs[1].find("gmd:report", NS) is not None
    assert (
        dqs[1]
        .findtext("gmd:lineage/gmd:LI_Lineage/gmd:statement/gco:CharacterString", namespaces=NS)
        .startswith(MARK)
    )
    # a copy of the copy replaces orthospec's element instead of adding a second one
    again = etree.fromstring(iso19139_document(doc, copy1))
    assert [etree.QName(c).localname for c in again] == names
    with pytest.raises(ValueError):
        iso19139_document(doc, b"<metadata/>")


def test_inserted_into_iso19115_2_mi_metadata(doc):
    # gmi:MI_Metadata extends MD_Metadata: dataQualityInfo goes before its acquisitionInformation
    gmi = "http://www.isotc211.org/2005/gmi"
    src = (
        f'<gmi:MI_Metadata xmlns:gmi="{gmi}" xmlns:gmd="{GMD}" xmlns:gco="{GCO}"><gmd:fileIdentifier>'
        "<gco:CharacterString>id-2</gco:CharacterString></gmd:fileIdentifier>"
        "<gmi:acquisitionInformation/></gmi:MI_Metadata>"
    ).encode()
    root = etree.fromstring(iso19139_document(doc, src))
    assert [etree.QName(c).localname for c in root] == [
        "fileIdentifier",
        "dataQualityInfo",
        "acquisitionInformation",
    ]


def test_cli_format_iso19157(tmp_path):
    from click.testing import CliRunner

    from orthospec.cli.groups import main

    out = tmp_path / "out"
    res = CliRunner().invoke(
        main,
        [
            "check",
            str(ROOT / "examples/deliveries/aerial-pass"),
            "--profile",
            str(ROOT / "specs/fgdc-nssda-1998.yaml"),
            "--param",
            "accuracy_h95=1.0",
            "--checker",
            str(ROOT / "examples/checker/aerial-pass"),
            "--out",
            str(out),
            "--format",
            "iso19157",
        ],
    )
    assert res.exit_code == 1, res.output  # rejected under the NSSDA: no §3.2.3 statement
    root = etree.parse(str(out / "iso19157.xml")).getroot()
    assert root.tag == f"{{{GMD}}}DQ_DataQuality"
    # with the updated copy of the delivery's CSDGM record (metadata/ folder of the delivery)
    assert sorted(p.name for p in out.iterdir()) == ["iso19157.xml", "metadata-D-2026-014_fgdc.xml"]
