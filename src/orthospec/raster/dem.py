"""A delivered DEM file read for the JRC Table 7 integrity checks (§9.2 "complete, continuous and
without any gross anomalies ... correctly georeferenced").

One streamed pass over band 1 in row strips (a one-row halo above and below, so a spike on a strip
edge is seen once): the no-data share, the spikes and holes, and the CRS. A cell is a spike (or a
hole) when it lies more than ``spike_height`` above (below) the median of its 3 x 3 neighbourhood
with every one of the nine cells valid: §9.2 "Possibly use histograms/3D views to check for
spikes/holes". Heights are read in the file's own unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rasterio import features
from rasterio.windows import Window
from scipy import ndimage

from .reading import gdal_errors, open_read_only, read_only_env

#: rows read per strip (times the DEM's width, as float64): about 64 MB for a 16,000-column DEM
STRIP_ROWS = 512


@dataclass(frozen=True)
class DemIntegrity:
    """What one read of a DEM file tells: cells, no-data cells, spikes/holes, CRS."""

    width: int
    height: int
    #: cells judged for completeness: inside ``within`` when given, else every cell
    judged_cells: int
    nodata_cells: int
    spikes: int
    #: (row, column, height above (+) or below (-) the neighbourhood median) of the first spikes
    examples: tuple[tuple[int, int, float], ...] = field(default=())
    crs_wkt: str | None = None
    epsg: int | None = None

    @property
    def cells(self) -> int:
        return self.width * self.height

    @property
    def nodata_share(self) -> float:
        """No-data cells among the judged ones, % (100 when the area lies wholly off the file)."""
        return 100.0 * self.nodata_cells / self.judged_cells if self.judged_cells else 100.0


def horizontal_epsg(crs_wkt: str | None) -> int | None:
    """The EPSG code of a CRS, of its horizontal part for a compound CRS (heights have their own)."""
    if not crs_wkt:
        return None
    from pyproj import CRS

    crs = CRS.from_wkt(crs_wkt)
    if crs.is_compound and crs.sub_crs_list:
        crs = crs.sub_crs_list[0]
    return crs.to_epsg()


def spikes_in(z: np.ndarray, valid: np.ndarray, spike_height: float) -> np.ndarray:
    """Mask of cells more than ``spike_height`` from the median of their fully valid 3 x 3 window."""
    filled = np.where(valid, z, 0.0)
    med = ndimage.median_filter(filled, size=3, mode="nearest")
    whole = ndimage.minimum_filter(valid.astype(np.uint8), size=3, mode="constant", cval=0).astype(
        bool
    )
    return whole & (np.abs(z - med) > spike_height)


def dem_integrity(
    path: str | Path,
    *,
    name: str | None = None,
    spike_height: float = 30.0,
    within: Any = None,
    keep: int = 5,
) -> DemIntegrity:
    """Read a DEM file once: no-data cells (of the cells whose centre lies in ``within``, a shapely
    geometry in the file's CRS, when given: "completeness in the project zone"), spikes/holes beyond
    ``spike_height``, CRS.

    Raises MeasureError naming ``name`` when the file is refused or unreadable."""
    label = name or str(path)
    with (
        read_only_env(),
        open_read_only(path, name=label) as ds,
        gdal_errors(file=label, path=path),
    ):
        w, h = ds.width, ds.height
        nodata = ds.nodata
        nod = spikes = judged = 0
        examples: list[tuple[int, int, float]] = []
        for top in range(0, h, STRIP_ROWS):
            r0, r1 = max(0, top - 1), min(h, top + STRIP_ROWS + 1)
            z = ds.read(1, window=Window(0, r0, w, r1 - r0), masked=True).astype(np.float64)
            valid = ~np.ma.getmaskarray(z) & np.isfinite(z.filled(np.nan))
            if nodata is not None and not np.isnan(nodata):
                valid &= z.filled(np.nan) != nodata
            zz = z.filled(np.nan)
            own = slice(
                top - r0, top - r0 + min(STRIP_ROWS, h - top)
            )  # this strip's rows, halo excluded
            zone = np.ones_like(valid[own])
            if within is not None:
                win = Window(0, top, w, own.stop - own.start)
                zone = features.geometry_mask(
                    [within], out_shape=zone.shape, transform=ds.window_transform(win), invert=True
                )
            judged += int(zone.sum())
            nod += int((~valid[own] & zone).sum())
            hit = spikes_in(zz, valid, spike_height)[own]
            spikes += int(hit.sum())
            if len(examples) < keep and hit.any():
                med = ndimage.median_filter(np.where(valid, zz, 0.0), size=3, mode="nearest")[own]
                for r, c in zip(*np.nonzero(hit), strict=True):
                    if len(examples) >= keep:
                        break
                    examples.append((int(top + r), int(c), float(zz[own][r, c] - med[r, c])))
        wkt = ds.crs.to_wkt() if ds.crs is not None else None
    return DemIntegrity(w, h, judged, nod, spikes, tuple(examples), wkt, horizontal_epsg(wkt))
