"""Copies and near copies among the delivered images (issue 25; JRC §12.4 Table 12 "Ortho-image"). Pure.

An image is a copy of another when

* its decoded pixels are equal (the same :class:`~orthospec.measures.signature.PixelHash`), whatever
  its file, compression, tiling or georeference: one scene's pixels under another scene's
  georeference (``gdal_translate -a_ullr``) is the same picture twice; or
* its thumbnail (band mean on a coarse grid, measures/signature.py) correlates with the other's at
  ``min_correlation`` or more after aligning the best whole-cell shift (one pixel changed, a few
  DN added, the picture shifted), over at least ``min_overlap`` of the smaller grid, *and* that
  shift is not what the two georeferences predict: content that sits where its georeference says
  is the same ground seen twice (overlapping orthophotos of one strip), unless the two claim
  nearly the same ground (``same_ground`` of both footprints): then it is the same image delivered
  twice (a table padded with copies of its own images).

Flat images (thumbnail spread under ``flat_std`` DN: blank, all nodata, open water) are never
called copies: equal pixels there say nothing. Images are compared only with images of the same
band count and thumbnail cell size (the same scale). Images with byte-equal thumbnails are one
class, compared once (a table padded with many files of one picture costs one comparison, plus
the pairs it lists). Screening: each class's best ``candidates`` others by the zero-shift
correlation of an 8 x 8 block-mean thumbnail (at least ``screen``, 0.9) are then aligned and
tested; a copy shifted by more than about a quarter of the image can be missed (stated
limitation). The screen is a blocked matrix product over the distinct thumbnails (quadratic in
their number, in 512-row blocks of bounded memory); the result lists every pair, so its size
is the sum of k x k over groups of k copies.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from operator import attrgetter

import numpy as np

SAME_PIXELS = "same pixels"
NEAR_COPY = "near copy"


@dataclass(frozen=True)
class Content:
    """What one image's pixels and georeference say (from the scan and RasterFacts)."""

    id: str
    pixels_hash: str | None
    thumbnail: np.ndarray | None  # (rows, cols) float, NaN = no sample
    cell_px: int | None
    bands: int | None
    bounds: tuple[float, float, float, float] | None = None  # left, bottom, right, top
    pixel_size: tuple[float, float] | None = None
    crs: str | None = None


@dataclass(frozen=True)
class Match:
    """``other`` holds the same (or nearly the same) picture as the image it is listed under."""

    other: str
    kind: str
    correlation: float | None = None
    shift_cells: tuple[int, int] | None = None
    expected_shift_cells: tuple[float, float] | None = None

    def describe(self, cell_px: int | None = None) -> str:
        if self.kind == SAME_PIXELS:
            return f"{self.other} (equal decoded pixels)"
        assert self.correlation is not None and self.shift_cells is not None
        where = ""
        if self.shift_cells != (0, 0):
            unit = f" x {cell_px} px" if cell_px else ""
            where = f", shifted by ({self.shift_cells[0]}, {self.shift_cells[1]}) cells{unit}"
        geo = (
            "the georeferences place them on nearly the same ground"
            if self.expected_shift_cells is not None
            and _close(self.shift_cells, self.expected_shift_cells)
            else "not where their georeferences put the common ground"
        )
        return f"{self.other} (thumbnail correlation {self.correlation:.4f}{where}; {geo})"


def _close(found: tuple[int, int], expected: tuple[float, float], tol: float = 1.5) -> bool:
    return abs(found[0] - expected[0]) <= tol and abs(found[1] - expected[1]) <= tol


def _filled(stack: np.ndarray) -> np.ndarray:
    """Thumbnails (n, rows, cols) with empty cells set to the image's mean (so they add nothing)."""
    ok = np.isfinite(stack)
    if ok.all():  # integer images: every cell has samples
        return stack
    counts = ok.sum(axis=(1, 2))
    means = np.where(ok, stack, 0.0).sum(axis=(1, 2)) / np.maximum(counts, 1)
    return np.where(ok, stack, means[:, None, None])


def _unit_rows(x: np.ndarray) -> np.ndarray:
    """Each row minus its mean, divided by its norm (zero rows stay zero); float64 for the sums."""
    x = x.astype(np.float64)
    x -= x.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(x, axis=1, keepdims=True)
    np.divide(x, norm, out=x, where=norm > 0)
    x[(norm == 0).ravel()] = 0.0
    return x


def _coarse(stack: np.ndarray, n: int = 8) -> np.ndarray:
    """Unit vectors of the n x n block means of filled thumbnails (n_images, n*n)."""
    _, gh, gw = stack.shape
    rs = np.unique(np.arange(min(n, gh)) * gh // min(n, gh))
    cs = np.unique(np.arange(min(n, gw)) * gw // min(n, gw))
    blocks = np.add.reduceat(np.add.reduceat(stack, rs, axis=1), cs, axis=2)
    return _unit_rows(blocks.reshape(len(stack), -1).astype(np.float64))


def aligned_correlation(
    a: np.ndarray, b: np.ndarray, *, min_overlap: float = 0.5
) -> tuple[float, tuple[int, int]] | None:
    """Best normalised cross-correlation of two grids over whole-cell shifts, and that shift
    (dy, dx): cell (r, c) of ``b`` lies on cell (r + dy, c + dx) of ``a``. Only shifts where at
    least ``min_overlap`` of the smaller grid's valid cells overlap count (Padfield's masked NCC,
    through FFTs). None when no shift qualifies or a grid is flat."""
    ma, mb = np.isfinite(a), np.isfinite(b)
    fa, fb = np.where(ma, a, 0.0), np.where(mb, b, 0.0)
    ha, wa = a.shape
    hb, wb = b.shape
    shape = (ha + hb - 1, wa + wb - 1)

    def corr(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        # sum over (r, c) of x[r + dy, c + dx] * y[r, c], for every shift; index (dy + hb - 1, dx + wb - 1)
        fx = np.fft.rfft2(x, shape)
        fy = np.fft.rfft2(y[::-1, ::-1], shape)
        return np.fft.irfft2(fx * fy, shape)

    ma_f, mb_f = ma.astype(float), mb.astype(float)
    n = np.rint(corr(ma_f, mb_f))
    sab = corr(fa, fb)
    sa, sb = corr(fa, mb_f), corr(ma_f, fb)
    saa, sbb = corr(fa * fa, mb_f), corr(ma_f, fb * fb)
    need = max(4.0, min_overlap * min(ma.sum(), mb.sum()))
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = sab - sa * sb / n
        va = saa - sa * sa / n
        vb = sbb - sb * sb / n
        r = cov / np.sqrt(va * vb)
    tiny = 1e-9 * max(float(np.nanmax(np.abs(fa))) ** 2, 1.0) * n
    ok = (n >= need) & (va > tiny) & (vb > tiny) & np.isfinite(r)
    if not ok.any():
        return None
    r = np.where(ok, r, -np.inf)
    k = int(np.argmax(r))  # ties: the first in row-major order, deterministic
    iy, ix = np.unravel_index(k, r.shape)
    return float(min(r[iy, ix], 1.0)), (int(iy) - (hb - 1), int(ix) - (wb - 1))


def _expected_shift(a: Content, b: Content) -> tuple[float, float] | None:
    """Whole-cell shift the georeferences predict for the common ground (see aligned_correlation)."""
    if (
        a.bounds is None
        or b.bounds is None
        or a.pixel_size is None
        or b.pixel_size is None
        or a.crs is None
        or a.crs != b.crs
        or not a.cell_px
    ):
        return None
    if any(abs(p - q) > 0.01 * max(p, q) for p, q in zip(a.pixel_size, b.pixel_size, strict=True)):
        return None
    cx, cy = a.pixel_size[0] * a.cell_px, a.pixel_size[1] * a.cell_px
    return ((a.bounds[3] - b.bounds[3]) / cy, (b.bounds[0] - a.bounds[0]) / cx)


def _shared_ground(a: Content, b: Content) -> float:
    """Smaller of the two shares of each footprint that the other covers (0 when unknown)."""
    if a.bounds is None or b.bounds is None:
        return 0.0
    w = min(a.bounds[2], b.bounds[2]) - max(a.bounds[0], b.bounds[0])
    h = min(a.bounds[3], b.bounds[3]) - max(a.bounds[1], b.bounds[1])
    if w <= 0 or h <= 0:
        return 0.0
    area = w * h
    aa = (a.bounds[2] - a.bounds[0]) * (a.bounds[3] - a.bounds[1])
    ab = (b.bounds[2] - b.bounds[0]) * (b.bounds[3] - b.bounds[1])
    return min(area / aa, area / ab) if aa > 0 and ab > 0 else 0.0


def _top(sims: np.ndarray, k: int) -> np.ndarray:
    """Mask of each row's ``k`` largest values, ties taken in column order (what a stable sort of
    the row, largest first, would keep), in time linear in the row length."""
    kth = -np.partition(-sims, k - 1, axis=1)[:, k - 1 : k]
    above = sims > kth
    tied = sims == kth
    room = k - above.sum(axis=1, keepdims=True)
    return above | (tied & (np.cumsum(tied, axis=1) <= room))


def _screen(coarse: np.ndarray, screen: float, candidates: int) -> list[tuple[int, int]]:
    """Pairs (i < j) of rows whose zero-shift coarse correlation is at least ``screen``; a row with
    more such partners keeps its best ``candidates`` (a table padded with look-alikes)."""
    pairs: set[tuple[int, int]] = set()
    for start in range(0, len(coarse), 512):
        sims = coarse[start : start + 512] @ coarse.T
        rows = np.arange(sims.shape[0])
        sims[rows, rows + start] = -np.inf
        hit = sims >= screen
        crowded = np.flatnonzero(hit.sum(axis=1) > candidates)
        if crowded.size:  # many look-alikes: the best few are enough
            hit[crowded] = _top(sims[crowded], candidates)
        hit_r, hit_c = np.nonzero(hit)
        i = hit_r + start
        pairs.update(zip(np.minimum(i, hit_c).tolist(), np.maximum(i, hit_c).tolist(), strict=True))
    return sorted(pairs)


def _flipped(m: Match, other: str) -> Match:
    """``m`` seen from the other image of the pair."""
    return Match(
        other,
        m.kind,
        m.correlation,
        None if m.shift_cells is None else (-m.shift_cells[0], -m.shift_cells[1]),
        None
        if m.expected_shift_cells is None
        else (-m.expected_shift_cells[0], -m.expected_shift_cells[1]),
    )


def find_copies(
    images: Sequence[Content],
    *,
    min_correlation: float = 0.99,
    min_overlap: float = 0.5,
    same_ground: float = 0.9,
    flat_std: float = 0.5,
    screen: float = 0.9,
    candidates: int = 3,
) -> dict[str, list[Match]]:
    """image id -> the images it is a copy or near copy of (both directions listed).

    Images with the same thumbnail (bytes) form one class and are compared once, through the
    first of them: a correlation depends only on the two thumbnails, so a table padded with many
    files of the same pixels costs one comparison per distinct content plus the pairs it lists
    (the georeference test, which differs from image to image, is made for every listed pair).
    """
    out: dict[str, list[Match]] = {}

    def add(a: Content, b: Content, m: Match) -> None:
        out.setdefault(a.id, []).append(m)
        out.setdefault(b.id, []).append(_flipped(m, a.id))

    def same_pixels(a: Content, b: Content) -> bool:
        return bool(a.pixels_hash) and a.pixels_hash == b.pixels_hash

    def near(a: Content, b: Content, r: float, shift: tuple[int, int]) -> None:
        """List a and b as near copies unless their georeferences explain the match."""
        expected = _expected_shift(a, b)
        if expected is not None and _close(shift, expected) and _shared_ground(a, b) < same_ground:
            return  # the same ground where both georeferences put it: overlapping images
        add(a, b, Match(b.id, NEAR_COPY, r, shift, expected))

    # thumbnails by geometry (bands, cell size, grid): flat ones are never copies
    groups: dict[tuple[int | None, int | None, tuple[int, ...]], list[Content]] = {}
    for c in images:
        if c.thumbnail is not None:
            groups.setdefault((c.bands, c.cell_px, c.thumbnail.shape), []).append(c)
    stacks: list[tuple[list[Content], np.ndarray]] = []
    for members in groups.values():
        raw = np.stack([np.asarray(c.thumbnail) for c in members]).astype(np.float32, copy=False)
        with np.errstate(invalid="ignore"):
            spread = (
                np.nanstd(raw.reshape(len(members), -1), axis=1)
                if np.isfinite(raw).any()
                else np.zeros(len(members))
            )
        keep = np.isfinite(spread) & (spread >= flat_std)
        if keep.any():
            stacks.append(
                ([c for c, k in zip(members, keep.tolist(), strict=True) if k], raw[keep])
            )
    varied = {c.id for members, _ in stacks for c in members}
    by_hash: dict[str, list[Content]] = {}
    for c in images:
        if c.pixels_hash and c.id in varied:
            by_hash.setdefault(c.pixels_hash, []).append(c)
    for group in by_hash.values():  # one Match per image, shared by the lists that name it
        named = [Match(c.id, SAME_PIXELS) for c in group]
        for k, c in enumerate(group):
            if len(group) > 1:
                out.setdefault(c.id, []).extend(named[:k] + named[k + 1 :])
    # near copies: one representative per class of equal thumbnails, screened by the coarse
    # zero-shift correlation among the classes of one thumbnail geometry
    while stacks:  # popped, so each group's arrays are freed before the next is read
        members, raw = stacks.pop()
        classes: dict[bytes, list[int]] = {}
        for k in range(len(members)):
            classes.setdefault(raw[k].tobytes(), []).append(k)
        reps = [ks[0] for ks in classes.values()]  # in member order
        stack = _filled(raw[reps])
        del raw
        unit = _unit_rows(stack.reshape(len(reps), -1))
        class_members = list(classes.values())
        twins = [t for t, ks in enumerate(class_members) if len(ks) > 1]
        itself = np.einsum("pk,pk->p", unit[twins], unit[twins]).tolist() if twins else []
        for t, r_t in zip(twins, itself, strict=True):  # equal thumbnails: zero-shift correlation
            r = float(min(r_t, 1.0))
            if r < min_correlation:  # no variance left after filling
                continue
            same: dict[str | int, list[int]] = {}  # the class by pixel hash (listed above)
            for i in class_members[t]:
                same.setdefault(members[i].pixels_hash or i, []).append(i)
            subs = list(same.values())
            for x, si in enumerate(subs):
                for sj in subs[x + 1 :]:
                    for i in si:
                        for j in sj:
                            near(members[min(i, j)], members[max(i, j)], r, (0, 0))
        if len(reps) < 2:
            continue
        pairs = _screen(_coarse(stack), screen, candidates)
        del stack
        if not pairs:
            continue
        ij = np.array(pairs)
        zero = np.einsum("pk,pk->p", unit[ij[:, 0]], unit[ij[:, 1]])
        for (ci, cj), r0 in zip(pairs, zero.tolist(), strict=True):
            ra, rb = members[reps[ci]], members[reps[cj]]
            got: tuple[float, tuple[int, int]] | None = (float(min(r0, 1.0)), (0, 0))
            if r0 < min_correlation:  # not at zero shift: align (rare: the screen passed)
                assert ra.thumbnail is not None and rb.thumbnail is not None
                got = aligned_correlation(ra.thumbnail, rb.thumbnail, min_overlap=min_overlap)
            if got is None or got[0] < min_correlation:
                continue
            r, (dy, dx) = got
            for i in class_members[ci]:  # every pair of the two classes, oriented as listed
                for j in class_members[cj]:
                    if same_pixels(members[i], members[j]):
                        continue
                    if i < j:
                        near(members[i], members[j], r, (dy, dx))
                    else:
                        near(members[j], members[i], r, (-dy, -dx))
    return {k: sorted(v, key=attrgetter("other")) for k, v in sorted(out.items())}
