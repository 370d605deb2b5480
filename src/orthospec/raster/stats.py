"""What a raster scan is asked (:class:`ScanSettings`, part of the cache key) and what it
returns (:class:`RasterStats`): the types the scan (raster/scan.py), its accumulators
(raster/accumulators.py) and the result cache share, apart from the code that fills them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from ..measures.histogram import BandStats
from ..measures.luminosity import LUMA_WEIGHTS
from ..measures.registration import Shift
from .misregistration import misregistration_reliable
from .opening import GDAL_CACHEMAX_MB


@dataclass(frozen=True)
class ScanSettings:
    """What a scan computes; part of the cache key."""

    bit_depth: int | None = None
    noise: bool = True
    luminosity: bool = True
    misregistration: bool = True
    #: the pixel facts of issue 25 (measures/signature.py): content hash of the decoded pixels,
    #: thumbnail for near copies, measured cloud cover
    signature: bool = True
    #: noise estimators look at whole chunks spread evenly over the image, at most this many
    #: pixels per band (4 Mpx estimate sigma to better than 1 %); 0 = every chunk
    noise_max_pixels: int = 4 * 2**20
    chunk_bytes: int = 8 * 2**20
    gdal_cachemax_mb: int = GDAL_CACHEMAX_MB
    #: threads counting the chunks of one image (besides the reader thread); the results do not
    #: depend on it (chunks always go to the same two accumulator sets, merged in one order)
    threads: int = 2

    def key(self) -> str:
        """Stable text key of the settings that change results (not of performance knobs)."""
        d = asdict(self)
        d.pop("chunk_bytes")
        d.pop("gdal_cachemax_mb")
        d.pop("threads")
        return ";".join(f"{k}={d[k]}" for k in sorted(d))


@dataclass
class RasterStats:
    """Everything a scan of one raster measured (no file checks)."""

    bands: list[BandStats]
    luminosity: BandStats | None
    misregistration: dict[int, Shift] = field(default_factory=dict)
    misregistration_spread: dict[int, float] = field(default_factory=dict)
    reference_band: int | None = None
    chunks: int = 0
    #: facts of the decoded pixels (measures/signature.py): content hash, thumbnail cell means,
    #: measured cloud cover (None: no colour bands), DN-0 saturation under a nodata value of 0
    pixels_hash: str | None = None
    thumbnail: list[list[float | None]] | None = None
    thumbnail_cell_px: int | None = None
    cloud_pct: float | None = None
    cloud_samples: int | None = None
    low_nodata: dict[str, Any] | None = None

    def to_dict(self, *, histogram: bool = True) -> dict[str, Any]:
        return {
            "statistics": "exact, population std, nodata excluded per band, as GDAL",
            "bands": [b.to_dict(histogram=histogram) for b in self.bands],
            "luminosity": None
            if self.luminosity is None
            else self.luminosity.to_dict(histogram=histogram),
            "luminosity_weights": list(LUMA_WEIGHTS),
            "misregistration": {
                str(k): {
                    "dy_px": v.dy,
                    "dx_px": v.dx,
                    "magnitude_px": v.magnitude,
                    "peak": v.peak,
                    "spread_px": self.misregistration_spread.get(k),
                    "reliable": misregistration_reliable(
                        v.peak, self.misregistration_spread.get(k)
                    ),
                }
                for k, v in sorted(self.misregistration.items())
            },
            "misregistration_reference_band": self.reference_band,
            "pixels_hash": self.pixels_hash,
            "thumbnail": self.thumbnail,
            "thumbnail_cell_px": self.thumbnail_cell_px,
            "cloud_pct": self.cloud_pct,
            "cloud_samples": self.cloud_samples,
            "low_nodata": self.low_nodata,
        }
