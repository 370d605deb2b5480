"""Quality statements for the delivery's metadata (issue 30 item 3).

:mod:`.nssda` words the FGDC-STD-007.3-1998 §3.2.3 reporting statement from a QCR document's judged
figures and writes it into a copy of an FGDC CSDGM XML file.
"""

from .nssda import NssdaStatement, nssda_statements, write_fgdc_copy

__all__ = ["NssdaStatement", "nssda_statements", "write_fgdc_copy"]
