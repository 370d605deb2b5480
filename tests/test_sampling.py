"""External-QC sampling: size, reproducibility, spread, tags, problem batches, redelivery."""

from __future__ import annotations

import numpy as np
import pytest

from orthospec.errors import MeasureError
from orthospec.measures.sampling import select_sample


def _images(nx=20, ny=10):
    gx, gy = np.meshgrid(np.arange(nx) * 1000.0, np.arange(ny) * 800.0)
    ids = [f"IMG_{i:04d}" for i in range(nx * ny)]
    return ids, gx.ravel(), gy.ravel()


def test_size_and_reproducibility():
    ids, x, y = _images()
    a = select_sample(ids, x, y, seed=42)
    b = select_sample(ids, x, y, seed=42)
    assert a == b
    assert len(a.ids) == a.target == 20  # 10% of 200
    assert set(a.reasons.values()) <= {"systematic", "random"}
    assert "random" in a.reasons.values() and "systematic" in a.reasons.values()
    assert select_sample(ids, x, y, seed=43).ids != a.ids


def test_independent_of_input_order():
    ids, x, y = _images()
    perm = np.random.default_rng(0).permutation(len(ids))
    a = select_sample(ids, x, y, seed=7)
    b = select_sample([ids[i] for i in perm], x[perm], y[perm], seed=7)
    assert a.ids == b.ids


def test_minimum_and_fraction():
    ids, x, y = _images(5, 4)
    s = select_sample(ids, x, y, seed=1, fraction=0.05, minimum=3)
    assert len(s.ids) == 3  # ceil(0.05*20) = 1 < minimum 3
    with pytest.raises(MeasureError, match="fraction"):
        select_sample(ids, x, y, seed=1, fraction=0.0)


def test_systematic_part_is_spread_over_all_quadrants():
    ids, x, y = _images()
    pos = {i: (xi, yi) for i, xi, yi in zip(ids, x, y, strict=True)}
    for seed in range(10):
        s = select_sample(ids, x, y, seed=seed, random_share=0.0)
        pts = np.array([pos[i] for i in s.ids])
        cx, cy = (x.min() + x.max()) / 2, (y.min() + y.max()) / 2
        quads = {(px >= cx, py >= cy) for px, py in pts}
        assert len(quads) == 4, seed


def test_every_tag_and_problem_batch_included():
    ids, x, y = _images()
    tags = np.array(["flat"] * 200, dtype=object)
    tags[137] = "mountain"
    tags[5] = "forest"
    batches = np.array([f"R{i // 50}" for i in range(200)], dtype=object)
    s = select_sample(ids, x, y, seed=3, tags=tags, batches=batches, problem_batches={"R3"})
    assert ids[137] in s.ids and s.reasons[ids[137]] == "tag mountain"
    assert ids[5] in s.ids
    assert all(ids[i] in s.ids for i in range(150, 200))
    assert s.reasons[ids[160]] == "problem batch R3"
    assert len(s.ids) >= 50  # the problem batch alone exceeds the 10% target
    with pytest.raises(MeasureError, match="batch per item"):
        select_sample(ids, x, y, seed=3, problem_batches={"R3"})


def test_redelivery_draws_a_new_reproducible_sample():
    ids, x, y = _images()
    first = select_sample(ids, x, y, seed=11, round=0)
    second = select_sample(ids, x, y, seed=11, round=1)
    assert second.ids != first.ids
    assert second == select_sample(ids, x, y, seed=11, round=1)
    # overlap is allowed (not excluded): over many rounds some earlier item recurs
    overlaps = [set(select_sample(ids, x, y, seed=11, round=r).ids) & set(first.ids)
                for r in range(1, 8)]
    assert any(overlaps)


@pytest.mark.parametrize(
    ("ids", "x", "y", "match"),
    [
        ([], [], [], "no items"),
        (["a", "a"], [0, 1], [0, 1], "duplicate.*a"),
        (["a", "b"], [0, np.nan], [0, 1], "non-finite.*b"),
        (["a", "b"], [0], [0, 1], "one value per item"),
    ],
)
def test_bad_input(ids, x, y, match):
    with pytest.raises(MeasureError, match=match):
        select_sample(ids, x, y, seed=0)
