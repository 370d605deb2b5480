"""init --from, metadata: ISO 19139 and FGDC CSDGM read with evidence, against what the files say.

Expected values come from the files' own text (the generator's constants) and, independently,
from OWSLib's parsers of the same files; hostile XML is refused without any entity expanded, any
DTD loaded or any file outside read.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest
from lxml import etree

from orthospec.ingest.metadata import read_metadata, sensor_of

ROOT = Path(__file__).resolve().parents[1]
META = ROOT / "examples" / "deliveries" / "tiles-real" / "metadata"
ISO = META / "LE07_L3_iso19139.xml"
FGDC = META / "LE07_L3_fgdc.xml"


def _stated(path: Path) -> dict[str, object]:
    m = read_metadata(path, path.name)
    assert m is not None and m.refused is None
    return {s.field: s.value for s in m.stated}


def test_iso_19139_values_as_owslib_reads_them() -> None:
    from owslib.iso import MD_Metadata

    got = _stated(ISO)
    ref = MD_Metadata(etree.parse(str(ISO)).getroot())
    ident = ref.identification[0]
    originator = next(c for c in ident.contact if c.role == "originator")
    assert got["id"] == ref.identifier == "DE-L3-ORTHO-LS7-2026-01"
    assert got["project.name"] == ident.title
    assert got["contractor.name"] == originator.organization
    assert got["contractor.contact"] == originator.email
    assert (
        got["product.gsd"]
        == {"value": float(ident.distance[0]), "unit": ident.uom[0]}
        == {"value": 300.0, "unit": "m"}
    )
    assert str(got["dates.acquired_from"]) == str(ident.temporalextent_start) == "2002-11-04"
    assert got["dates.acquired_to"] == dt.date(2002, 11, 4)
    assert (
        got["project.crs"] == "EPSG:" + ref.referencesystem.code.rsplit("/", 1)[-1] == "EPSG:32618"
    )
    assert got["lineage"] == ref.dataquality.lineage
    assert got["sensor.platform"] == "Landsat-7" and got["sensor.camera"] == "ETM+"
    assert got["sensor.type"] == "satellite" and got["sensor.digital"] is True
    assert got["product.accuracy_statement"] == "RMSE planimetric: 150 m"
    assert got["product.bit_depth"] == 8


def test_fgdc_values_as_owslib_reads_them() -> None:
    from owslib.fgdc import Metadata

    got = _stated(FGDC)
    ref = Metadata(etree.parse(str(FGDC)).getroot())
    cite = ref.idinfo.citation.citeinfo
    assert got["project.name"] == cite["title"]
    assert got["contractor.name"] == cite["origin"] == "Geodaten Nord GmbH (fictional)"
    assert got["contractor.contact"] == ref.idinfo.ptcontac.email
    rng = ref.idinfo.timeperd.timeinfo.rngdates
    assert got["dates.acquired_from"] == dt.datetime.strptime(rng.begdate, "%Y%m%d").date()
    assert got["dates.acquired_to"] == dt.datetime.strptime(rng.enddate, "%Y%m%d").date()
    # UTM zone 18 on WGS 84 is EPSG:32618 (EPSG registry: WGS 84 / UTM zone 18N)
    assert got["project.crs"] == "EPSG:32618"
    assert got["product.gsd"] == {"value": 300.0, "unit": "m"}
    assert got["sensor.type"] == "satellite" and got["sensor.camera"] == "ETM+"


def test_every_value_carries_its_file_line_and_xpath() -> None:
    """The XPath of each statement finds, in the file, the text the draft filled."""
    m = read_metadata(ISO, "metadata/iso.xml")
    assert m is not None
    from orthospec.ingest.metadata import NS

    tree = etree.parse(str(ISO))
    for s in m.stated:
        if " + " in s.xpath or s.field in (
            "product.gsd",
            "product.accuracy_statement",
            "project.crs",
        ):
            continue
        hits = tree.xpath(s.xpath, namespaces=NS)
        assert hits, s
        assert s.line == hits[0].sourceline
        text = " ".join("".join(hits[0].itertext()).split())
        assert (
            str(s.value) in text or s.field.startswith("dates.") or s.field == "product.bit_depth"
        )
        assert s.file == "metadata/iso.xml"


def test_an_inspire_md_metadata_without_gmi(tmp_path: Path) -> None:
    text = ISO.read_text(encoding="utf-8").replace("gmi:MI_Metadata", "gmd:MD_Metadata")
    p = tmp_path / "inspire.xml"
    p.write_text(text, encoding="utf-8")
    got = _stated(p)
    assert got["id"] == "DE-L3-ORTHO-LS7-2026-01" and got["product.gsd"] == {
        "value": 300.0,
        "unit": "m",
    }


@pytest.mark.parametrize(
    "names, expected",
    [
        (["Landsat-7", "ETM+"], ("satellite", True)),
        (["Vulcanair P68 aircraft", "UltraCam Eagle"], ("aerial", True)),
        (["Leica RC30"], ("aerial", False)),
        (["WorldView-3", "UltraCam Eagle"], (None, True)),  # the names disagree: no type
        (["Some platform"], (None, None)),
    ],
)
def test_sensor_type_only_from_names_that_say_it(
    names: list[str], expected: tuple[object, object]
) -> None:
    assert sensor_of(names) == expected


# --------------------------------------------------------------------------- hostile XML
SECRET = "TOP-SECRET-CONTENT-7f3a"


@pytest.mark.parametrize(
    "doc",
    [
        # billion laughs
        """<?xml version="1.0"?><!DOCTYPE metadata [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">
    <!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;"><!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;">]>
    <metadata><idinfo><citation><citeinfo><title>&d;</title></citeinfo></citation></idinfo></metadata>""",
        # external entity reading a file outside the source
        """<?xml version="1.0"?><!DOCTYPE metadata [<!ENTITY x SYSTEM "file://{secret}">]>
    <metadata><idinfo><citation><citeinfo><title>&x;</title></citeinfo></citation></idinfo></metadata>""",
        # parameter entity from the network
        """<?xml version="1.0"?><!DOCTYPE metadata [<!ENTITY % p SYSTEM "http://127.0.0.1:9/evil.dtd"> %p;]>
    <metadata><idinfo/></metadata>""",
    ],
)
def test_entities_are_refused_unread(tmp_path: Path, doc: str) -> None:
    secret = tmp_path / "outside.txt"
    secret.write_text(SECRET, encoding="utf-8")
    p = tmp_path / "src" / "m.xml"
    p.parent.mkdir()
    p.write_text(doc.replace("{secret}", str(secret)), encoding="utf-8")
    m = read_metadata(p, "m.xml")
    assert m is not None and m.refused is not None
    assert "entit" in m.refused or "DTD" in m.refused
    assert not m.stated and SECRET not in repr(m)


def test_an_external_dtd_reference_is_not_loaded_and_the_file_is_read(tmp_path: Path) -> None:
    """FGDC files often name their DTD (SYSTEM): never fetched, the document is still read."""
    got = _stated(FGDC)  # the example's FGDC file names http://www.fgdc.gov/...dtd
    assert "DOCTYPE metadata SYSTEM" in FGDC.read_text(encoding="utf-8")
    assert got["contractor.name"] == "Geodaten Nord GmbH (fictional)"


def test_size_limit_and_broken_xml(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    p = tmp_path / "big.xml"
    p.write_text("<metadata>" + "x" * 2000 + "</metadata>", encoding="utf-8")
    monkeypatch.setenv("ORTHOSPEC_MAX_XML_BYTES", "1000")
    m = read_metadata(p, "big.xml")
    assert m is not None and "ORTHOSPEC_MAX_XML_BYTES" in (m.refused or "")
    monkeypatch.delenv("ORTHOSPEC_MAX_XML_BYTES")
    p.write_text("<metadata><idinfo></metadata>", encoding="utf-8")
    m = read_metadata(p, "broken.xml")
    assert m is not None and "not well-formed" in (m.refused or "")


def test_other_xml_is_not_metadata(tmp_path: Path) -> None:
    p = tmp_path / "a.aux.xml"
    p.write_text("<PAMDataset/>", encoding="utf-8")
    assert read_metadata(p, "a.aux.xml") is None
