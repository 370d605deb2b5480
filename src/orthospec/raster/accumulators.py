"""Every per-band accumulator of one scan, fed chunk by chunk (raster/scan.py streams the chunks).

Validity masks cost as much as a histogram: they are built only where a pixel can be invalid, and
only for the accumulators that need them. Two sets of accumulators count alternate chunks and merge
at the end; integer counts merge exactly, and the floating-point sums are added in chunk order
within each set, so the results do not depend on the machine's cores or on timing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import rasterio
from rasterio.windows import Window

from ..measures import signature as sig
from ..measures.counting import histogram_layout, scratch
from ..measures.histogram import HistogramAccumulator, Moments
from ..measures.luminosity import luminosity_block
from ..measures.noise import NoiseAccumulator
from .opening import BandInfo, validity

if TYPE_CHECKING:
    from .stats import RasterStats, ScanSettings


def _rgb_bands(infos: Sequence[BandInfo]) -> tuple[int, int, int] | None:
    """1-based R, G, B band indexes by colour interpretation, else bands 1-3 of a 3/4-band image."""
    by = {b.colour: b.index for b in infos}
    if {"red", "green", "blue"} <= by.keys():
        return by["red"], by["green"], by["blue"]
    if len(infos) in (3, 4) and all(b.colour in ("undefined", "gray") for b in infos[:3]):
        return 1, 2, 3
    return None


def _nonfinite(data: np.ndarray, info: BandInfo, mask: np.ndarray | None) -> int:
    """Pixels of a float band's block that are NaN or +/-Inf and not no-data (a NaN nodata value
    makes NaN no-data; a GDAL mask's zeros are no-data): excluded from every statistic, counted."""
    if data.dtype.kind != "f":
        return 0
    bad = ~np.isfinite(data)
    if not bad.any():
        return 0
    nd = info.nodata
    if nd is not None and not info.use_mask:
        bad &= ~np.isnan(data) if math.isnan(nd) else data != np.asarray(nd).astype(data.dtype)
    if info.use_mask and mask is not None:
        bad &= mask
    return int(np.count_nonzero(bad))


def _nodata_bin(info: BandInfo, hist: HistogramAccumulator) -> int | None:
    """Histogram bin of the band's nodata value, None when the value excludes no pixel."""
    nd = info.nodata
    if info.use_mask or nd is None or not math.isfinite(nd) or nd != int(nd):
        return None
    i = int(nd) - hist.offset
    return i if 0 <= i < hist.counts.size else None


@dataclass
class ScanAccumulators:
    """Every per-band accumulator of one scan, fed chunk by chunk by :meth:`add`."""

    infos: Sequence[BandInfo]
    hists: dict[int, HistogramAccumulator]
    moms: dict[int, Moments]
    edge_counts: dict[int, list[int]]  # low, high, outside the grey range (moments bands)
    noise: dict[int, NoiseAccumulator]
    rgb: tuple[int, int, int] | None
    lum: HistogramAccumulator | None
    #: pixel facts (measures/signature.py), None when ScanSettings.signature is off
    pixel_hash: sig.PixelHash | None = None
    thumb: sig.Thumbnail | None = None
    cloud: sig.CloudCounter | None = None
    #: bands whose nodata value is their lowest grey level (DN-0 saturation hidden by nodata), and
    #: per such band the pixels at that value while another band is valid (told apart), and the
    #: pixels at nodata in every band (cannot be told apart)
    hidden: tuple[int, ...] = ()
    low_told: dict[int, int] = field(default_factory=dict)
    all_nodata: int = 0
    #: per float band, its NaN / +/-Inf pixels that are not no-data (:func:`_nonfinite`)
    nonfinite: dict[int, int] = field(default_factory=dict)

    @classmethod
    def for_bands(
        cls, infos: Sequence[BandInfo], s: ScanSettings, ds: rasterio.io.DatasetReader | None = None
    ) -> ScanAccumulators:
        exact = [histogram_layout(b.dtype) is not None for b in infos]
        rgb = _rgb_bands(infos) if s.luminosity else None
        if rgb is not None and not all(exact[i - 1] for i in rgb):
            rgb = None
        hidden = tuple(
            b.index
            for b in infos
            if not b.use_mask
            and b.nodata is not None
            and b.grey.low is not None
            and b.nodata == b.grey.low
        )
        extra: dict[str, Any] = {
            "hidden": hidden,
            "low_told": dict.fromkeys(hidden, 0),
            "nonfinite": {b.index: 0 for b in infos if np.dtype(b.dtype).kind == "f"},
        }
        if s.signature and ds is not None:
            dtype = str(np.result_type(*ds.dtypes))
            extra["pixel_hash"] = sig.PixelHash(
                width=ds.width, height=ds.height, count=ds.count, dtype=dtype
            )
            extra["thumb"] = sig.Thumbnail(width=ds.width, height=ds.height, dtype=dtype)
            colour = _rgb_bands(infos)
            if colour is not None and all(infos[i - 1].grey.high for i in colour):
                r, g, b = (infos[i - 1] for i in colour)
                extra["cloud"] = sig.CloudCounter.for_image(
                    width=ds.width,
                    height=ds.height,
                    rgb=(r.index - 1, g.index - 1, b.index - 1),
                    tops=(
                        float(r.grey.high or 0),
                        float(g.grey.high or 0),
                        float(b.grey.high or 0),
                    ),
                    nodata=(
                        None if r.use_mask else r.nodata,
                        None if g.use_mask else g.nodata,
                        None if b.use_mask else b.nodata,
                    ),
                )
        return cls(
            **extra,
            infos=infos,
            hists={
                b.index: HistogramAccumulator.for_dtype(b.dtype)
                for b, ex in zip(infos, exact, strict=True)
                if ex
            },
            moms={b.index: Moments() for b, ex in zip(infos, exact, strict=True) if not ex},
            edge_counts={b.index: [0, 0, 0] for b, ex in zip(infos, exact, strict=True) if not ex},
            noise={b.index: NoiseAccumulator() for b in infos} if s.noise else {},
            rgb=rgb,
            lum=HistogramAccumulator.for_dtype(infos[rgb[0] - 1].dtype) if rgb else None,
        )

    def add(
        self,
        data: np.ndarray,
        shared_mask: np.ndarray | None,
        *,
        noise: bool,
        later: list[tuple[int, np.ndarray, np.ndarray | None]] | None = None,
        win: Window | None = None,
    ) -> None:
        """Feed one chunk (bands, rows, cols); ``noise`` False skips the noise estimators.

        Validity masks cost as much as a histogram: they are built only where a pixel can be
        invalid (a GDAL mask with zeros, or a chunk whose histogram counted the nodata value)
        and only for the accumulators that need them (moments, noise, luminosity).
        ``later`` (a list) receives (band index, band, validity) of the integer bands' noise
        instead of adding it here: their sums are exact integers, the same in any order, so
        another thread may add them (:func:`_stream`); float bands are added here, in order.
        """
        mask_valid = None
        if shared_mask is not None:
            mask_valid = shared_mask != 0
            if np.count_nonzero(mask_valid) == mask_valid.size:
                mask_valid = None
        need = set(self.moms) | (set(self.noise) if noise else set())
        valids: dict[int, np.ndarray | None] = {}
        with_nodata: dict[int, int] = {}  # bands whose nodata value occurs in this chunk: how often
        for b in self.infos:
            band = data[b.index - 1]
            hist = self.hists.get(b.index)
            if hist is None:
                valid = validity(band, b, mask_valid if b.use_mask else None)
                self._add_moments(band, b, valid)
                if b.index in self.nonfinite:
                    self.nonfinite[b.index] += _nonfinite(
                        band, b, mask_valid if b.use_mask else None
                    )
            elif b.use_mask:
                hist.add(band, mask_valid)
                valid = mask_valid
            else:
                nd = _nodata_bin(b, hist)
                before = int(hist.counts[nd]) if nd is not None else 0
                hist.add(band)  # the nodata bin is dropped once at the end (exclude_value)
                if nd is not None and int(hist.counts[nd]) != before:
                    with_nodata[b.index] = int(hist.counts[nd]) - before
                valid = (
                    validity(band, b, None) if b.index in with_nodata and b.index in need else None
                )
            valids[b.index] = valid
            if noise and b.index in self.noise:
                if later is not None and band.dtype.kind in "uib" and band.dtype.itemsize <= 2:
                    later.append((b.index, band, valid))
                else:
                    self.noise[b.index].add(band, valid)
        if self.rgb is not None and self.lum is not None:
            self._add_luminosity(data, mask_valid, valids, with_nodata)
        if with_nodata and self.hidden:
            self._add_low_nodata(data, with_nodata, valids)
        if win is not None:
            c0, r0 = int(win.col_off), int(win.row_off)
            if self.pixel_hash is not None:
                self.pixel_hash.add(data, c0, r0)
            if self.thumb is not None:
                self.thumb.add(data, c0, r0)
            if self.cloud is not None:
                self.cloud.add(data, c0, r0, shared_mask)

    def _add_low_nodata(
        self, data: np.ndarray, with_nodata: dict[int, int], valids: dict[int, np.ndarray | None]
    ) -> None:
        """DN-0 saturation under a nodata value of 0 (issue 26): a band at its nodata value where
        another band of the pixel is valid is saturated, not no-data; a pixel at nodata in every
        band cannot be told apart. Only for chunks where a band's nodata value occurs. A band's
        count at nodata is its histogram's (``with_nodata``), and a validity mask built for the
        moments is reused. The pixels at nodata in every band are found by position: the band with
        the fewest nodata pixels in the chunk is compared once, the others only at those positions
        (a chunk has few such pixels, except at an image's no-data rim); no comparison at all when a
        band has no nodata pixel in the chunk (then no pixel is at nodata in every band)."""
        bands: list[BandInfo] = []
        for b in self.infos:
            if (
                b.use_mask
                or b.nodata is None
                or (isinstance(b.nodata, float) and math.isnan(b.nodata))
                or (b.index in self.hists and b.index not in with_nodata)
            ):
                bands = []  # a band without nodata here: no pixel is nodata in every band
                break
            bands.append(b)
        # fewest first: histogram bands by their count at nodata, the others (no count) last
        bands.sort(key=lambda b: with_nodata.get(b.index, data[0].size + 1))
        where: np.ndarray | None = None
        for b in bands:
            band = data[b.index - 1].reshape(-1)
            nd = np.asarray(b.nodata).astype(data.dtype)
            if where is None:
                valid = valids.get(b.index)
                at = (
                    ~valid.reshape(-1)
                    if valid is not None and data.dtype.kind in "uib"
                    else band == nd
                )
                where = np.flatnonzero(at)
            else:
                where = where[band[where] == nd]
            if not where.size:
                break
        ambiguous = int(where.size) if where is not None else 0
        self.all_nodata += ambiguous
        for idx in self.hidden:
            if idx in with_nodata:
                self.low_told[idx] += (
                    with_nodata[idx] - ambiguous
                )  # every-band pixels are not told apart

    def finish(self, out: RasterStats, ds: rasterio.io.DatasetReader) -> None:
        """Put the pixel facts into ``out`` (after every chunk was added and the sets merged)."""
        if self.pixel_hash is not None:
            out.pixels_hash = self.pixel_hash.hexdigest()
        if self.thumb is not None:
            out.thumbnail, out.thumbnail_cell_px = self.thumb.result(), self.thumb.cell
        if self.cloud is not None:
            out.cloud_pct, out.cloud_samples = self.cloud.percent, self.cloud.valid
        if self.hidden:
            total = ds.width * ds.height
            rest = total - self.all_nodata
            out.low_nodata = {
                "bands": [str(i) for i in self.hidden],
                "pixels_nodata_in_every_band": self.all_nodata,
                "pixels_nodata_in_every_band_pct": 100.0 * self.all_nodata / total
                if total
                else None,
                "saturation_low_told_pct": {
                    str(i): (100.0 * self.low_told[i] / rest if rest else None) for i in self.hidden
                },
            }

    def _add_luminosity(
        self,
        data: np.ndarray,
        mask_valid: np.ndarray | None,
        valids: dict[int, np.ndarray | None],
        with_nodata: dict[int, int],
    ) -> None:
        """Luminosity of the pixels valid in all three colour bands."""
        assert self.rgb is not None and self.lum is not None
        rgb = [self.infos[i - 1] for i in self.rgb]
        r, g, bl = (data[i - 1] for i in self.rgb)
        first = self.rgb[0] - 1
        planes = data[first : first + 3] if self.rgb == (first + 1, first + 2, first + 3) else None
        y = luminosity_block(
            r, g, bl, data.dtype, planes=planes, out=scratch("luminosity", r.shape, data.dtype)
        )
        nodata = {b.nodata for b in rgb}
        if not with_nodata.keys() & set(self.rgb) and not any(
            b.use_mask and mask_valid is not None for b in rgb
        ):
            self.lum.add(y)  # every pixel of the chunk is valid in all three bands
            return
        low = np.iinfo(data.dtype).min if data.dtype.kind in "ui" else None
        if (
            len(nodata) == 1
            and low is not None
            and nodata == {float(low)}
            and not any(b.use_mask for b in rgb)
        ):
            # the usual case (nodata 0 in every band): a pixel is invalid where the darkest of its
            # three values is the nodata value; two np.minimum beat three masks by about 3x
            darkest = np.minimum(r, g, out=scratch("darkest", r.shape, r.dtype))
            np.minimum(darkest, bl, out=darkest)
            if low == 0:  # darkest != 0 exactly where the pixel is valid: the mask as it is
                self.lum.add_where(y, darkest)
            else:
                self.lum.add_excluding(y, np.flatnonzero(darkest == low))
            return
        v = None
        for b in rgb:
            part = valids.get(b.index)
            if part is None and (b.index in with_nodata or (b.use_mask and mask_valid is not None)):
                part = validity(data[b.index - 1], b, mask_valid if b.use_mask else None)
            if part is not None:
                v = part if v is None else v & part
        self.lum.add(y, v)

    def merge(self, other: ScanAccumulators) -> ScanAccumulators:
        """Add another set's counts and sums (same bands); integer counts merge exactly."""
        for idx, h in self.hists.items():
            h.merge(other.hists[idx])
        for idx, m in self.moms.items():
            m.merge(other.moms[idx])
            self.edge_counts[idx] = [
                a + b for a, b in zip(self.edge_counts[idx], other.edge_counts[idx], strict=True)
            ]
        for idx, nz in self.noise.items():
            nz.merge(other.noise[idx])
        if self.lum is not None and other.lum is not None:
            self.lum.merge(other.lum)
        for mine, theirs in (
            (self.pixel_hash, other.pixel_hash),
            (self.thumb, other.thumb),
            (self.cloud, other.cloud),
        ):
            if mine is not None and theirs is not None:
                mine.merge(theirs)  # type: ignore[arg-type]
        for idx in self.hidden:
            self.low_told[idx] += other.low_told.get(idx, 0)
        self.all_nodata += other.all_nodata
        for idx in self.nonfinite:
            self.nonfinite[idx] += other.nonfinite.get(idx, 0)
        return self

    def _add_moments(self, band: np.ndarray, b: BandInfo, valid: np.ndarray | None) -> None:
        self.moms[b.index].add(band, valid)
        g = b.grey
        if g.bit_depth is not None:
            vals = band if valid is None else band[valid]
            ec = self.edge_counts[b.index]
            ec[0] += int(np.count_nonzero(vals == g.low))
            ec[1] += int(np.count_nonzero(vals == g.high))
            ec[2] += int(np.count_nonzero((vals < g.low) | (vals > g.high)))
