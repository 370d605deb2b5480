"""The check-point provider's typed block results and its report detail (docs/QCR.md, issue 14
item 3): the detail's points are a DataFrame in file-row order; beyond DETAIL_POINTS_MAX rows per
block it keeps every flagged point and the largest residuals and says how many it leaves out,
while statistics and per-point measures use every point."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from orthospec.delivery.reader import open_delivery
from orthospec.engine.providers import checkpoints as cp
from orthospec.engine.registry import ProviderContext

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "deliveries" / "aerial-fail"


def _run():
    d = open_delivery(EXAMPLE)
    ctx = ProviderContext(d, {"tolerance_xy": 0.5})
    block = {m.name: m for m in cp.block_checkpoint_stats(ctx)}
    points = {m.name: m for m in cp.point_decisions(ctx)}
    return d, block, points


def test_detail_points_are_a_frame_in_file_order_with_independent_values():
    _, block, _ = _run()
    detail = block["checkpoints.rmse_x"].detail["checkpoints"]
    src = pd.read_csv(EXAMPLE / "tables" / "checkpoints.csv")
    for b, det in detail.items():
        frame = det["points"]
        assert isinstance(frame, pd.DataFrame) and "points_omitted" not in det
        assert list(frame.columns) == [
            "point_id",
            "dx",
            "dy",
            "dz",
            "dr",
            "x_ref",
            "y_ref",
            "status",
            "decision",
            "row",
        ]
        mine = src[src["block"] == b]
        assert frame["point_id"].tolist() == mine["point_id"].tolist()
        np.testing.assert_allclose(frame["dx"], mine["x"] - mine["x_ref"], atol=1e-9)
        np.testing.assert_allclose(
            frame["dr"], np.hypot(mine["x"] - mine["x_ref"], mine["y"] - mine["y_ref"]), atol=1e-9
        )
        assert frame["row"].tolist() == [i + 1 for i in mine.index]
        # the block RMSE recomputed with numpy from the file (no exclusion is justified in aerial-fail B02)
        kept = frame["decision"] != "excluded"
        assert block["checkpoints.n"].values[b] == int(kept.sum())
        rmse = float(np.sqrt(np.mean(frame.loc[kept, "dx"] ** 2)))
        assert block["checkpoints.rmse_x"].values[b] == pytest.approx(rmse, rel=1e-12)
        assert det["stats"]["rmse_x"] == block["checkpoints.rmse_x"].values[b]


def test_detail_is_capped_but_keeps_flagged_points_and_the_largest_residuals(monkeypatch):
    monkeypatch.setattr(cp, "DETAIL_POINTS_MAX", 6)
    _, block, points = _run()
    detail = block["checkpoints.rmse_x"].detail["checkpoints"]
    n_points = len(points["checkpoint.dr"].values)
    for b, det in detail.items():
        frame = det["points"]
        total = det.get("points_total", len(frame))
        assert det.get("points_omitted", 0) == total - len(frame)
        if total <= 6:
            continue
        assert det["points_omitted"] > 0
        flagged = (frame["status"] == "fail") | (frame["decision"] != "kept")
        assert len(frame) == max(6, int(flagged.sum()))
        assert frame["row"].is_monotonic_increasing  # still file-row order
        # every point left out has a smaller residual than every unflagged point kept
        others = points["checkpoint.dr"].values.drop(frame["point_id"])
        left_out = others[others.index.str.startswith(b)]
        if (~flagged).any() and len(left_out):
            assert left_out.max() <= frame.loc[~flagged, "dr"].min()
    assert n_points == len(
        pd.read_csv(EXAMPLE / "tables" / "checkpoints.csv")
    )  # every point keeps its own QCR measure
