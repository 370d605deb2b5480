"""The cloud estimator's accuracy on a labelled set (issue 25 item 8): synthetic clouds on the real Landsat
extract in ../shared/data/real, measured through the scan `check` runs (benchmarks/cloud.py prints the
same table). The truth is the synthetic cloud mask (opacity >= 0.5) over the pixels whose truth is
known (the scene's own clouds and bright, white surfaces are left out: measures/cloudsim.py)."""

from __future__ import annotations

import statistics
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "data" / "real" / "RGB.byte.tif"


@pytest.fixture(scope="module")
def scores(tmp_path_factory: pytest.TempPathFactory) -> list:
    if not REAL.is_file():
        pytest.skip("../shared/data/real is not beside the checkout")
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from cloud import labelled_scores
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return labelled_scores(REAL, seeds=3, workdir=tmp_path_factory.mktemp("clouds"))


def test_stated_accuracy_on_the_labelled_set(scores: list) -> None:
    errors = [s.error_pct for _, _, s in scores]
    upto20 = [abs(s.error_pct) for c, _, s in scores if c <= 0.20]
    print(
        f"\ncloud estimator on {len(scores)} labelled scenes: mean |error| {statistics.fmean(map(abs, errors)):.2f} "
        f"pp, largest {max(map(abs, errors)):.2f} pp, bias {statistics.fmean(errors):+.2f} pp; up to 20 % cover "
        f"largest {max(upto20):.2f} pp; pixel accuracy {statistics.fmean(s.accuracy for _, _, s in scores):.4f}"
    )
    assert max(upto20) <= 1.5  # the margin the profile's notes state
    assert max(abs(e) for e in errors) <= 8.0  # at 50 % cover
    assert abs(statistics.fmean(errors)) <= 1.5  # not biased low: an under-count would pass a cap
    assert all(
        s.estimated_pct == 0.0 for c, _, s in scores if c == 0.0
    )  # no false cloud on clear ground
    assert min(s.precision for c, _, s in scores if c > 0) >= 0.99
    assert statistics.fmean(s.accuracy for _, _, s in scores) >= 0.95


def test_measured_cover_grows_with_the_true_cover(scores: list) -> None:
    by_cover: dict[float, list[float]] = {}
    for cover, _, s in scores:
        by_cover.setdefault(cover, []).append(s.estimated_pct)
    means = [statistics.fmean(v) for _, v in sorted(by_cover.items())]
    assert means == sorted(means) and means[-1] > 40.0
