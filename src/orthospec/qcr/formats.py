"""Every machine output rendered from one QCR document, by format name.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..errors import OrthospecError
from .csv import iter_csv
from .json import iter_dumps
from .junit import iter_junit
from .parquet import to_parquet

Output = str | bytes | Iterable[str]


def render_all(doc: dict[str, Any], formats: Iterable[str]) -> dict[str, Output]:
    """Every requested machine output, written by ``api.write_outputs`` all or none.

    qcr.json, qcr.csv and junit.xml are streams of pieces (:func:`iter_dumps`, :func:`iter_csv`,
    :func:`iter_junit`), written to their temporary files piece by piece; the others are rendered
    in memory first."""
    out: dict[str, Output] = {}
    fmts = set(formats)
    if "json" in fmts:
        out["qcr.json"] = iter_dumps(doc)
    if "csv" in fmts:
        out["qcr.csv"] = iter_csv(doc)
    if "junit" in fmts:
        out["junit.xml"] = iter_junit(doc)
    if "parquet" in fmts:
        out["qcr.parquet"] = to_parquet(doc)
    own = {"json", "csv", "junit", "parquet", "terminal", "html", "pdf"}
    for name in sorted(fmts - own):
        from .. import plugins  # lazy: only when a format a plugin adds is asked for

        fmt = plugins.output_format(name)
        if fmt is None:
            raise OrthospecError(
                f"unknown output format {name!r}: neither orthospec's nor a plugin's "
                "(orthospec.formats entry point)"
            )
        out[f"qcr{fmt.suffix}"] = fmt.render(doc)
    return out
