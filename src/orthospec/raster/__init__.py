"""Reading rasters in windows, file checks, parallel scans and the result cache.

Public API for the rule engine: :func:`scan_images` -> list of :class:`ImageReport`.
"""

from __future__ import annotations

from .cache import ResultCache
from .filechecks import (
    FileChecks,
    ListingCheck,
    VectorCheck,
    check_file,
    check_name,
    check_vector,
    listing_consistency,
)
from .parallel import (
    ImageReport,
    PlainProgress,
    Progress,
    RichProgress,
    ScanOptions,
    make_progress,
    scan_image,
    scan_images,
)
from .reading import (
    RasterStats,
    ScanSettings,
    mask_share,
    overlap_means,
    pan_fused_windows,
    scan_raster,
    seamline_check,
)

__all__ = [
    "FileChecks",
    "ImageReport",
    "ListingCheck",
    "PlainProgress",
    "Progress",
    "RasterStats",
    "ResultCache",
    "RichProgress",
    "ScanOptions",
    "ScanSettings",
    "VectorCheck",
    "check_file",
    "check_name",
    "check_vector",
    "listing_consistency",
    "make_progress",
    "mask_share",
    "overlap_means",
    "pan_fused_windows",
    "scan_image",
    "scan_images",
    "scan_raster",
    "seamline_check",
]
