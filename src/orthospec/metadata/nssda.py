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
        warn = (
            "" if self.valid else "; RMSE_min/RMSE_max below 0.6: the approximation does not hold"
        )
        return f"Block {self.item}: {formula} (orthospec rule {self.rule}); {how}{warn}."

    def as_dict(self) -> dict[str, Any]:
        return {
            "item": self.item,
            "axis": self.axis,
            "value": self.value_m,
            "unit": "m",
            "tested": self.tested,
            "valid": self.valid,
            "rule": self.rule,
            "text": self.text,
        }


def nssda_statements(doc: Mapping[str, Any]) -> list[NssdaStatement]:
    """The §3.2.3 statements of a QCR document, one per block and axis with a measured figure."""
    records = list(all_records(doc))
    tested = any(r["rule"] == INDEPENDENCE_RULE and r["verdict"] == "pass" for r in records)
    ratio_failed = {
        r["item"] for r in records if r["rule"] == RATIO_RULE and r["verdict"] == "fail"
    }
    out: list[NssdaStatement] = []
    for r in records:
        measure = r.get("measure", "")
        if measure not in (H_MEASURE, V_MEASURE):
            continue
        value = r["measured"]["value"] if isinstance(r["measured"], Mapping) else r["measured"]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value:
            continue
        axis = "horizontal" if measure == H_MEASURE else "vertical"
        out.append(
            NssdaStatement(
                item=str(r["item"]),
                axis=axis,
                value_m=float(value),
                tested=tested,
                valid=not (axis == "horizontal" and r["item"] in ratio_failed),
                rule=str(r["rule"]),
            )
        )
    return out


#: CSDGM (FGDC-STD-001-1998) elements written, as the XML schema names them (short names, as
#: fgdc-std-001-1998.xsd and every CSDGM tool read) and as the standard's long names (a document
#: whose root's children use long names gets long names)
_LONG = {
    "dataqual": "Data_Quality_Information",
    "posacc": "Positional_Accuracy",
    "horizpa": "Horizontal_Positional_Accuracy",
    "horizpar": "Horizontal_Positional_Accuracy_Report",
    "qhorizpa": "Quantitative_Horizontal_Positional_Accuracy_Assessment",
    "horizpav": "Horizontal_Positional_Accuracy_Value",
    "horizpae": "Horizontal_Positional_Accuracy_Explanation",
    "vertpa": "Vertical_Positional_Accuracy",
    "vertaccr": "Vertical_Positional_Accuracy_Report",
    "qvertpa": "Quantitative_Vertical_Positional_Accuracy_Assessment",
    "vertaccv": "Vertical_Positional_Accuracy_Value",
    "vertacce": "Vertical_Positional_Accuracy_Explanation",
    "idinfo": "Identification_Information",
    "attracc": "Attribute_Accuracy",
    "logic": "Logical_Consistency_Report",
    "complete": "Completeness_Report",
    "lineage": "Lineage",
    "cloud": "Cloud_Cover",
    "spdoinfo": "Spatial_Data_Organization_Information",
    "spref": "Spatial_Reference_Information",
    "eainfo": "Entity_and_Attribute_Information",
    "distinfo": "Distribution_Information",
    "metainfo": "Metadata_Reference_Information",
}
#: the sequences the elements sit in (FGDC-STD-001-1998 sections 0 and 2; the XML schema keeps the
#: standard's order): a new element goes before the first sibling that follows it
_ORDER = {
    "metadata": ("idinfo", "dataqual", "spdoinfo", "spref", "eainfo", "distinfo", "metainfo"),
    "dataqual": ("attracc", "logic", "complete", "posacc", "lineage", "cloud"),
    "posacc": ("horizpa", "vertpa"),
}
#: axis -> (holder, report, quantitative assessment, value, explanation)
_AXES = {
    "horizontal": ("horizpa", "horizpar", "qhorizpa", "horizpav", "horizpae"),
    "vertical": ("vertpa", "vertaccr", "qvertpa", "vertaccv", "vertacce"),
}
#: FGDC-STD-007.3-1998 §3.2.3: the explanation of a value tested (or compiled) to the NSSDA
NSSDA_NAME = "National Standard for Spatial Data Accuracy"


class _Names:
    """Short or long CSDGM element names, as the document in hand uses them."""

    def __init__(self, root: etree._Element) -> None:
        self.long = any(isinstance(c.tag, str) and c.tag in _LONG.values() for c in root)
        self._order = {self(k): tuple(self(t) for t in v) for k, v in _ORDER.items()}

    def __call__(self, short: str) -> str:
        return _LONG.get(short, short) if self.long else short

    def child(self, parent: etree._Element, short: str) -> etree._Element:
        """The first ``short`` child of ``parent``, created at its place in the sequence if absent."""
        tag = self(short)
        found = parent.find(tag)
        if found is not None:
            return found
        el = etree.Element(tag)
        self.place(parent, el)
        return el

    def place(self, parent: etree._Element, el: etree._Element) -> None:
        order = self._order.get(parent.tag)
        if order and el.tag in order:
            later = set(order[order.index(el.tag) + 1 :])
            nxt = next((c for c in parent if c.tag in later), None)
            if nxt is not None:
                nxt.addprevious(el)
                return
        parent.append(el)


def _report_text(axis: str, mine: list[NssdaStatement]) -> str:
    lines = [f"{s.text} (block {s.item})." for s in mine]
    return (
        f"{NSSDA_NAME} (FGDC-STD-007.3-1998 §3.2.3), {axis} accuracy per block measured by the external "
        "quality control: " + " ".join(lines)
    )


def fgdc_with_statements(source: bytes | None, statements: list[NssdaStatement]) -> bytes:
    """A CSDGM document (the delivery's bytes, or a minimal ``metadata`` root when None) with the
    statements in Data_Quality_Information/Positional_Accuracy (``dataqual/posacc``): per axis, a
    report worded as §3.2.3 and one quantitative assessment per block (value in metres, explanation
    "National Standard for Spatial Data Accuracy" followed by the block's statement). The producer's
    own positional accuracy of that axis is replaced (it is a declaration; the statement is the
    measured figure); every other element is kept. New elements go where the standard's sequence
    puts them. The parser resolves no entities, loads no DTD and reads nothing from the network."""
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, remove_blank_text=True
    )
    root = etree.fromstring(source, parser) if source else etree.Element("metadata")
    names = _Names(root)
    if not statements:
        return _serialise(root)
    dq = names.child(root, "dataqual")
    pa = names.child(dq, "posacc")
    for axis, (box, report, quant, value, expl) in _AXES.items():
        mine = [s for s in statements if s.axis == axis]
        if not mine:
            continue
        for old in pa.findall(names(box)):
            pa.remove(old)
        holder = etree.Element(names(box))
        names.place(pa, holder)
        etree.SubElement(holder, names(report)).text = _report_text(axis, mine)
        for s in mine:
            q = etree.SubElement(holder, names(quant))
            etree.SubElement(q, names(value)).text = f"{s.value_m:.3f}"
            etree.SubElement(q, names(expl)).text = f"{NSSDA_NAME}. {s.text}. {s.explanation}"
    return _serialise(root)


def _serialise(root: etree._Element) -> bytes:
    """The whole document (its DOCTYPE line and the comments around the root kept), UTF-8."""
    return etree.tostring(
        root.getroottree(), xml_declaration=True, encoding="UTF-8", pretty_print=True
    )


def write_fgdc_copy(
    doc: Mapping[str, Any],
    out_dir: str | Path,
    source: str | Path | None = None,
    *,
    name: str = "metadata.fgdc.xml",
) -> Path:
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
