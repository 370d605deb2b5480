"""Figures and report tables stay bounded at any number of check points (issue 14), and say so.

50,000 synthetic check points go straight into the figure functions; what the SVG draws is read
back (marks, their colours and positions, bar heights) and compared with counts made here from
the inputs, never with the figure code's own numbers.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
import pytest

from orthospec.figures.accuracy import (
    MAX_BINS,
    MAX_FLAGGED_LABELS,
    MAX_MARKS,
    MIN_SAMPLE,
    _uncrowded,
    checkpoint_map_svg,
    quadrant_distribution_svg,
    residual_histograms_svg,
)
from orthospec.reports.fetcher import data_uri
from orthospec.reports.html import ReportOptions, report_context

SVG = "{http://www.w3.org/2000/svg}"
RED = "#d62728"  # tab:red
N = 50_000


def _points(n: int = N, seed: int = 7) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    x = rng.uniform(500_000, 506_000, n)
    y = rng.uniform(5_400_000, 5_407_000, n)
    dx, dy = rng.normal(0, 0.15, n), rng.normal(0, 0.15, n)
    ids = [f"P{i:06d}" for i in rng.permutation(n)]  # ids unrelated to the input order
    return {"x": x, "y": y, "dx": dx, "dy": dy, "ids": ids}


def _group(svg: str, gid: str) -> ET.Element:
    root = ET.fromstring(svg)
    found = [el for el in root.iter(f"{SVG}g") if el.get("id") == gid]
    assert len(found) == 1, gid
    return found[0]


def _marks(svg: str) -> list[tuple[float, float, bool]]:
    """(x, y, red?) of every check point mark drawn, in SVG pixels."""
    return [(float(u.get("x")), float(u.get("y")), RED in (u.get("style") or ""))
            for u in _group(svg, "checkpoints").iter(f"{SVG}use")]


def _note(svg: str) -> str:
    return "".join(_group(svg, "sample-note").itertext()).strip()


def _fit(data: np.ndarray, pixels: np.ndarray) -> tuple[float, float]:
    """Axis mapping data -> pixels (a*v + b) from two far-apart points."""
    i, j = int(np.argmin(data)), int(np.argmax(data))
    a = (pixels[j] - pixels[i]) / (data[j] - data[i])
    return float(a), float(pixels[i] - a * data[i])


@pytest.fixture(scope="module")
def big_map() -> dict[str, Any]:
    p = _points()
    ids = p["ids"]
    dr = np.hypot(p["dx"], p["dy"])
    flagged = [ids[i] for i in np.flatnonzero(dr > 0.5)]  # blunder candidates, ~0.4 %
    excluded = [ids[i] for i in range(0, N, 9973)][:5]  # exclusion requests: drawn, not red
    kw = {
        "ids": ids,
        "flagged": flagged,
        "always": excluded,
        "gcp_x": [500_100.0],
        "gcp_y": [5_400_100.0],
    }
    svg = checkpoint_map_svg(p["x"], p["y"], p["dx"], p["dy"], **kw)
    return {**p, "flagged": flagged, "excluded": excluded, "kw": kw, "svg": svg}


def test_map_draws_at_most_the_cap_and_every_flagged_point_in_red(big_map):
    marks = _marks(big_map["svg"])
    flagged = big_map["flagged"]
    assert 0 < len(flagged) < MAX_MARKS // 2  # the case the cap is about: a few flagged among many
    assert len(marks) <= MAX_MARKS
    assert sum(red for *_, red in marks) == len(flagged)
    assert len(marks) >= MAX_MARKS // 2  # a sample, not a token handful


def _mapping(m: dict[str, Any]) -> tuple[float, float, float, float]:
    """Data -> SVG pixel mapping (ax, bx, ay, by) read off the red marks: sorted by x, the red
    marks and the flagged points pair up (the mapping is monotonic)."""
    pos = {v: i for i, v in enumerate(m["ids"])}
    fi = np.array([pos[f] for f in m["flagged"]])
    fx, fy = m["x"][fi], m["y"][fi]
    red = np.array([(mx, my) for mx, my, r in _marks(m["svg"]) if r])
    rx = red[np.argsort(red[:, 0])]
    order = np.argsort(fx)
    ax_, bx = _fit(fx[order], rx[:, 0])
    ay, by = _fit(fy[order], rx[:, 1])
    # every pair must follow the same mapping: the red marks are exactly the flagged points
    np.testing.assert_allclose(rx[:, 0], ax_ * fx[order] + bx, atol=0.01)
    np.testing.assert_allclose(rx[:, 1], ay * fy[order] + by, atol=0.01)
    return ax_, bx, ay, by


def test_map_draws_flagged_and_excluded_points_where_they_are(big_map):
    """The red marks are the flagged points (an axis-aligned affine image of their coordinates);
    every excluded point has a mark at its position under the same mapping."""
    ax_, bx, ay, by = _mapping(big_map)
    assert ay < 0 < ax_  # northing upwards
    pos = {v: i for i, v in enumerate(big_map["ids"])}
    all_marks = np.array([(mx, my) for mx, my, _ in _marks(big_map["svg"])])
    for e in big_map["excluded"]:
        want = np.array([ax_ * big_map["x"][pos[e]] + bx, ay * big_map["y"][pos[e]] + by])
        assert np.min(np.hypot(*(all_marks - want).T)) < 0.01, e


def test_map_states_its_counts(big_map):
    marks = _marks(big_map["svg"])
    must = len(set(big_map["flagged"]) | set(big_map["excluded"]))
    m = re.fullmatch(
        r"([\d,]+) of ([\d,]+) points drawn: all ([\d,]+) flagged or excluded, 1 in ([\d,]+) of the others "
        r"\(an even spatial sample\)",
        _note(big_map["svg"]),
    )
    assert m, _note(big_map["svg"])
    drawn, total, k, step = (int(g.replace(",", "")) for g in m.groups())
    assert (drawn, total, k) == (len(marks), N, must)
    assert drawn - must == math.ceil((N - must) / step)  # every step-th of the others


def test_map_sample_is_evenly_spread(big_map):
    """Each cell of a 4 x 4 grid over the block holds about the share of the drawn (unflagged)
    points that it holds of all points."""
    ax_, bx, ay, by = _mapping(big_map)
    drawn = np.array(
        [((mx - bx) / ax_, (my - by) / ay) for mx, my, red in _marks(big_map["svg"]) if not red]
    )
    x, y = big_map["x"], big_map["y"]
    ex, ey = np.linspace(x.min(), x.max(), 5), np.linspace(y.min(), y.max(), 5)
    everyone, _, _ = np.histogram2d(x, y, bins=[ex, ey])
    sample, _, _ = np.histogram2d(drawn[:, 0], drawn[:, 1], bins=[ex, ey])
    # stratified along a Z-order curve: within a point or two per cell, far below the +-7 points
    # (+-0.008) a random sample of this size would scatter by
    np.testing.assert_allclose(sample / sample.sum(), everyone / everyone.sum(), atol=0.003)


def test_map_is_deterministic_and_independent_of_input_order(big_map):
    p = big_map
    again = checkpoint_map_svg(p["x"], p["y"], p["dx"], p["dy"], **p["kw"])
    assert again == p["svg"]
    perm = np.random.default_rng(3).permutation(N)
    kw = {**p["kw"], "ids": [p["ids"][i] for i in perm]}
    shuffled = checkpoint_map_svg(p["x"][perm], p["y"][perm], p["dx"][perm], p["dy"][perm], **kw)
    assert shuffled == p["svg"]  # drawn in curve order, ties by point id


def test_small_map_draws_every_point_and_no_note():
    p = _points(300)
    svg = checkpoint_map_svg(p["x"], p["y"], p["dx"], p["dy"], ids=p["ids"], flagged=p["ids"][:3])
    assert len(_marks(svg)) == 300
    assert "sample-note" not in svg


def test_quadrant_figure_is_capped_and_says_so():
    p = _points()
    svg = quadrant_distribution_svg(
        p["x"],
        p["y"],
        centre=(503_000.0, 5_403_500.0),
        ids=p["ids"],
        shares={"NE": 0.25, "NW": 0.25, "SW": 0.25, "SE": 0.25},
    )
    marks = _marks(svg)
    assert len(marks) <= MAX_MARKS
    m = re.match(r"([\d,]+) of ([\d,]+) points drawn", _note(svg))
    assert m and int(m[1].replace(",", "")) == len(marks) and int(m[2].replace(",", "")) == N
    assert svg == quadrant_distribution_svg(
        p["x"],
        p["y"],
        centre=(503_000.0, 5_403_500.0),
        ids=p["ids"],
        shares={"NE": 0.25, "NW": 0.25, "SW": 0.25, "SE": 0.25},
    )


def _bar_heights(svg: str, gid: str) -> np.ndarray:
    root = ET.fromstring(svg)
    out = []
    for g in root.iter(f"{SVG}g"):
        if g.get("id") == gid:
            ys = [float(v) for v in re.findall(r"[-\d.]+ ([-\d.]+)", g.find(f"{SVG}path").get("d"))]
            out.append(max(ys) - min(ys))
    return np.array(out)


def test_histogram_bins_every_value_in_at_most_max_bins():
    """One far outlier makes numpy's 'auto' bins hundreds (2 sqrt(n)); the bars are capped and
    their heights are the counts of every value (np.histogram over all of them)."""
    p = _points()
    dx = p["dx"].copy()
    dx[123] = 400.0  # a blunder 400 m out
    svg = residual_histograms_svg(dx, p["dy"])
    assert np.histogram_bin_edges(dx, bins="auto").size - 1 > MAX_BINS
    h = _bar_heights(svg, "hist-dx-bar")
    counts, _ = np.histogram(dx, bins=MAX_BINS)
    assert h.size == MAX_BINS
    scale = h.max() / counts.max()
    np.testing.assert_allclose(h, counts * scale, atol=0.01)
    # dy has no outlier: numpy's own 'auto' bins, all values
    hy = _bar_heights(svg, "hist-dy-bar")
    cy, _ = np.histogram(p["dy"], bins="auto")
    assert hy.size == cy.size
    np.testing.assert_allclose(hy, cy * (hy.max() / cy.max()), atol=0.01)


def _doc(n: int, n_fail: int) -> dict[str, Any]:
    """A QCR document holding one block's point table of ``n`` points (no records)."""
    p = _points(n, seed=11)
    status = ["fail" if i % (n // n_fail) == 0 else "pass" for i in range(n)]
    decision = ["candidate_kept" if s == "fail" else "kept" for s in status]
    decision[1] = "excluded"  # an exclusion request that is not a candidate
    cols = {
        "point_id": p["ids"],
        "dx": p["dx"].tolist(),
        "dy": p["dy"].tolist(),
        "dz": [None] * n,
        "dr": np.hypot(p["dx"], p["dy"]).tolist(),
        "x_ref": p["x"].tolist(),
        "y_ref": p["y"].tolist(),
        "status": status,
        "decision": decision,
        "row": list(range(1, n + 1)),
    }
    block = {
        "points": {"columns": list(cols), "data": cols},
        "unit": "m",
        "limit_x": 0.45,
        "limit_y": 0.45,
        "basis": "calculated",
        "stats": {"n": n},
        "gcps": [],
        "polygon": None,
        "area_source": None,
    }
    return {
        "schema": "orthospec.qcr/3",
        "date": "2026-11-21",
        "profile": {},
        "delivery": {"id": "D"},
        "verdict": "rejected",
        "summary": {},
        "records": [],
        "rules": [],
        "details": {"checkpoints": {"B01": block}},
    }


def test_html_view_lists_every_flagged_point_and_counts_the_hidden_ones():
    n, n_fail = 6000, 40
    doc = _doc(n, n_fail)
    opts = ReportOptions()
    ctx = report_context(doc, opts, figure=data_uri)
    (b,) = ctx["checkpoints"]
    cols = doc["details"]["checkpoints"]["B01"]["points"]["data"]
    must = {
        i
        for i, (s, d) in enumerate(zip(cols["status"], cols["decision"], strict=True))
        if s == "fail" or d != "kept"
    }
    shown = {p["row"] - 1 for p in b["points"]}
    assert must <= shown
    assert len(b["points"]) == opts.max_table_points
    assert b["n_hidden"] == n - opts.max_table_points
    assert b["n_pass_shown"] == opts.max_table_points - len(must)
    passing_shown = sorted(shown - must)
    first_passing = [i for i in range(n) if i not in must][: len(passing_shown)]
    assert passing_shown == first_passing  # the first ones, in table order
    (cap_map, *_) = [f for f in b["figures"] if f["kind"] == "map"]
    m = re.search(
        r"Drawn: ([\d,]+) of the ([\d,]+) points, all ([\d,]+) flagged or excluded",
        cap_map["caption"],
    )
    assert m and int(m[2].replace(",", "")) == n and int(m[3].replace(",", "")) == len(must)
    assert int(m[1].replace(",", "")) == len(_marks(cap_map["svg"])) <= MAX_MARKS
    hist = [f for f in b["figures"] if f["kind"] == "hist"]
    assert hist and f"Every one of the {n:,} points is binned." in hist[0]["caption"]


def test_pdf_view_still_lists_every_flagged_point():
    n, n_fail = 6000, 40
    doc = _doc(n, n_fail)
    ctx = report_context(doc, ReportOptions(bounded=True))
    (b,) = ctx["checkpoints"]
    cols = doc["details"]["checkpoints"]["B01"]["points"]["data"]
    must = sum(
        s == "fail" or d != "kept" for s, d in zip(cols["status"], cols["decision"], strict=True)
    )
    assert len(b["points"]) == must and b["n_hidden"] == n - must


def test_map_with_more_flagged_points_than_the_cap_draws_them_all_and_a_spread():
    p = _points(20_000, seed=5)
    flagged = p["ids"][:1500]
    svg = checkpoint_map_svg(p["x"], p["y"], p["dx"], p["dy"], ids=p["ids"], flagged=flagged)
    marks = _marks(svg)
    assert sum(red for *_, red in marks) == 1500
    others = len(marks) - 1500
    assert MIN_SAMPLE * 0.9 <= others <= MIN_SAMPLE  # the spread still shows, bounded
    labelled = {t.strip() for t in re.findall(r"<text[^>]*>([^<]*)</text>", svg)}
    assert len(labelled & set(flagged)) >= MAX_FLAGGED_LABELS
    dr = np.hypot(p["dx"][:1500], p["dy"][:1500])
    worst = {flagged[i] for i in np.argsort(-dr)[:MAX_FLAGGED_LABELS]}
    assert worst <= labelled  # the forced labels name the largest discrepancies
    assert not labelled & set(p["ids"][1500:])  # a sampled map labels flagged points only


def test_label_placement_matches_the_all_pairs_rule():
    """The grid lookup places exactly the labels the rule 'flagged always, others at least
    min_gap from every label placed before' places when every pair is compared."""
    rng = np.random.default_rng(2)
    for n, gap in ((400, 40.0), (1500, 15.0), (60, 300.0)):
        xs, ys = rng.uniform(0, 1000, n), rng.uniform(0, 1000, n)
        red = rng.random(n) < 0.05
        placed: list[int] = []
        for i in sorted(range(n), key=lambda k: (not red[k], k)):
            if red[i] or all(math.hypot(xs[i] - xs[j], ys[i] - ys[j]) >= gap for j in placed):
                placed.append(i)
        assert _uncrowded(xs, ys, red, gap) == placed
