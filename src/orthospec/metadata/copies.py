"""Updated copies of the delivery's own metadata XML (issue 30 item 3), written to ``--out``.

Which files: the delivery convention's ``metadata/`` folder (every ``*.xml`` file directly in it),
plus any ``documents:`` entry of the manifest that names an ``.xml`` file. Nothing is declared for
this: the metadata files are read only to write the copies, never as evidence of a rule, so no
entry in delivery.yaml can change a verdict through them.

What each file is, is read from its root element, never from its name:

* ``metadata`` (FGDC CSDGM, short or long element names): the NSSDA §3.2.3 statements go into
  ``dataqual/posacc`` (:func:`.nssda.fgdc_with_statements`); a QCR with no NSSDA figure gives no
  CSDGM copy (there is no statement to write);
* ``gmd:MD_Metadata`` or ``gmi:MI_Metadata`` (ISO 19139 / ISO 19115-2): orthospec's ISO 19157
  ``gmd:DQ_DataQuality`` is added (:func:`.iso19157.iso19139_document`);
* anything else is left alone.

A metadata file that cannot be read safely (larger than ``ORTHOSPEC_MAX_XML_BYTES``, not
well-formed, declaring entities) stops the output with a message naming the file: the user asked
for the copies, and a copy silently missing would read as "nothing to update".

The copies are named ``metadata-<file name>`` (characters other than letters, digits, ``.``,
``-`` and ``_`` replaced by ``_``; a second file of the same name gets ``-2``...), so they never
overwrite qcr.json, the reports or each other. The delivery's files are only read.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import OrthospecError
from ..ingest.metadata import safe_parse
from .iso19157 import ROOTS, iso19139_document
from .nssda import fgdc_with_statements, nssda_statements

#: the delivery convention's folder of metadata files
FOLDER = "metadata"
FGDC = "FGDC CSDGM"
ISO = "ISO 19139"


@dataclass(frozen=True)
class MetadataFile:
    """One metadata file of the delivery: its path inside the delivery (``rel``), where it was
    found (``metadata/`` or ``documents.<key>``) and its standard (read from the root element)."""

    rel: str
    path: Path
    found: str
    standard: str


def _standard(tree: Any) -> str | None:
    root = tree.getroot()
    if root.tag in ROOTS:
        return ISO
    if root.tag == "metadata":
        return FGDC
    return None


def _candidates(root: Path, documents: Mapping[str, str]) -> list[tuple[str, str]]:
    seen: dict[str, str] = {}
    folder = root / FOLDER
    if folder.is_dir() and not folder.is_symlink():
        for p in sorted(folder.iterdir()):
            if p.suffix.lower() == ".xml" and p.is_file():
                seen.setdefault(f"{FOLDER}/{p.name}", FOLDER + "/")
    for key, rel in sorted(documents.items()):
        if isinstance(rel, str) and rel.lower().endswith(".xml"):
            seen.setdefault(rel.split("#", 1)[0], f"documents.{key}")
    return sorted(seen.items())


def find_metadata(delivery: Any) -> list[MetadataFile]:
    """The delivery's metadata files (``delivery``: a :class:`orthospec.delivery.reader.Delivery`,
    whose ``path`` refuses a file outside the delivery). A file that is missing is left out (the
    document rules report a missing document); one that cannot be parsed safely raises
    :class:`OrthospecError` naming it."""
    out: list[MetadataFile] = []
    documents = dict(getattr(delivery.manifest, "documents", {}) or {})
    for rel, found in _candidates(Path(delivery.root), documents):
        path = delivery.path(rel, what=found)
        if not path.is_file():
            continue
        tree, why = safe_parse(path, rel)
        if tree is None:
            raise OrthospecError(
                f"{rel} ({found}): the metadata file {why}; no metadata copy written"
            )
        standard = _standard(tree)
        if standard is not None:
            out.append(MetadataFile(rel, path, found, standard))
    return out


def copy_name(rel: str, taken: Iterable[str] = ()) -> str:
    """``metadata-<file name>`` of ``rel``, safe as a file name, distinct from ``taken``."""
    base = re.sub(r"[^A-Za-z0-9._-]", "_", rel.rsplit("/", 1)[-1]).lstrip(".") or "metadata.xml"
    stem, dot, ext = base.rpartition(".")
    stem, ext = (stem, f".{ext}") if dot and stem else (base, "")
    name, n, used = f"metadata-{stem}{ext}", 1, set(taken)
    while name in used:
        n += 1
        name = f"metadata-{stem}-{n}{ext}"
    return name


def metadata_copies(
    doc: Mapping[str, Any], files: Iterable[MetadataFile], taken: Iterable[str] = ()
) -> dict[str, bytes]:
    """Output name -> bytes of the updated copy of each metadata file (see the module docstring)."""
    out: dict[str, bytes] = {}
    used = set(taken)
    statements = nssda_statements(doc)
    for f in files:
        data = f.path.read_bytes()
        if f.standard == FGDC:
            if not statements:
                continue
            payload = fgdc_with_statements(data, statements)
        else:
            payload = iso19139_document(doc, data)
        name = copy_name(f.rel, used)
        used.add(name)
        out[name] = payload
    return out


def metadata_outputs(doc: Mapping[str, Any], delivery: Any = None) -> dict[str, bytes]:
    """Everything ``--format iso19157`` writes: ``iso19157.xml`` (the standalone ISO 19157
    ``gmd:DQ_DataQuality``) and, when ``delivery`` is given, the updated copies of its metadata."""
    out = {"iso19157.xml": iso19139_document(doc)}
    if delivery is not None:
        out.update(metadata_copies(doc, find_metadata(delivery), taken=out))
    return out
