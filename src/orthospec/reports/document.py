"""Entry point for the auditor's report: QCR document -> ``report.html`` / ``report.pdf``.

``render(doc, formats=[...])`` is what ``orthospec check`` and ``orthospec report`` call. It reads
the QCR document only (``extra`` is accepted for the check command's convenience and ignored), so
a stored qcr.json re-renders to the same report. The PDF is PDF/A-3b and carries qcr.json and a
CSV of every check point as attachments.
"""

from __future__ import annotations

import csv
import hashlib
import io
from collections.abc import Iterable
from typing import Any

from ..errors import ReportError
from ..qcr import csv_safe, natural_key, point_rows
from ..resources import templates_dir
from .fetcher import SafeFetcher, data_uri
from .html import ReportOptions, canonical_qcr, document_sha256, render_html

__all__ = ["FORMATS", "checkpoints_csv", "document_sha256", "render"]

FORMATS = ("html", "pdf")
CHECKPOINT_COLUMNS = [
    "block",
    "point_id",
    "x_ref",
    "y_ref",
    "dx",
    "dy",
    "dz",
    "dr",
    "status",
    "decision",
    "row",
]


def checkpoints_csv(doc: dict[str, Any]) -> str:
    """The JRC §12.6 check point table of every block as CSV (complete, unlike the PDF pages)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CHECKPOINT_COLUMNS)
    cps = (doc.get("details") or {}).get("checkpoints") or {}
    for bid in sorted(cps, key=natural_key):
        for p in point_rows((cps[bid] or {}).get("points")):
            w.writerow(
                [
                    csv_safe(bid),
                    *(
                        csv_safe("" if p.get(k) is None else p.get(k))
                        for k in CHECKPOINT_COLUMNS[1:]
                    ),
                ]
            )
    return buf.getvalue()


def _check_doc(doc: Any) -> None:
    if not isinstance(doc, dict):
        raise ReportError(f"a QCR document must be a JSON object, got {type(doc).__name__}")
    missing = [
        k
        for k in ("schema", "date", "profile", "delivery", "verdict", "summary", "records")
        if k not in doc
    ]
    if missing:
        raise ReportError(
            f"not a QCR document: missing key(s) {', '.join(missing)} "
            f"(expected qcr.json written by `orthospec check`)"
        )


def render(
    doc: dict[str, Any],
    *,
    formats: Iterable[str] = FORMATS,
    extra: dict[str, Any] | None = None,
    options: ReportOptions | None = None,
) -> dict[str, str | bytes]:
    """Render the requested report formats in memory: ``{"report.html": str, "report.pdf": bytes}``."""
    del extra  # the report must be reproducible from qcr.json alone
    fmts = list(dict.fromkeys(formats))
    bad = [f for f in fmts if f not in FORMATS]
    if bad:
        raise ReportError(
            f"unknown report format(s) {', '.join(bad)}; choose from {', '.join(FORMATS)}"
        )
    _check_doc(doc)
    out: dict[str, str | bytes] = {}
    cache: dict[str, list[dict[str, str]]] = {}  # figures are drawn once for both formats
    qcr_text = canonical_qcr(
        doc
    )  # serialised once: checksum and attachment (national deliveries are large)
    sha = hashlib.sha256(qcr_text.encode("utf-8")).hexdigest()
    if "html" in fmts:
        opts = options or ReportOptions(bounded=False)
        out["report.html"] = render_html(doc, opts, figure=data_uri, cache=cache, sha256=sha)
    if "pdf" in fmts:
        from .pdf import FileAttachment, write_pdf

        opts = options or ReportOptions(bounded=True)
        fetcher = SafeFetcher(templates_dir())
        html = render_html(
            doc,
            opts,
            figure=lambda data, mime: fetcher.allow(data_uri(data, mime)),
            pdf=True,
            cache=cache,
            sha256=sha,
        )
        files = [
            FileAttachment(
                "qcr.json",
                qcr_text.encode("utf-8"),
                f"The complete quality control records as orthospec check wrote them "
                f"(SHA-256 {sha}); sign-offs and history are in the report and the ledger",
            )
        ]
        cps = (doc.get("details") or {}).get("checkpoints")
        if cps:
            files.append(
                FileAttachment(
                    "checkpoints.csv",
                    checkpoints_csv(doc).encode("utf-8"),
                    "Check point discrepancies and Pass/Fail status (JRC §12.6), all blocks",
                )
            )
        profile_yaml = doc.get("profile", {}).get("resolved_yaml")
        if isinstance(profile_yaml, str):
            files.append(
                FileAttachment(
                    "profile.yaml",
                    profile_yaml.encode("utf-8"),
                    "The resolved spec profile",
                    relationship="Source",
                )
            )
        out["report.pdf"] = write_pdf(
            html, fetcher=fetcher, day=str(doc["date"]), identifier=sha, attachments=files
        )
    return out
