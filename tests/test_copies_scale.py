"""find_copies (measures/copies.py) at scale: images with equal thumbnails are compared once.

The expected results come from a quadratic reference written here from the module docstring's
definition (every pair; equal pixel hashes; else the Pearson correlation of the two thumbnails at
zero shift, or the best whole-cell shift, against the shift the two georeferences predict), not
from find_copies' own output.
"""

from __future__ import annotations

import time
from itertools import combinations

import numpy as np
import pytest

from orthospec.measures.copies import (
    NEAR_COPY,
    SAME_PIXELS,
    Content,
    _top,
    aligned_correlation,
    find_copies,
)

CELL, PX = 4, 0.25  # thumbnail cell (pixels) and pixel size (m): one cell is 1 m


def _picture(seed: int, n: int = 32, sigma: float = 2.0) -> np.ndarray:
    from scipy.ndimage import gaussian_filter

    return gaussian_filter(np.random.default_rng(seed).standard_normal((n, n)), sigma) * 400 + 120


def _content(name: str, thumb: np.ndarray, left: float, top: float, h: str | None) -> Content:
    size = thumb.shape[0] * CELL * PX
    bounds = (left, top - size, left + size, top)
    return Content(name, h, thumb, CELL, 3, bounds, (PX, PX), "EPSG:25832")


# --------------------------------------------------------------------------- the reference


def _filled(t: np.ndarray) -> np.ndarray:
    t = t.astype(np.float64)
    return np.where(np.isfinite(t), t, np.nanmean(t))


def _varied(c: Content, flat_std: float) -> bool:
    t = c.thumbnail
    return t is not None and bool(np.isfinite(t).any()) and float(np.nanstd(t)) >= flat_std


def reference(
    images: list[Content],
    *,
    min_correlation: float = 0.99,
    min_overlap: float = 0.5,
    same_ground: float = 0.9,
    flat_std: float = 0.5,
) -> dict[str, set[tuple[str, str, tuple[int, int] | None]]]:
    """Every pair tested; image id -> {(other, kind, shift)}."""
    out: dict[str, set[tuple[str, str, tuple[int, int] | None]]] = {}
    for a, b in combinations(images, 2):
        assert a.thumbnail is not None and b.thumbnail is not None
        if not (_varied(a, flat_std) and _varied(b, flat_std)):
            continue
        if (a.bands, a.cell_px, a.thumbnail.shape) != (b.bands, b.cell_px, b.thumbnail.shape):
            continue
        if a.pixels_hash and a.pixels_hash == b.pixels_hash:
            out.setdefault(a.id, set()).add((b.id, SAME_PIXELS, None))
            out.setdefault(b.id, set()).add((a.id, SAME_PIXELS, None))
            continue
        r0 = float(np.corrcoef(_filled(a.thumbnail).ravel(), _filled(b.thumbnail).ravel())[0, 1])
        got = (r0, (0, 0)) if r0 >= min_correlation else None
        if got is None:
            got = aligned_correlation(a.thumbnail, b.thumbnail, min_overlap=min_overlap)
        if got is None or got[0] < min_correlation:
            continue
        shift = got[1]
        assert a.bounds is not None and b.bounds is not None
        # where the georeferences put b's top-left cell on a's grid (cells; rows down, columns right)
        expected = (
            (a.bounds[3] - b.bounds[3]) / (PX * CELL),
            (b.bounds[0] - a.bounds[0]) / (PX * CELL),
        )
        w = min(a.bounds[2], b.bounds[2]) - max(a.bounds[0], b.bounds[0])
        h = min(a.bounds[3], b.bounds[3]) - max(a.bounds[1], b.bounds[1])
        area = (a.bounds[2] - a.bounds[0]) * (a.bounds[3] - a.bounds[1])  # equal sizes here
        shared = max(w, 0.0) * max(h, 0.0) / area
        where_mapped = abs(shift[0] - expected[0]) <= 1.5 and abs(shift[1] - expected[1]) <= 1.5
        if where_mapped and shared < same_ground:
            continue  # overlapping orthophotos of one strip
        out.setdefault(a.id, set()).add((b.id, NEAR_COPY, shift))
        out.setdefault(b.id, set()).add((a.id, NEAR_COPY, (-shift[0], -shift[1])))
    return out


def _as_sets(got: dict) -> dict[str, set[tuple[str, str, tuple[int, int] | None]]]:
    return {k: {(m.other, m.kind, m.shift_cells) for m in v} for k, v in got.items()}


def _small_case() -> list[Content]:
    """Groups of equal pixels larger than the screen's ``candidates`` (3), their near and shifted
    copies, equal thumbnails under different hashes, an overlap the georeferences explain, flat
    images, unrelated pictures; nothing overlaps on the ground unless said."""
    imgs: list[Content] = []
    for g in range(3):
        pic = _picture(g)
        for k in range(5):  # five files of the same pixels, far apart
            imgs.append(_content(f"g{g}-{k}", pic, 100_000 * g + 1_000 * k, 5_000_000, f"h{g}"))
        changed = pic.copy()
        changed[10, 10] += 40  # one cell differs
        imgs.append(_content(f"g{g}-near", changed, 100_000 * g + 50_000, 5_000_000, f"n{g}"))
    big = _picture(7, 40, sigma=6.0)
    a, shifted = big[:32, :32], big[2:34, 3:35]
    imgs.append(_content("s-a", a, 400_000, 5_000_000, "sa"))
    imgs.append(_content("s-far", shifted, 410_000, 5_000_000, "sf"))  # shifted, elsewhere: copy
    # the same ground where both maps put it (2 cells down, 3 right): overlapping, not a copy
    imgs.append(_content("s-overlap", shifted, 400_003, 4_999_998, "so"))
    twin = _picture(8)
    imgs.append(_content("t-1", twin, 500_000, 5_000_000, "t1"))
    # equal thumbnails under other pixel hashes: far away, and on t-1's own ground
    imgs.append(_content("t-2", twin.copy(), 510_000, 5_000_000, "t2"))
    imgs.append(_content("t-3", twin.copy(), 500_000, 5_000_000, "t3"))
    flat = np.full((32, 32), 9.0)
    imgs += [_content(f"flat{k}", flat, 600_000 + 1_000 * k, 5_000_000, "flat") for k in range(4)]
    imgs += [
        _content(f"other{k}", _picture(20 + k), 700_000 + 1_000 * k, 5_000_000, None)
        for k in range(4)
    ]
    return imgs


def test_find_copies_equals_the_quadratic_reference() -> None:
    imgs = _small_case()
    want = reference(imgs)
    got = find_copies(imgs)
    assert _as_sets(got) == want
    # the planted facts, read off the reference (so the reference itself is checked too)
    assert {o for o, k, _ in want["g0-0"] if k == SAME_PIXELS} == {"g0-1", "g0-2", "g0-3", "g0-4"}
    assert {o for o, k, _ in want["g1-near"]} == {f"g1-{k}" for k in range(5)}
    assert ("s-far", NEAR_COPY, (2, 3)) in want["s-a"] and "s-overlap" not in {
        o for o, _, _ in want["s-a"]
    }
    assert {o for o, _, _ in want["t-1"]} == {"t-2", "t-3"}
    assert not any(k.startswith(("flat", "other")) for k in want)
    # correlations: the reference's Pearson coefficient
    r = {(k, m.other): m.correlation for k, v in got.items() for m in v if m.kind == NEAR_COPY}
    want_r = np.corrcoef(
        _picture(2).ravel(), imgs[[c.id for c in imgs].index("g2-near")].thumbnail.ravel()
    )
    assert r[("g2-3", "g2-near")] == pytest.approx(float(want_r[0, 1]), abs=1e-9)


def test_every_file_of_a_padded_group_is_listed() -> None:
    """Five files of one picture and a near copy of it: the near copy is listed with all five (a
    per-image screen of the best three look-alikes listed it with three at most)."""
    got = _as_sets(find_copies(_small_case()))
    assert {o for o, k, _ in got["g0-near"] if k == NEAR_COPY} == {f"g0-{k}" for k in range(5)}


@pytest.mark.parametrize("seed", range(5))
def test_top_keeps_what_a_stable_sort_keeps(seed: int) -> None:
    rng = np.random.default_rng(seed)
    sims = rng.integers(0, 6, size=(40, 30)).astype(float)  # many ties
    for k in (1, 3, 7):
        want = np.zeros_like(sims, dtype=bool)
        top = np.argsort(-sims, axis=1, kind="stable")[:, :k]
        np.put_along_axis(want, top, True, axis=1)
        assert (_top(sims, k) == want).all()


def test_ten_thousand_images_in_a_hundred_groups_of_equal_pixels() -> None:
    """10^4 images, 100 pictures delivered 100 times each (distinct files, equal pixels), plus a
    near copy of each picture: seconds, and every image lists its 99 twins."""
    groups, size = 100, 100
    imgs: list[Content] = []
    for g in range(groups):
        pic = _picture(1000 + g)
        for k in range(size):
            imgs.append(
                _content(f"g{g:03d}-{k:03d}", pic, 2_000.0 * (g * size + k), 5_000_000, f"h{g}")
            )
    for g in range(groups):
        near = _picture(1000 + g)
        near[5, 5] += 30
        imgs.append(_content(f"n{g:03d}", near, 2_000.0 * (groups * size + g), 5_000_000, f"n{g}"))
    t0 = time.perf_counter()
    got = find_copies(imgs)
    took = time.perf_counter() - t0
    assert took < 30, f"find_copies took {took:.1f} s on 10^4 images"
    first = got["g042-007"]
    assert sum(m.kind == SAME_PIXELS for m in first) == size - 1
    assert [m.other for m in first if m.kind == NEAR_COPY] == ["n042"]
    assert {m.other for m in got["n042"]} == {f"g042-{k:03d}" for k in range(size)}
    assert len(got) == groups * (size + 1)
