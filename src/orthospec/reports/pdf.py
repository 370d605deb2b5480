"""HTML -> archival PDF (PDF/A-3b) with WeasyPrint: deterministic, offline, data attached.

Determinism: the document dates (``dcterms.created/modified`` in the HTML head, the XMP packet and
the attachments' dates) come from the QCR date, and the PDF ``/ID`` is derived from the report
checksum instead of being random. Font subsets are written by fontTools, which stamps the font's
``head.modified`` with the wall clock unless ``SOURCE_DATE_EPOCH`` is set (reproducible-builds
convention): we set it to the QCR date for the duration of the render. The same HTML, attachments
and date then give byte-identical PDFs.
"""

from __future__ import annotations

import hashlib
import io
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, date, datetime

from ..errors import ReportError
from .fetcher import SafeFetcher

__all__ = ["PDF_VARIANT", "FileAttachment", "write_pdf"]

PDF_VARIANT = "pdf/a-3b"


@dataclass(frozen=True)
class FileAttachment:
    """A file embedded in the PDF (PDF/A-3 associated file)."""

    name: str
    data: bytes
    description: str
    relationship: str = "Data"  # PDF/A-3 AFRelationship: Source, Data, Alternative, Supplement


def _moment(day: str) -> datetime:
    try:
        d = date.fromisoformat(day)
    except (TypeError, ValueError) as exc:
        raise ReportError(f"report date {day!r} is not YYYY-MM-DD") from exc
    return datetime(d.year, d.month, d.day, tzinfo=UTC)


@contextmanager
def _source_date_epoch(moment: datetime) -> Iterator[None]:
    """Pin fontTools' timestamps (process-wide env var, restored afterwards)."""
    old = os.environ.get("SOURCE_DATE_EPOCH")
    os.environ["SOURCE_DATE_EPOCH"] = str(int(moment.timestamp()))
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("SOURCE_DATE_EPOCH", None)
        else:
            os.environ["SOURCE_DATE_EPOCH"] = old


def write_pdf(html: str, *, fetcher: SafeFetcher, day: str, identifier: str,
              attachments: Iterable[FileAttachment] = ()) -> bytes:
    """Render ``html`` to PDF/A-3b bytes.

    ``identifier`` (e.g. the report checksum) seeds the PDF file identifier; ``day`` (YYYY-MM-DD)
    dates the attachments. Resources are fetched only through ``fetcher``.
    """
    import weasyprint  # heavy: imported only when a PDF is asked for

    moment = _moment(day)
    files = [
        weasyprint.Attachment(
            file_obj=io.BytesIO(a.data),
            name=a.name,
            description=a.description,
            created=moment,
            modified=moment,
            relationship=a.relationship,
            url_fetcher=fetcher,
        )
        for a in attachments
    ]
    pdf_id = hashlib.sha256(f"orthospec-pdf:{identifier}".encode()).hexdigest()[:32].encode("ascii")
    try:
        doc = weasyprint.HTML(
            string=html, base_url=fetcher.root.as_uri() + "/", url_fetcher=fetcher
        )
        with _source_date_epoch(moment):
            return doc.write_pdf(
                pdf_variant=PDF_VARIANT,
                attachments=files,
                pdf_identifier=pdf_id,
                uncompressed_pdf=False,
                custom_metadata=False,
            )
    except (
        Exception
    ) as exc:  # WeasyPrint raises many kinds; never swallowed: one error class, chained
        # (the original traceback stays on __cause__ for --debug)
        raise ReportError(f"PDF rendering failed: {type(exc).__name__}: {exc}") from exc
