"""Image chips around the checker's check points, for the report (issue 29 item 6).

For a flagged or hand-measured point of the checker's table, the report shows the delivered image
around the measured position beside the reference chip around the 'true' one, with the shift drawn
(figures/chips.py). The chips are cut here at check time, with windowed reads of the two rasters
only, reduced to an 8-bit luminance of at most :data:`CHIP_PX` pixels a side, and stored in
qcr.json (``details.checker_chips``) so that a report rendered later from the document draws them
without the delivery. Nothing is fetched; a point no raster covers gets the reason instead.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import OrthospecError

#: edge of a stored chip, pixels (a 48 x 48 8-bit chip is 2.3 kB in qcr.json)
CHIP_PX = 48


@dataclass(frozen=True)
class Chip:
    """An 8-bit luminance window and the map extent (left, bottom, right, top) it covers."""

    data: np.ndarray
    extent: tuple[float, float, float, float]

    def to_dict(self) -> dict[str, Any]:
        h, w = self.data.shape
        return {
            "shape": [int(h), int(w)],
            "extent": [float(v) for v in self.extent],
            "luminance": base64.b64encode(
                np.ascontiguousarray(self.data, dtype=np.uint8).tobytes()
            ).decode(),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Chip:
        h, w = (int(v) for v in d["shape"])
        raw = base64.b64decode(str(d["luminance"]), validate=True)
        if len(raw) != h * w or h <= 0 or w <= 0 or h > 4 * CHIP_PX or w > 4 * CHIP_PX:
            raise ValueError("chip size does not match its data")
        ext = tuple(float(v) for v in d["extent"])
        if len(ext) != 4:
            raise ValueError("chip extent needs 4 numbers")
        return cls(np.frombuffer(raw, dtype=np.uint8).reshape(h, w), ext)


def read_chip(path: str | Path, x: float, y: float, *, name: str, px: int = CHIP_PX) -> Chip | str:
    """The window of ``px`` x ``px`` pixels of the raster at ``path`` centred on map position (x, y), as 8-bit
    luminance (mean of the first three bands, or the band, stretched 2-98 %); or why there is none
    (the position lies outside the raster, it cannot be read)."""
    from rasterio.windows import Window, bounds

    from ..raster.reading import gdal_errors, open_read_only, read_only_env

    try:
        with (
            read_only_env(),
            open_read_only(path, name=name) as ds,
            gdal_errors(file=name, path=path),
        ):
            row, col = ds.index(x, y)
            if not (0 <= row < ds.height and 0 <= col < ds.width):
                return f"({x:.3f}, {y:.3f}) lies outside {name}"
            half = px // 2
            win = Window(col - half, row - half, px, px).intersection(
                Window(0, 0, ds.width, ds.height)
            )
            bands = list(range(1, min(ds.count, 3) + 1))
            arr = ds.read(bands, window=win, masked=True).astype(np.float64)
            lum = np.ma.mean(arr, axis=0).filled(np.nan)
            ext = bounds(win, ds.transform)
    except OrthospecError as exc:
        return str(exc)
    ok = np.isfinite(lum)
    if not ok.any():
        return f"{name} holds no valid pixel around ({x:.3f}, {y:.3f})"
    lo, hi = np.percentile(lum[ok], [2, 98])
    scaled = np.clip((lum - lo) / (hi - lo if hi > lo else 1.0) * 255.0, 0, 255)
    data = np.where(ok, scaled, 0).round().astype(np.uint8)
    return Chip(data, (float(ext[0]), float(ext[1]), float(ext[2]), float(ext[3])))
