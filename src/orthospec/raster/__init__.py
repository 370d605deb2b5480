"""Reading rasters in windows, file checks, parallel scans and the result cache.

Public API for the rule engine: :func:`scan_images` -> list of :class:`ImageReport`.
Names are imported lazily (PEP 562) so that ``import orthospec.raster.scan`` in a worker
or a short CLI call does not pay for multiprocessing, SQLite and the rest.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "FileChecks": "filechecks",
    "ImageReport": "parallel",
    "ListingCheck": "filechecks",
    "PlainProgress": "parallel",
    "Progress": "parallel",
    "RasterFacts": "facts",
    "RasterStats": "stats",
    "ResultCache": "cache",
    "RichProgress": "parallel",
    "ScanOptions": "parallel",
    "ScanSettings": "stats",
    "VectorCheck": "filechecks",
    "check_file": "filechecks",
    "checked_file": "filechecks",
    "gdal_errors": "opening",
    "library_errors": "opening",
    "open_read_only": "opening",
    "require_dask": "parallel",
    "scan_dataset": "scan",
    "check_name": "filechecks",
    "check_vector": "filechecks",
    "listing_consistency": "filechecks",
    "make_progress": "parallel",
    "mask_share": "scan",
    "read_facts": "facts",
    "scan_image": "parallel",
    "scan_images": "parallel",
    "scan_raster": "scan",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
