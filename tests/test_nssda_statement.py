"""The NSSDA §3.2.3 statement (issue 30 item 3): worded from the QCR's judged figures, equal to the
value computed by hand from the checker's check points, written into a copy of a CSDGM XML."""

from __future__ import annotations

from pathlib import Path

import pytest
from lxml import etree
from tests.checking import nssda_accuracy_r

from orthospec import api
from orthospec.metadata import nssda_statements, write_fgdc_copy
from orthospec.metadata.nssda import fgdc_with_statements

ROOT = Path(__file__).resolve().parents[1]
DELIVERY = ROOT / "examples" / "deliveries" / "aerial-pass"
CHECKER = ROOT / "examples" / "checker" / "aerial-pass"


@pytest.fixture(scope="module")
def doc():
    return api.check(DELIVERY, ROOT / "specs" / "fgdc-nssda-1998.yaml", params=["accuracy_h95=1.0"],
                     checker=CHECKER, date="2026-01-01").document


def _by_hand() -> dict[str, float]:
    return nssda_accuracy_r(CHECKER / "tables" / "checkpoints.csv")


def test_statement_equals_hand_computation(doc):
    hand = _by_hand()
    stmts = [s for s in nssda_statements(doc) if s.axis == "horizontal"]
    assert {s.item for s in stmts} == set(hand) and len(stmts) == len(hand) == 3
    for s in stmts:
        assert s.value_m == pytest.approx(hand[s.item], abs=5e-4)
        # independence is not signed in the example: §3.2.3 words it "Compiled to meet"
        assert (
            s.text
            == f"Compiled to meet {hand[s.item]:.3f} meters horizontal accuracy at 95% confidence level"
        )
    assert not [
        s for s in nssda_statements(doc) if s.axis == "vertical"
    ]  # no heights: no Accuracy_z


def test_statement_in_qcr_json_and_on_the_terminal(tmp_path):
    """The statements are a field of qcr.json (the document the CLI writes) and a terminal line, with
    the hand-computed values; a profile without NSSDA figures (jrc-v3) gets no field."""
    import json

    from click.testing import CliRunner

    from orthospec.cli.main import cli

    hand = _by_hand()
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(DELIVERY),
            "--profile",
            str(ROOT / "specs" / "fgdc-nssda-1998.yaml"),
            "--param",
            "accuracy_h95=1.0",
            "--checker",
            str(CHECKER),
            "--out",
            str(tmp_path),
            "--format",
            "json,terminal",
            "--date",
            "2026-01-01",
        ],
    )
    assert res.exit_code in (0, 1, 3), res.output
    field = json.loads((tmp_path / "qcr.json").read_text(encoding="utf-8"))["nssda"]
    assert {f["item"]: f["value"] for f in field} == pytest.approx(hand, abs=5e-4)
    assert all(f["axis"] == "horizontal" and f["unit"] == "m" and not f["tested"] for f in field)
    for block, v in hand.items():
        line = (f"NSSDA §3.2.3, block {block}: Compiled to meet {v:.3f} meters horizontal accuracy at 95% "
                "confidence level")
        assert line in " ".join(res.output.split()), res.output
    jrc = api.check(DELIVERY, "jrc-v3", checker=CHECKER, date="2026-01-01").document
    assert "nssda" not in jrc


def test_tested_only_when_independence_passed(doc):
    import copy

    d = copy.deepcopy(doc)
    from orthospec.qcr import all_records

    recs = list(all_records(d))
    assert any(
        r["rule"] == "NSSDA-3.2.1-INDEPENDENT-SOURCE" and r["verdict"] != "pass" for r in recs
    )
    assert all(not s.tested for s in nssda_statements(d))


def test_fgdc_copy(doc, tmp_path):
    # CSDGM as its XML schema and the tools write it: short element names, FGDC-STD-001-1998 order
    src = tmp_path / "in.xml"
    src.write_bytes(
        b"<?xml version='1.0'?><metadata><idinfo><citation>x &amp; y</citation></idinfo>"
        b"<dataqual><logic>l</logic><complete>c</complete><posacc><horizpa><horizpar>declared"
        b"</horizpar><qhorizpa><horizpav>0.1</horizpav><horizpae>old</horizpae></qhorizpa></horizpa>"
        b"</posacc><lineage><procstep><procdesc>p</procdesc></procstep></lineage></dataqual>"
        b"<metainfo/></metadata>"
    )
    before = src.read_bytes()
    out = write_fgdc_copy(doc, tmp_path / "out", src)
    assert src.read_bytes() == before  # the delivery's file is only read
    root = etree.parse(str(out)).getroot()
    assert root.findtext("idinfo/citation") == "x & y"
    assert [c.tag for c in root.find("dataqual")] == ["logic", "complete", "posacc", "lineage"]
    hpa = root.find("dataqual/posacc/horizpa")
    assert [c.tag for c in hpa] == [
        "horizpar",
        "qhorizpa",
        "qhorizpa",
        "qhorizpa",
    ]  # the declared one replaced
    hand = _by_hand()
    qs = hpa.findall("qhorizpa")
    assert sorted(q.findtext("horizpav") for q in qs) == sorted(f"{v:.3f}" for v in hand.values())
    for q in qs:
        assert [c.tag for c in q] == ["horizpav", "horizpae"]
        # FGDC-STD-007.3-1998 §3.2.3: the explanation names the NSSDA; the statement follows
        assert q.findtext("horizpae").startswith(
            "National Standard for Spatial Data Accuracy. Compiled to meet "
        )
    for v in hand.values():
        assert (
            f"Compiled to meet {v:.3f} meters horizontal accuracy at 95% confidence level"
            in hpa.findtext("horizpar")
        )
    assert not list((tmp_path / "out").glob(".tmp-*"))


def test_fgdc_copy_long_names_and_order(doc):
    # a document written with the standard's long names gets long names; a missing posacc goes
    # between Completeness_Report and Lineage (FGDC-STD-001-1998 section 2 order)
    src = (
        b"<metadata><Identification_Information/><Data_Quality_Information><Logical_Consistency_Report>l"
        b"</Logical_Consistency_Report><Completeness_Report>c</Completeness_Report><Lineage/>"
        b"</Data_Quality_Information><Metadata_Reference_Information/></metadata>"
    )
    root = etree.fromstring(fgdc_with_statements(src, nssda_statements(doc)))
    dq = root.find("Data_Quality_Information")
    assert [c.tag for c in dq] == [
        "Logical_Consistency_Report",
        "Completeness_Report",
        "Positional_Accuracy",
        "Lineage",
    ]
    vals = dq.findall(
        "Positional_Accuracy/Horizontal_Positional_Accuracy/"
        "Quantitative_Horizontal_Positional_Accuracy_Assessment/Horizontal_Positional_Accuracy_Value"
    )
    assert sorted(v.text for v in vals) == sorted(f"{v:.3f}" for v in _by_hand().values())
    root = etree.fromstring(
        fgdc_with_statements(
            b"<metadata><Identification_Information/><Spatial_Reference_Information/>"
            b"<Metadata_Reference_Information/></metadata>",
            nssda_statements(doc),
        )
    )
    assert [c.tag for c in root] == [
        "Identification_Information",
        "Data_Quality_Information",
        "Spatial_Reference_Information",
        "Metadata_Reference_Information",
    ]
    # no dataqual at all: it goes right after idinfo, before spdoinfo/metainfo
    root = etree.fromstring(
        fgdc_with_statements(
            b"<metadata><idinfo/><spdoinfo/><metainfo/></metadata>", nssda_statements(doc)
        )
    )
    assert [c.tag for c in root] == ["idinfo", "dataqual", "spdoinfo", "metainfo"]


def test_fgdc_hostile_and_entities():
    from orthospec.metadata import NssdaStatement

    s = NssdaStatement(
        item='B<script>"\u202e',
        axis="horizontal",
        value_m=0.5,
        tested=True,
        valid=True,
        rule="NSSDA-H95",
    )
    xml = fgdc_with_statements(None, [s])
    assert b"<script>" not in xml
    root = etree.fromstring(xml)
    assert 'B<script>"\u202e' in root.findtext(".//horizpae")
    assert 'B<script>"\u202e' in root.findtext(".//horizpar")
    evil = (
        b'<?xml version="1.0"?><!DOCTYPE m [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
        b"<metadata><t>&e;</t></metadata>"
    )
    assert b"root:" not in fgdc_with_statements(evil, [s])
