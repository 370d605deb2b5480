"""Facts of an image's decoded pixels, accumulated chunk by chunk in the one pixel scan. Pure: no I/O.

Why these three (issue 25: measured, not declared):

* :class:`PixelHash`: a content hash of the *decoded* pixels, the same whatever the compression,
  tiling, georeference or tags of the file, so one scene's pixels written again under another
  scene's georeference (``gdal_translate -a_ullr``) is recognised although every byte of the file
  differs. It is a linear hash over the canonical little-endian byte stream of each band's rows,
  read as 64-bit words: ``H = sum F(band, row) * G(word) * word (mod 2**64)`` with odd keys from
  splitmix64. Linear, so the chunks of any window layout (strips, tiles, a word split between two
  tiles) add up to the same value in any order; the keys are odd, so any single changed pixel
  changes it. Not cryptographic: it tells copies apart, it is not a signature (the file's SHA-256 is).
* :class:`Thumbnail`: the mean of all bands over a grid of at most ``THUMB_CELLS`` x
  ``THUMB_CELLS`` square cells, from a regular subsample (>= 4 samples a cell). Near copies (a
  pixel changed, the whole image shifted) correlate with their original however the file was
  rewritten; integer data sum exactly, so the thumbnail does not depend on the chunk layout.
* :class:`CloudCounter`: a per-pixel cloud test on a subsample of the colour bands (bright and
  white, JRC §6.3 "Cloud cover"): the measured cloud cover the declaration is compared with.
  Its accuracy on a labelled set (synthetic clouds on a real Landsat scene) is stated in
  ``benchmarks/cloud.py`` and held by ``tests/test_cloud_estimator.py``.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

#: Thumbnail grid: at most this many cells along the longer side.
THUMB_CELLS = 32
#: Samples per cell side at least (the subsample stride is cell // this): 2 x 2 samples a cell at least
#: (a coarse mean is all a near copy needs; more would cost a tenth of a small image's scan).
THUMB_SAMPLES = 2
#: Cloud test on about this many pixels at most (a regular subsample; the share's sampling error
#: is then below 0.1 percentage point).
CLOUD_SAMPLES = 1 << 20

_U64 = np.uint64
_SEED_ROW = _U64(0x6A09E667F3BCC908)
_SEED_WORD = _U64(0xBB67AE8584CAA73B)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    """splitmix64 of each element (uint64, wrapping): well-spread keys from indexes."""
    with np.errstate(over="ignore"):
        z = x + _U64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> _U64(30))) * _U64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> _U64(27))) * _U64(0x94D049BB133111EB)
        return (z ^ (z >> _U64(31))) | _U64(1)


class PixelHash:
    """Linear, position-keyed hash of the decoded pixels (see the module docstring)."""

    def __init__(self, *, width: int, height: int, count: int, dtype: str) -> None:
        self.width, self.height, self.count, self.dtype = width, height, count, np.dtype(dtype)
        self.value = 0

    def add(self, data: np.ndarray, col_off: int, row_off: int) -> None:
        """Add one chunk (bands, rows, cols) read at pixel (``col_off``, ``row_off``)."""
        b, h, w = data.shape
        if not (b and h and w):
            return
        le = np.ascontiguousarray(data, dtype=self.dtype.newbyteorder("<"))
        nbytes = w * le.itemsize
        start = col_off * le.itemsize
        lead = start % 8
        nwords = (lead + nbytes + 7) // 8
        raw = le.view(np.uint8).reshape(b, h, nbytes)
        if lead == 0 and nbytes % 8 == 0:
            words = raw.view("<u8")
        else:  # the chunk's rows do not start or end on a word of the canonical row: pad a copy
            buf = np.zeros((b, h, nwords * 8), dtype=np.uint8)
            buf[:, :, lead : lead + nbytes] = raw
            words = buf.view("<u8")
        first = start // 8
        g = _splitmix64(np.arange(first, first + nwords, dtype=_U64) ^ _SEED_WORD)
        per_row = np.einsum("brj,j->br", words, g)  # uint64, wraps mod 2**64
        rows = (np.arange(b, dtype=_U64)[:, None] << _U64(40)) + np.arange(
            row_off, row_off + h, dtype=_U64
        )[None, :]
        f = _splitmix64(rows ^ _SEED_ROW)
        self.value = (self.value + int(np.einsum("br,br->", per_row, f))) & 0xFFFFFFFFFFFFFFFF

    def merge(self, other: PixelHash) -> PixelHash:
        self.value = (self.value + other.value) & 0xFFFFFFFFFFFFFFFF
        return self

    def hexdigest(self) -> str:
        """32 hex digits naming the pixel content together with its type and shape."""
        text = f"px1|{self.dtype.name}|{self.count}|{self.height}|{self.width}|{self.value:016x}"
        return hashlib.sha256(text.encode()).hexdigest()[:32]


def thumbnail_geometry(
    width: int, height: int, cells: int = THUMB_CELLS
) -> tuple[int, int, int, int]:
    """(cell size px, subsample stride px, grid rows, grid cols) of an image's thumbnail."""
    cell = max(1, math.ceil(max(width, height) / cells))
    sub = max(1, cell // THUMB_SAMPLES)
    return cell, sub, math.ceil(height / cell), math.ceil(width / cell)


def _sampled(n: int, off: int, sub: int) -> tuple[int, np.ndarray]:
    """(first local index, global indexes) of the samples of a chunk axis on the global ``sub`` grid."""
    first = (-off) % sub
    return first, np.arange(off + first, off + n, sub)


def _cell_sums(
    values: np.ndarray, rows: np.ndarray, cols: np.ndarray, cell: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sums of ``values`` (sampled rows x cols) per cell: (cell rows, cell cols, sums)."""
    cr, cc = rows // cell, cols // cell
    sr = np.flatnonzero(np.r_[True, cr[1:] != cr[:-1]])
    sc = np.flatnonzero(np.r_[True, cc[1:] != cc[:-1]])
    wide = np.float64 if values.dtype.kind == "f" else np.int64
    part = np.add.reduceat(np.add.reduceat(values, sr, axis=0, dtype=wide), sc, axis=1)
    return cr[sr], cc[sc], part


class Thumbnail:
    """Mean of all bands per cell of a coarse grid, from a regular subsample (see the module docstring)."""

    def __init__(self, *, width: int, height: int, dtype: str, cells: int = THUMB_CELLS) -> None:
        self.cell, self.sub, gh, gw = thumbnail_geometry(width, height, cells)
        self.exact = np.dtype(dtype).kind in "uib"
        # int64 sums for integer pixels (exact), float64 otherwise
        self.sums: np.ndarray = np.zeros((gh, gw), dtype=np.int64 if self.exact else np.float64)
        self.counts: np.ndarray = np.zeros((gh, gw), dtype=np.int64)

    def add(self, data: np.ndarray, col_off: int, row_off: int) -> None:
        b, h, w = data.shape
        r0, rows = _sampled(h, row_off, self.sub)
        c0, cols = _sampled(w, col_off, self.sub)
        if not (rows.size and cols.size):
            return
        samp = data[:, r0 :: self.sub, c0 :: self.sub]
        if self.exact:
            narrow = (
                samp.dtype.kind in "ub" and samp.dtype.itemsize <= 2
            )  # unsigned: uint32 cannot wrap
            values = samp.sum(axis=0, dtype=np.uint32 if narrow else np.int64)
            n = None
        else:
            finite = np.isfinite(samp)
            values = np.where(finite, samp, 0).sum(axis=0, dtype=np.float64)
            n = finite.sum(axis=0, dtype=np.int64)
        cr, cc, part = _cell_sums(values, rows, cols, self.cell)
        self.sums[np.ix_(cr, cc)] += part
        if (
            self.exact
        ):  # every sample counts: samples per cell = sampled rows x sampled cols x bands
            per_r = np.bincount(rows // self.cell - cr[0])
            per_c = np.bincount(cols // self.cell - cc[0])
            self.counts[np.ix_(cr, cc)] += np.outer(per_r[per_r > 0], per_c[per_c > 0]) * b
        else:
            assert n is not None  # counted with the float samples above
            self.counts[np.ix_(cr, cc)] += _cell_sums(n, rows, cols, self.cell)[2]

    def merge(self, other: Thumbnail) -> Thumbnail:
        self.sums += other.sums
        self.counts += other.counts
        return self

    def result(self) -> list[list[float | None]]:
        """Cell means (rounded to 1/1000 DN, so the result does not depend on float summation
        order), None for a cell without a sample."""
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.round(self.sums / self.counts, 3)
        if np.isfinite(mean).all():
            return mean.tolist()
        return [[None if not math.isfinite(v) else float(v) for v in row] for row in mean.tolist()]


#: Cloud test thresholds, on DN scaled to [0, 1] by each band's grey range: a pixel is cloud when
#: the mean of its red, green and blue values is at least ``CLOUD_BRIGHT`` and their spread
#: (max - min) is at most ``CLOUD_WHITE`` of that mean (clouds are bright and white; bare soil,
#: roofs and water are darker or coloured). Chosen on the labelled set of benchmarks/cloud.py.
CLOUD_BRIGHT = 0.70
CLOUD_WHITE = 0.05
#: Share of the labelled set's cloud pixels the test finds (its recall, benchmarks/cloud.py: 0.65-0.88,
#: thin cloud edges over dark ground are missed) while it calls no clear pixel cloud (precision 1.00).
#: The cover is the count divided by it, so the estimate is not biased low: an image whose cloud is
#: under-counted would pass a cap it fails.
CLOUD_RECALL = 0.78


def cloud_mask(r: np.ndarray, g: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The per-pixel cloud test on red, green and blue scaled to [0, 1] (see :data:`CLOUD_BRIGHT`)."""
    bright = (r + g + b) / np.float32(3.0)
    spread = np.maximum(np.maximum(r, g), b) - np.minimum(np.minimum(r, g), b)
    return (bright >= np.float32(CLOUD_BRIGHT)) & (spread <= np.float32(CLOUD_WHITE) * bright)


@dataclass
class CloudCounter:
    """Cloudy and valid samples of an image (see :data:`CLOUD_BRIGHT`)."""

    rgb: tuple[int, int, int]  # 0-based band indexes in the chunk
    scale: tuple[float, float, float]  # 1 / grey-range top of each band
    nodata: tuple[float | None, float | None, float | None]
    sub: int
    cloudy: int = 0
    valid: int = 0

    @classmethod
    def for_image(
        cls,
        *,
        width: int,
        height: int,
        rgb: tuple[int, int, int],
        tops: tuple[float, float, float],
        nodata: tuple[float | None, float | None, float | None],
    ) -> CloudCounter:
        sub = max(1, math.ceil(math.sqrt(width * height / CLOUD_SAMPLES)))
        scale = (1.0 / tops[0], 1.0 / tops[1], 1.0 / tops[2])
        return cls(rgb=rgb, scale=scale, nodata=nodata, sub=sub)

    def add(
        self, data: np.ndarray, col_off: int, row_off: int, mask: np.ndarray | None = None
    ) -> None:
        _b, h, w = data.shape
        r0, rows = _sampled(h, row_off, self.sub)
        c0, cols = _sampled(w, col_off, self.sub)
        if not (rows.size and cols.size):
            return
        if data.dtype.kind == "u" and data.dtype.itemsize <= 2 and len(set(self.scale)) == 1:
            self._add_integers(data, r0, c0, mask)
            return
        planes = []
        ok = None if mask is None else mask[r0 :: self.sub, c0 :: self.sub] != 0
        for idx, scale, nd in zip(self.rgb, self.scale, self.nodata, strict=True):
            band = data[idx, r0 :: self.sub, c0 :: self.sub]
            v = band.astype(np.float32) * np.float32(scale)
            bad = ~np.isfinite(v)
            if nd is not None and math.isfinite(nd):
                bad |= band == nd
            ok = ~bad if ok is None else ok & ~bad
            planes.append(v)
        cloud = cloud_mask(*planes)
        assert ok is not None
        self.valid += int(np.count_nonzero(ok))
        self.cloudy += int(np.count_nonzero(cloud & ok))

    def _add_integers(self, data: np.ndarray, r0: int, c0: int, mask: np.ndarray | None) -> None:
        """:func:`cloud_mask` in integers (the three bands share one grey range): bright when
        r + g + b >= 3 x CLOUD_BRIGHT x top, white when (max - min) x 3 / CLOUD_WHITE <= r + g + b;
        the same decisions as the float test (the thresholds are whole numbers here), at a third of
        the cost."""
        r, g, b = (data[i, r0 :: self.sub, c0 :: self.sub] for i in self.rgb)
        wide = np.uint32 if data.dtype.itemsize == 2 else np.uint16
        total: np.ndarray = r.astype(wide)
        total += g
        total += b
        spread = np.maximum(r, g)
        np.maximum(spread, b, out=spread)
        low = np.minimum(r, g)
        np.minimum(low, b, out=low)
        spread -= low
        top = 1.0 / self.scale[0]
        bright = math.ceil(3.0 * CLOUD_BRIGHT * top - 1e-9)
        # a grey range beyond the data type: no pixel is bright
        cloud = np.zeros(total.shape, dtype=bool) if bright > np.iinfo(wide).max else total >= wide(bright)
        scaled = spread.astype(wide)
        scaled *= wide(round(3.0 / CLOUD_WHITE))
        cloud &= scaled <= total
        ok = None if mask is None else mask[r0 :: self.sub, c0 :: self.sub] != 0
        for plane, nd in zip((r, g, b), self.nodata, strict=True):
            if (
                nd is not None
                and math.isfinite(nd)
                and float(nd).is_integer()
                and 0 <= nd <= np.iinfo(plane.dtype).max
            ):
                bad = plane == int(nd)
                ok = ~bad if ok is None else ok & ~bad
        if ok is None:
            self.valid += int(cloud.size)
            self.cloudy += int(np.count_nonzero(cloud))
        else:
            self.valid += int(np.count_nonzero(ok))
            self.cloudy += int(np.count_nonzero(cloud & ok))

    def merge(self, other: CloudCounter) -> CloudCounter:
        self.cloudy += other.cloudy
        self.valid += other.valid
        return self

    @property
    def percent(self) -> float | None:
        """Estimated cloud cover, % of the valid pixels (the count corrected by :data:`CLOUD_RECALL`)."""
        return (
            None if not self.valid else min(100.0, 100.0 * self.cloudy / self.valid / CLOUD_RECALL)
        )
