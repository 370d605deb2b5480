"""Quality statements for the delivery's metadata (issue 30 item 3, docs/METADATA.md).

:mod:`.nssda` words the FGDC-STD-007.3-1998 §3.2.3 reporting statement from a QCR document's judged
figures and writes it into a copy of an FGDC CSDGM XML file; :mod:`.iso19157` writes ISO 19157
data-quality elements as ISO 19139 XML (standalone, or into a copy of an MD_Metadata record);
:mod:`.copies` finds the delivery's own metadata records and makes the updated copies
``check --format iso19157`` writes to ``--out``.
"""

from .nssda import NssdaStatement, nssda_statements, write_fgdc_copy

__all__ = ["NssdaStatement", "nssda_statements", "write_fgdc_copy"]
