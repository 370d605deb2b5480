"""Issue 31: ``orthospec measure edge IMAGE --roi A --roi B ...`` measures many ROIs in one call,
in parallel processes, with the same numbers as one ROI per call."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine
from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.measures.synthetic import PsfFamily, family_edge, family_truth

ANGLES = (6.0, 21.0)


@pytest.fixture
def tiles(tmp_path: Path) -> Path:
    """Two 8-bit edges side by side (100 x 100 px each, 10 px apart)."""
    mosaic = np.full((100, 210), 120, dtype=np.uint8)
    for i, angle in enumerate(ANGLES):
        mosaic[:, 110 * i : 110 * i + 100] = family_edge(
            PsfFamily("gauss", sigma=0.7),
            (100, 100),
            angle_deg=angle,
            dark=40,
            bright=200,
            snr=200,
            bit_depth=8,
            rng=np.random.default_rng(i),
        )
    path = tmp_path / "tiles.tif"
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=210,
        height=100,
        count=1,
        dtype="uint8",
        crs="EPSG:25832",
        transform=Affine(0.2, 0, 500000.0, 0, -0.2, 5600000.0),
    ) as ds:
        ds.write(mosaic, 1)
    return path


def test_many_rois_in_one_call_equal_one_per_call(tiles):
    rois = ["0,0,100,100", "110,0,210,100"]
    res = CliRunner().invoke(
        cli(),
        [
            "measure",
            "edge",
            str(tiles),
            "--roi",
            rois[0],
            "--roi",
            rois[1],
            "--workers",
            "2",
            "--json",
        ],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["workers"] == 2 and [r["roi"] for r in doc["rois"]] == [
        [0, 0, 100, 100],
        [110, 0, 210, 100],
    ]
    for roi, angle, got in zip(rois, ANGLES, doc["rois"], strict=True):
        one = json.loads(
            CliRunner()
            .invoke(cli(), ["measure", "edge", str(tiles), "--roi", roi, "--json"])
            .output
        )
        truth = family_truth(PsfFamily("gauss", sigma=0.7), angle_deg=angle)
        assert got["valid"] and got["fwhm_px"] == pytest.approx(one["fwhm_px"], rel=1e-12)
        assert got["fwhm_px"] == pytest.approx(truth.fwhm_px, rel=0.02)
        assert got["fwhm_px.u"] is not None and got["fwhm_m"] == pytest.approx(got["fwhm_px"] * 0.2)
    text = (
        CliRunner()
        .invoke(
            cli(),
            ["measure", "edge", str(tiles), "--roi", rois[0], "--roi", rois[1], "--workers", "1"],
            terminal_width=160,
        )
        .output
    )
    assert "2 ROIs" in text and "±" in text


def test_a_bad_roi_among_many_exits_2(tiles):
    res = CliRunner().invoke(
        cli(), ["measure", "edge", str(tiles), "--roi", "0,0,100,100", "--roi", "0,0,500,100"]
    )
    assert res.exit_code == 2 and "Traceback" not in res.output
