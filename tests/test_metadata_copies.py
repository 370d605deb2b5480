"""The delivery's own metadata XML, updated, written to --out (issue 30 item 3).

The example deliveries carry the producer's metadata in the convention's ``metadata/`` folder (a
CSDGM record for the aerial ones, an ISO 19139 ``gmd:MD_Metadata`` for the satellite ones);
``check --format iso19157`` writes updated copies beside iso19157.xml and never touches the
delivery. Expected figures come from the checker's check points computed here by hand
(FGDC-STD-007.3-1998 Appendix 3-A), structure from the ISO/TS 19139:2007 schemas and the CSDGM
production rules (tests/metadata_xsd.py), the producer's content from the source files.
"""

from __future__ import annotations

import copy
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from lxml import etree
from tests import metadata_xsd
from tests.checking import CHECKERS, DATE, EXAMPLES, copy_example, nssda_accuracy_r

from orthospec.metadata.copies import FGDC, ISO, MetadataFile, copy_name, metadata_copies
from orthospec.metadata.iso19157 import GCO, GMD, MARK
from orthospec.qcr import all_records

NS = {"gmd": GMD, "gco": GCO}
NSSDA = str(Path(__file__).resolve().parents[1] / "specs" / "fgdc-nssda-1998.yaml")
EVIL = 'B<script>alert("x")</script>\u202e\'&"'


def _sums(root: Path) -> dict[str, str]:
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _check(delivery: Path, out: Path, *args: str, example: str = "aerial-pass") -> tuple[int, str]:
    """The installed command, as a user runs it (exit codes and messages of cli/main.py)."""
    exe = Path(sys.executable).with_name("orthospec")
    r = subprocess.run(
        [
            str(exe),
            "check",
            str(delivery),
            "--checker",
            str(CHECKERS / example),
            "--out",
            str(out),
            "--date",
            DATE,
            *args,
        ],
        capture_output=True,
        text=True,
    )
    return r.returncode, r.stdout + r.stderr


def _by_hand(example: str = "aerial-pass") -> dict[str, float]:
    return nssda_accuracy_r(CHECKERS / example / "tables" / "checkpoints.csv")


@pytest.mark.parametrize(
    "example", ["aerial-pass", "aerial-fail", "satellite-pass", "satellite-fail"]
)
def test_examples_carry_the_producers_metadata(example):
    manifest = yaml.safe_load((EXAMPLES / example / "delivery.yaml").read_text(encoding="utf-8"))
    files = sorted((EXAMPLES / example / "metadata").iterdir())
    assert len(files) == 1
    root = etree.parse(str(files[0])).getroot()
    if manifest["sensor"]["type"] == "aerial":
        assert files[0].name == f"{manifest['id']}_fgdc.xml"
        assert metadata_xsd.errors(metadata_xsd.csdgm(), root) == []
        assert manifest["id"] in root.findtext("idinfo/citation/citeinfo/title")
        assert root.findtext("idinfo/timeperd/timeinfo/rngdates/begdate") == str(
            manifest["dates"]["acquired_from"]
        ).replace("-", "")
        assert root.findtext(
            "dataqual/posacc/horizpa/qhorizpa/horizpav"
        )  # the producer's declared figure
    else:
        assert files[0].name == f"{manifest['id']}_iso19139.xml"
        assert metadata_xsd.errors(metadata_xsd.iso19139(), root) == []
        assert (
            root.findtext("gmd:fileIdentifier/gco:CharacterString", namespaces=NS) == manifest["id"]
        )
        assert root.findtext("gmd:dateStamp/gco:Date", namespaces=NS) == str(
            manifest["dates"]["delivered"]
        )


def test_aerial_csdgm_copy_has_the_statement_and_the_delivery_is_unchanged(tmp_path):
    delivery = EXAMPLES / "aerial-pass"
    before = _sums(delivery)
    out = tmp_path / "out"
    code, output = _check(
        delivery,
        out,
        "--profile",
        NSSDA,
        "--param",
        "accuracy_h95=1.0",
        "--format",
        "json,iso19157",
    )
    assert code == 1, (
        output
    )  # rejected under the NSSDA (no signed independence of the check points)
    assert _sums(delivery) == before  # nothing in the delivery was written
    assert sorted(p.name for p in out.iterdir()) == [
        "iso19157.xml",
        "metadata-D-2026-014_fgdc.xml",
        "qcr.json",
    ]
    src = etree.parse(str(delivery / "metadata" / "D-2026-014_fgdc.xml")).getroot()
    cp = etree.parse(str(out / "metadata-D-2026-014_fgdc.xml")).getroot()
    assert metadata_xsd.errors(metadata_xsd.csdgm(), cp) == []
    # the producer's record is kept, element for element, outside posacc
    for path in ("idinfo", "spref", "metainfo", "dataqual/lineage", "dataqual/logic"):
        assert etree.tostring(cp.find(path)) == etree.tostring(src.find(path))
    hand = _by_hand()
    qs = cp.findall("dataqual/posacc/horizpa/qhorizpa")
    assert sorted(float(q.findtext("horizpav")) for q in qs) == pytest.approx(
        sorted(round(v, 3) for v in hand.values()), abs=1e-9
    )
    declared = src.findtext("dataqual/posacc/horizpa/qhorizpa/horizpav")
    assert declared not in {q.findtext("horizpav") for q in qs}  # the declaration is replaced
    report = cp.findtext("dataqual/posacc/horizpa/horizpar")
    for block, v in hand.items():
        assert (
            f"Compiled to meet {v:.3f} meters horizontal accuracy at 95% confidence level (block {block})"
            in report
        )
    assert cp.find("dataqual/posacc/vertpa") is None  # no heights measured: no vertical statement
    assert metadata_xsd.errors(metadata_xsd.iso19139(), (out / "iso19157.xml").read_bytes()) == []


def test_satellite_iso_copy_is_valid_and_keeps_the_producers_quality(tmp_path):
    delivery = EXAMPLES / "satellite-pass"
    before = _sums(delivery)
    expected = yaml.safe_load((delivery / "expected.yaml").read_text(encoding="utf-8"))
    out = tmp_path / "out"
    code, output = _check(
        delivery, out, "--profile", "jrc-v3", "--format", "json,iso19157", example="satellite-pass"
    )
    assert (code == 0) == (expected["verdict"] == "accepted"), output
    assert _sums(delivery) == before
    # jrc-v3 gives no NSSDA figure: no statement, so no CSDGM copy; the ISO record is updated
    assert sorted(p.name for p in out.iterdir()) == [
        "iso19157.xml",
        "metadata-D-2026-031_iso19139.xml",
        "qcr.json",
    ]
    data = (out / "metadata-D-2026-031_iso19139.xml").read_bytes()
    assert metadata_xsd.errors(metadata_xsd.iso19139(), data) == []
    root = etree.fromstring(data)
    src = etree.parse(str(delivery / "metadata" / "D-2026-031_iso19139.xml")).getroot()
    assert etree.tostring(root.find("gmd:identificationInfo", NS)) == etree.tostring(
        src.find("gmd:identificationInfo", NS)
    )
    dqs = root.findall("gmd:dataQualityInfo/gmd:DQ_DataQuality", NS)
    assert len(dqs) == 2
    assert etree.tostring(dqs[0]) == etree.tostring(
        src.find("gmd:dataQualityInfo/gmd:DQ_DataQuality", NS)
    )
    ours = dqs[1]
    assert ours.findtext(
        "gmd:lineage/gmd:LI_Lineage/gmd:statement/gco:CharacterString", namespaces=NS
    ).startswith(f"{MARK} of delivery D-2026-031")
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    judged = {r["rule"]: r["verdict"] for r in doc["rules"] if r["verdict"] != "not_applicable"}
    conf = ours.findall("gmd:report/gmd:DQ_DomainConsistency", NS)
    got = {
        c.findtext(
            "gmd:measureIdentification/gmd:MD_Identifier/gmd:code/gco:CharacterString",
            namespaces=NS,
        ): c.findtext("gmd:result/gmd:DQ_ConformanceResult/gmd:pass/gco:Boolean", namespaces=NS)
        for c in conf
    }
    assert got == {r: ("true" if v in ("pass", "waived") else "false") for r, v in judged.items()}


HOSTILE_CSDGM = (
    "<?xml version='1.0' encoding='UTF-8'?><metadata><idinfo><citation><citeinfo><title>"
    "&lt;script&gt;alert(\"t\")&lt;/script&gt;\u202e'quoted'</title></citeinfo></citation></idinfo>"
    "<dataqual><logic>l</logic><complete>c</complete><lineage/></dataqual><metainfo/></metadata>"
)
HOSTILE_ISO = (
    f"<gmd:MD_Metadata xmlns:gmd='{GMD}' xmlns:gco='{GCO}'><gmd:fileIdentifier><gco:CharacterString>"
    "&lt;script&gt;x&lt;/script&gt;\u202e\"'</gco:CharacterString></gmd:fileIdentifier></gmd:MD_Metadata>"
)


def test_hostile_names_and_strings_are_escaped_in_the_copies(tmp_path):
    delivery = copy_example("aerial-pass", tmp_path)
    (delivery / "metadata" / "D-2026-014_fgdc.xml").unlink()
    meta = delivery / "metadata"
    (meta / "x<script>\"\u202e'.xml").write_text(HOSTILE_CSDGM, encoding="utf-8")
    (meta / "iso.xml").write_text(HOSTILE_ISO, encoding="utf-8")
    (meta / "notes.xml").write_text("<notes>not metadata</notes>", encoding="utf-8")  # left alone
    before = _sums(delivery)
    out = tmp_path / "out"
    code, output = _check(
        delivery, out, "--profile", NSSDA, "--param", "accuracy_h95=1.0", "--format", "iso19157"
    )
    assert code == 1, output
    assert _sums(delivery) == before
    names = sorted(p.name for p in out.iterdir())
    assert names == ["iso19157.xml", "metadata-iso.xml", "metadata-x_script____.xml"]
    fgdc = (out / "metadata-x_script____.xml").read_bytes()
    assert b"<script>" not in fgdc and b"&lt;script&gt;" in fgdc
    assert (
        etree.fromstring(fgdc).findtext("idinfo/citation/citeinfo/title")
        == "<script>alert(\"t\")</script>\u202e'quoted'"
    )
    iso = (out / "metadata-iso.xml").read_bytes()
    assert b"<script>" not in iso
    assert (
        etree.fromstring(iso).findtext("gmd:fileIdentifier/gco:CharacterString", namespaces=NS)
        == "<script>x</script>\u202e\"'"
    )


def test_hostile_ids_from_the_qcr_are_escaped(tmp_path):
    # block ids, rule titles reach the copies from the QCR: a hostile one stays text
    from orthospec import api

    doc = api.check(
        EXAMPLES / "aerial-pass",
        NSSDA,
        params=["accuracy_h95=1.0"],
        checker=CHECKERS / "aerial-pass",
        date=DATE,
    ).document
    recs = [dict(r) for r in all_records(doc)]  # as a version 1 document: every record in full
    for r in recs:
        if str(r.get("measure", "")).startswith("checkpoints."):
            r["item"] = EVIL
    d = {k: copy.deepcopy(v) for k, v in doc.items() if k != "compact"}
    d["records"] = recs
    for r in d["rules"]:
        r["title"] = EVIL
    fgdc_src = tmp_path / "m.xml"
    fgdc_src.write_bytes(
        b"<metadata><idinfo/><dataqual><logic>l</logic><complete>c</complete><lineage/>"
        b"</dataqual><metainfo/></metadata>"
    )
    iso_src = tmp_path / "i.xml"
    iso_src.write_text(HOSTILE_ISO, encoding="utf-8")
    out = metadata_copies(
        d,
        [
            MetadataFile("metadata/m.xml", fgdc_src, "metadata/", FGDC),
            MetadataFile("metadata/i.xml", iso_src, "metadata/", ISO),
        ],
    )
    assert sorted(out) == ["metadata-i.xml", "metadata-m.xml"]
    for data in out.values():
        assert b"<script>" not in data
    texts = [t for el in etree.fromstring(out["metadata-m.xml"]).iter() for t in [el.text] if t]
    assert any(EVIL in t for t in texts), "the hostile block id reaches the CSDGM copy as text"
    iso = etree.fromstring(out["metadata-i.xml"])
    strings = [t.text or "" for t in iso.iter(f"{{{GCO}}}CharacterString")]
    assert any(
        t.startswith(EVIL) for t in strings
    )  # a rule's title (DQ_ConformanceResult explanation)
    assert any(f"({EVIL})" in t for t in strings)  # a block id (nameOfMeasure)


def test_metadata_declaring_entities_is_refused(tmp_path):
    delivery = copy_example("aerial-pass", tmp_path)
    (delivery / "metadata" / "evil.xml").write_text(
        '<?xml version="1.0"?><!DOCTYPE metadata [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
        "<metadata><idinfo>&e;</idinfo></metadata>",
        encoding="utf-8",
    )
    out = tmp_path / "out"
    code, output = _check(
        delivery, out, "--profile", NSSDA, "--param", "accuracy_h95=1.0", "--format", "iso19157"
    )
    assert code == 2, output
    assert "metadata/evil.xml" in output and "Traceback" not in output
    assert not out.exists() or not [p for p in out.iterdir() if not p.name.startswith(".")]


def test_copy_names():
    assert copy_name("metadata/D-1_fgdc.xml") == "metadata-D-1_fgdc.xml"
    assert copy_name('metadata/a<b>"\u202e.xml') == "metadata-a_b___.xml"
    assert copy_name("documents/../.hidden.xml") == "metadata-hidden.xml"
    assert copy_name("metadata/x.xml", {"metadata-x.xml"}) == "metadata-x-2.xml"
    assert (
        copy_name("metadata/iso19157.xml") == "metadata-iso19157.xml"
    )  # never the standalone output


def test_a_documents_entry_naming_xml_metadata_is_found(tmp_path):
    # a delivery that lists its record under documents: (not in metadata/) gets its copy too, and the
    # extra entry changes no verdict (the metadata is read for the copy only)
    delivery = copy_example("satellite-pass", tmp_path)
    (delivery / "docs").mkdir()
    (delivery / "metadata" / "D-2026-031_iso19139.xml").rename(delivery / "docs" / "record.xml")
    (delivery / "metadata").rmdir()
    text = (delivery / "delivery.yaml").read_text(encoding="utf-8")
    assert "\ndocuments: {" in text
    (delivery / "delivery.yaml").write_text(
        text.replace("\ndocuments: {", "\ndocuments: {metadata_iso19139: docs/record.xml, "),
        encoding="utf-8",
    )
    out = tmp_path / "out"
    code, output = _check(
        delivery, out, "--profile", "jrc-v3", "--format", "iso19157", example="satellite-pass"
    )
    assert code == 0, output  # accepted, as expected.yaml says of the unchanged delivery
    assert sorted(p.name for p in out.iterdir()) == ["iso19157.xml", "metadata-record.xml"]
    assert (
        metadata_xsd.errors(metadata_xsd.iso19139(), (out / "metadata-record.xml").read_bytes())
        == []
    )


def test_vertical_statement_goes_after_the_horizontal_one():
    from orthospec.metadata import NssdaStatement
    from orthospec.metadata.nssda import fgdc_with_statements

    v = NssdaStatement(
        item="B1", axis="vertical", value_m=0.392, tested=True, valid=True, rule="NSSDA-V95"
    )
    h = NssdaStatement(
        item="B1", axis="horizontal", value_m=0.5, tested=True, valid=True, rule="NSSDA-H95"
    )
    src = (b"<metadata><idinfo/><dataqual><logic>l</logic><complete>c</complete><lineage/></dataqual>"
           b"<metainfo/></metadata>")
    root = etree.fromstring(fgdc_with_statements(src, [v, h]))
    assert metadata_xsd.errors(metadata_xsd.csdgm(), root) == []
    assert [c.tag for c in root.find("dataqual/posacc")] == ["horizpa", "vertpa"]
    assert root.findtext("dataqual/posacc/vertpa/qvertpa/vertaccv") == "0.392"
    assert root.findtext("dataqual/posacc/vertpa/vertaccr").endswith(
        "Tested 0.392 meters vertical accuracy at 95% confidence level (block B1)."
    )
    # a producer's vertical report is kept when only a horizontal figure was measured; the
    # horizontal one goes before it (FGDC-STD-001-1998 2.4: horizpa, then vertpa)
    src = (
        b"<metadata><idinfo/><dataqual><logic>l</logic><complete>c</complete><posacc><vertpa><vertaccr>"
        b"declared</vertaccr></vertpa></posacc><lineage/></dataqual><metainfo/></metadata>"
    )
    root = etree.fromstring(fgdc_with_statements(src, [h]))
    assert metadata_xsd.errors(metadata_xsd.csdgm(), root) == []
    assert [c.tag for c in root.find("dataqual/posacc")] == ["horizpa", "vertpa"]
    assert root.findtext("dataqual/posacc/vertpa/vertaccr") == "declared"
