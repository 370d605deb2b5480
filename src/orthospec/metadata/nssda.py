"""The NSSDA reporting statement (FGDC-STD-007.3-1998 §3.2.3).

The statement is worded from the QCR document's judged figures, never recomputed from the tables:
the records of the measures ``checkpoints.nssda_horizontal_95`` (Accuracy_r) and
``checkpoints.nssda_vertical_95`` (Accuracy_z), one per block. §3.2.3 words it "Tested __ (meters,
feet) horizontal accuracy at 95% confidence level" when the accuracy was tested against an
independent source of higher accuracy, and "Compiled to meet __ (meters, feet) horizontal accuracy
at 95% confidence level" otherwise: here "Tested" only when the rule NSSDA-3.2.1-INDEPENDENT-SOURCE
passed (a signed confirmation); any other verdict (missing, fail) gives "Compiled to meet".
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lxml import etree

from ..qcr import all_records

H_MEASURE = "checkpoints.nssda_horizontal_95"
V_MEASURE = "checkpoints.nssda_vertical_95"
INDEPENDENCE_RULE = "NSSDA-3.2.1-INDEPENDENT-SOURCE"
RATIO_RULE = "NSSDA-3.2.1-RMSE-RATIO"


@dataclass(frozen=True)
class NssdaStatement:
    """One block's statement: ``axis`` is ``horizontal`` or ``vertical``; ``tested`` says whether
    the independence of the reference was confirmed; ``valid`` is False when the horizontal
    approximation does not hold (RMSE ratio rule failed): the figure must not be relied on."""

    item: str
    axis: str
    value_m: float
    tested: bool
    valid: bool
    rule: str

    @property
    def text(self) -> str:
        verb = "Tested" if self.tested else "Compiled to meet"
        return f"{verb} {self.value_m:.3f} meters {self.axis} accuracy at 95% confidence level"

    @property
    def explanation(self) -> str:
        how = ("tested against check points from an independent source of higher accuracy"
               if self.tested else
               "the independence of the check points' source is not confirmed (rule "
               f"{INDEPENDENCE_RULE}), so FGDC-STD-007.3-1998 §3.2.3 words it 'Compiled to meet'")
        formula = ("Accuracy_r per FGDC-STD-007.3-1998 Appendix 3-A" if self.axis == "horizontal"
                   else "Accuracy_z = 1.9600 x RMSE_z per FGDC-STD-007.3-1998 Appendix 3-A")
        warn = "" if self.valid else "; RMSE_min/RMSE_max below 0.6: the approximation does not hold"
        return f"Block {self.item}: {formula} (orthospec rule {self.rule}); {how}{warn}."

    def as_dict(self) -> dict[str, Any]:
        return {"item": self.item, "axis": self.axis, "value": self.value_m, "unit": "m",
                "tested": self.tested, "valid": self.valid, "rule": self.rule, "text": self.text}


def nssda_statements(doc: Mapping[str, Any]) -> list[NssdaStatement]:
    """The §3.2.3 statements of a QCR document, one per block and axis with a measured figure."""
    records = list(all_records(doc))
    tested = any(r["rule"] == INDEPENDENCE_RULE and r["verdict"] == "pass" for r in records)
    ratio_failed = {r["item"] for r in records if r["rule"] == RATIO_RULE and r["verdict"] == "fail"}
    out: list[NssdaStatement] = []
    for r in records:
        measure = r.get("measure", "")
        if measure not in (H_MEASURE, V_MEASURE):
            continue
        value = r["measured"]["value"] if isinstance(r["measured"], Mapping) else r["measured"]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value:
            continue
        axis = "horizontal" if measure == H_MEASURE else "vertical"
        out.append(NssdaStatement(item=str(r["item"]), axis=axis, value_m=float(value), tested=tested,
                                  valid=not (axis == "horizontal" and r["item"] in ratio_failed),
                                  rule=str(r["rule"])))
    return out


_PATHS = {
    "horizontal": ("Horizontal_Positional_Accuracy", "Horizontal_Positional_Accuracy_Report",
                   "Horizontal_Positional_Accuracy_Value", "Horizontal_Positional_Accuracy_Explanation"),
    "vertical": ("Vertical_Positional_Accuracy", "Vertical_Positional_Accuracy_Report",
                 "Vertical_Positional_Accuracy_Value", "Vertical_Positional_Accuracy_Explanation"),
}


def _child(parent: etree._Element, tag: str) -> etree._Element:
    found = parent.find(tag)
    return found if found is not None else etree.SubElement(parent, tag)


def fgdc_with_statements(source: bytes | None, statements: list[NssdaStatement]) -> bytes:
    """A CSDGM document (the delivery's bytes, or a minimal ``metadata`` root when None) with the
    statements as Data_Quality_Information/Positional_Accuracy reports; earlier reports of the same
    axis are replaced. The parser resolves no entities and reads nothing from the network."""
    parser = etree.XMLParser(resolve_entities=False, no_network=True, remove_blank_text=True)
    root = etree.fromstring(source, parser) if source else etree.Element("metadata")
    dq = _child(root, "Data_Quality_Information")
    pa = _child(dq, "Positional_Accuracy")
    for axis, (box, report, value, expl) in _PATHS.items():
        mine = [s for s in statements if s.axis == axis]
        if not mine:
            continue
        holder = _child(pa, box)
        for old in holder.findall(report):
            holder.remove(old)
        for s in mine:
            rep = etree.SubElement(holder, report)
            etree.SubElement(rep, value).text = f"{s.value_m:.3f}"
            etree.SubElement(rep, expl).text = f"{s.text}. {s.explanation}"
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def write_fgdc_copy(doc: Mapping[str, Any], out_dir: str | Path, source: str | Path | None = None,
                    *, name: str = "metadata.fgdc.xml") -> Path:
    """Write the delivery's CSDGM XML (``source``; None: a minimal one) with the statements into
    ``out_dir`` atomically; the source file is only read."""
    data = Path(source).read_bytes() if source is not None else None
    payload = fgdc_with_statements(data, nssda_statements(doc))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    target = out / name
    fd, tmp = tempfile.mkstemp(dir=out, prefix=".tmp-", suffix=".xml")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target
