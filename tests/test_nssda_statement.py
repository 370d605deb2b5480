"""The NSSDA §3.2.3 statement (issue 30 item 3): worded from the QCR's judged figures, equal to the
value computed by hand from the checker's check points, written into a copy of a CSDGM XML."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from lxml import etree

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
    t = pd.read_csv(CHECKER / "tables" / "checkpoints.csv")
    t = t[~t["excluded"].astype(str).str.lower().eq("true")]
    out = {}
    for block, g in t.groupby("block"):
        rx = float(np.sqrt(np.mean((g["x"] - g["x_ref"]) ** 2)))
        ry = float(np.sqrt(np.mean((g["y"] - g["y_ref"]) ** 2)))
        # FGDC-STD-007.3-1998 Appendix 3-A: 1.7308·RMSE_r when RMSE_x = RMSE_y, else 2.4477·0.5·(RMSE_x+RMSE_y)
        out[str(block)] = 1.7308 * float(np.hypot(rx, ry)) if rx == ry else 2.4477 * 0.5 * (rx + ry)
    return out


def test_statement_equals_hand_computation(doc):
    hand = _by_hand()
    stmts = [s for s in nssda_statements(doc) if s.axis == "horizontal"]
    assert {s.item for s in stmts} == set(hand) and len(stmts) == len(hand) == 3
    for s in stmts:
        assert s.value_m == pytest.approx(hand[s.item], abs=5e-4)
        # independence is not signed in the example: §3.2.3 words it "Compiled to meet"
        assert s.text == f"Compiled to meet {hand[s.item]:.3f} meters horizontal accuracy at 95% confidence level"
    assert not [s for s in nssda_statements(doc) if s.axis == "vertical"]  # no heights: no Accuracy_z


def test_tested_only_when_independence_passed(doc):
    import copy

    d = copy.deepcopy(doc)
    from orthospec.qcr import all_records

    recs = list(all_records(d))
    assert any(r["rule"] == "NSSDA-3.2.1-INDEPENDENT-SOURCE" and r["verdict"] != "pass" for r in recs)
    assert all(not s.tested for s in nssda_statements(d))


def test_fgdc_copy(doc, tmp_path):
    src = tmp_path / "in.xml"
    src.write_bytes(b"<?xml version='1.0'?><metadata><idinfo><citation>x &amp; y</citation></idinfo>"
                    b"<Data_Quality_Information><Positional_Accuracy><Horizontal_Positional_Accuracy>"
                    b"<Horizontal_Positional_Accuracy_Report><Horizontal_Positional_Accuracy_Value>old"
                    b"</Horizontal_Positional_Accuracy_Value></Horizontal_Positional_Accuracy_Report>"
                    b"</Horizontal_Positional_Accuracy></Positional_Accuracy></Data_Quality_Information></metadata>")
    before = src.read_bytes()
    out = write_fgdc_copy(doc, tmp_path / "out", src)
    assert src.read_bytes() == before  # the delivery's file is only read
    root = etree.parse(str(out)).getroot()
    assert root.findtext("idinfo/citation") == "x & y"
    reps = root.findall("Data_Quality_Information/Positional_Accuracy/Horizontal_Positional_Accuracy/"
                        "Horizontal_Positional_Accuracy_Report")
    hand = _by_hand()
    assert sorted(r.findtext("Horizontal_Positional_Accuracy_Value") for r in reps) == sorted(
        f"{v:.3f}" for v in hand.values())
    for r in reps:
        assert "Compiled to meet" in r.findtext("Horizontal_Positional_Accuracy_Explanation")
    assert not list((tmp_path / "out").glob(".tmp-*"))


def test_fgdc_hostile_and_entities():
    from orthospec.metadata import NssdaStatement

    s = NssdaStatement(item='B<script>"\u202e', axis="horizontal", value_m=0.5, tested=True, valid=True,
                       rule="NSSDA-H95")
    xml = fgdc_with_statements(None, [s])
    assert b"<script>" not in xml
    root = etree.fromstring(xml)
    assert 'B<script>"\u202e' in root.findtext(".//Horizontal_Positional_Accuracy_Explanation")
    evil = (b'<?xml version="1.0"?><!DOCTYPE m [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
            b"<metadata><t>&e;</t></metadata>")
    assert b"root:" not in fgdc_with_statements(evil, [s])
