"""Reading delivered rasters and vectors: the names of the modules they live in, under their
former address.

* opening.py: open strictly read-only (driver allow-list, size limits, read-only GDAL
  configuration), :func:`gdal_errors` (the one boundary mapping the libraries' errors to
  MeasureError naming the file), chunk windows, per-band validity;
* scan.py: the one read of the pixels feeding every accumulator (:func:`scan_raster`);
* misregistration.py: band misregistration windows taken from the scan's chunks;
* vector.py: delivered GeoPackages and shapefiles, read without touching the delivery.
"""

from __future__ import annotations

from .misregistration import (
    MISREGISTRATION_MAX_SPREAD_PX,
    MISREGISTRATION_MIN_PEAK,
    MISREGISTRATION_UPSAMPLE,
    MisregistrationWindows,
    misregistration_reliable,
)
from .opening import (
    LIBRARY_ERRORS,
    BandInfo,
    RasterLimits,
    band_infos,
    check_declared_size,
    chunk_windows,
    gdal_errors,
    library_errors,
    open_read_only,
    raster_driver,
    read_only_env,
    validity,
)
from .scan import (
    CHUNKS_IN_FLIGHT,
    SCAN_COUNT,
    RasterStats,
    ScanSettings,
    helper_pool,
    mask_share,
    scan_dataset,
    scan_raster,
)
from .vector import VECTOR_BATCH, read_vector, readable_vector, vector_driver

#: the former private name, still imported by tests written against it
_MisregistrationWindows = MisregistrationWindows

__all__ = [
    "CHUNKS_IN_FLIGHT",
    "LIBRARY_ERRORS",
    "MISREGISTRATION_MAX_SPREAD_PX",
    "MISREGISTRATION_MIN_PEAK",
    "MISREGISTRATION_UPSAMPLE",
    "SCAN_COUNT",
    "VECTOR_BATCH",
    "BandInfo",
    "MisregistrationWindows",
    "RasterLimits",
    "RasterStats",
    "ScanSettings",
    "_MisregistrationWindows",
    "band_infos",
    "check_declared_size",
    "chunk_windows",
    "gdal_errors",
    "helper_pool",
    "library_errors",
    "mask_share",
    "misregistration_reliable",
    "open_read_only",
    "raster_driver",
    "read_only_env",
    "read_vector",
    "readable_vector",
    "scan_dataset",
    "scan_raster",
    "validity",
    "vector_driver",
]
