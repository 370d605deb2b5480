"""XML schemas the metadata tests validate orthospec's XML with, read from tests/data/xsd with no
network access (issue 30 item 3).

* ISO 19139 (ISO/TS 19139:2007 schemas, version 20070417, with GML 3.2.1 and xlink): the files as
  the pycsw 2.6.2 package on PyPI ships them, unmodified, in pycsw's folder layout so that their
  relative imports resolve (tests/data/xsd/iso19139/README.md says where each came from). pycsw
  itself cannot be a test dependency here (it pins OWSLib < 0.29, the ingest tests need >= 0.29).
* FGDC CSDGM: no package available here ships fgdc-std-001-1998.xsd (tests/data/xsd/csdgm/
  README.md says what was searched); tests/data/xsd/csdgm/dataqual.xsd is a schema written from
  the standard's production rules for the elements orthospec writes (sections 0 and 2, in the
  order the standard and its XML schema keep), other sections accepted as they are.

Every import is resolved from the local files: a resolver refuses any URL that is not a file
under tests/data/xsd, so a schema that would need the network fails loudly instead.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from lxml import etree

XSD = Path(__file__).resolve().parent / "data" / "xsd"
GMD_XSD = XSD / "iso19139/pycsw/plugins/profiles/apiso/schemas/ogc/iso/19139/20070417/gmd/gmd.xsd"
CSDGM_XSD = XSD / "csdgm" / "dataqual.xsd"


class _LocalOnly(etree.Resolver):
    """Refuse every schema location outside tests/data/xsd (no network, no other file)."""

    def resolve(self, url, pubid, context):  # type: ignore[no-untyped-def]
        path = Path(url[7:] if url.startswith("file://") else url)
        if (
            "://" in url[:12] and not url.startswith("file://")
        ) or not path.resolve().is_relative_to(XSD):
            raise OSError(f"schema import {url!r} is not a local file under {XSD}")
        return None  # libxml2 reads the local file itself


def _schema(path: Path) -> etree.XMLSchema:
    parser = etree.XMLParser(no_network=True, resolve_entities=False, load_dtd=False)
    parser.resolvers.add(_LocalOnly())
    return etree.XMLSchema(etree.parse(str(path), parser))


@lru_cache(maxsize=1)
def iso19139() -> etree.XMLSchema:
    return _schema(GMD_XSD)


@lru_cache(maxsize=1)
def csdgm() -> etree.XMLSchema:
    return _schema(CSDGM_XSD)


def errors(schema: etree.XMLSchema, xml: bytes | etree._Element) -> list[str]:
    """The validation errors of ``xml`` (empty when valid)."""
    tree = etree.fromstring(xml) if isinstance(xml, bytes) else xml
    schema.validate(tree)
    return [f"line {e.line}: {e.message}" for e in schema.error_log]
