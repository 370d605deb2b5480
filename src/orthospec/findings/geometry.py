"""The delivery's geometries the QCR document does not carry: image footprints and seamlines."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import OrthospecError

if TYPE_CHECKING:
    from ..delivery.reader import Delivery

Bounds = tuple[float, float, float, float]


@dataclass(frozen=True)
class DeliveryGeometry:
    """Image id -> (left, bottom, right, top) of its raster (None: unreadable, with why), and the
    seamline polygons with the image each shows (``why`` says what could not be read)."""

    footprints: dict[str, Bounds | None] = field(default_factory=dict)
    seamlines: list[tuple[Any, str | None]] = field(default_factory=list)
    seamlines_file: str | None = None
    why: dict[str, str] = field(default_factory=dict)


def read_geometry(d: Delivery) -> DeliveryGeometry:
    """Footprints from the raster headers (no pixel read) and the delivered seamline layer.

    A file that cannot be read leaves its feature without geometry (the QCR already says why);
    it never stops the outputs.
    """
    from ..raster.footprints import image_footprints, read_seamlines

    feet: dict[str, Bounds | None] = {}
    why: dict[str, str] = {}
    for iid, (bounds, reason) in image_footprints(d).items():
        feet[iid] = None if bounds is None else tuple(float(v) for v in bounds)  # type: ignore[assignment]
        if reason:
            why[iid] = reason
    seams: list[tuple[Any, str | None]] = []
    rel = d.manifest.vectors.get("seamlines")
    if rel:
        try:
            seams, _ = read_seamlines(d.path(rel, what="vectors.seamlines"), name=rel)
        except (OrthospecError, OSError) as exc:
            why["seamlines"] = f"{rel}: {exc}"
    return DeliveryGeometry(footprints=feet, seamlines=seams, seamlines_file=rel or None, why=why)


def with_footprints(doc: dict[str, Any], geometry: DeliveryGeometry) -> dict[str, Any]:
    """``doc`` with ``details.footprints`` (image id -> [left, bottom, right, top] of each readable
    raster), so the map of the findings re-renders from qcr.json alone (``orthospec report``)."""
    from ..qcr import natural_key

    feet = {
        iid: list(b)
        for iid, b in sorted(geometry.footprints.items(), key=lambda kv: natural_key(kv[0]))
        if b is not None
    }
    if feet:
        doc["details"] = dict(sorted({**(doc.get("details") or {}), "footprints": feet}.items()))
    return doc
