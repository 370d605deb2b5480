"""The scale benchmarks build what they claim (issue 14): distinct images, real check points."""

from __future__ import annotations

import csv
import hashlib
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


def _bench(name: str):
    spec = importlib.util.spec_from_file_location(
        f"bench_{name}", ROOT / "benchmarks" / f"{name}.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_scale_builds_distinct_images_that_check_evaluates(tmp_path):
    scale = _bench("scale")
    n = 34
    delivery = tmp_path / "d"
    scale.build(delivery, n)
    with open(delivery / "tables" / "images.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == n and len({r["image_id"] for r in rows}) == n
    digests = {hashlib.sha256((delivery / r["file"]).read_bytes()).hexdigest() for r in rows}
    assert len(digests) == n  # every image is its own file: no cache or dedup can help

    from orthospec.cli.main import main

    with pytest.raises(SystemExit) as exc:
        main(
            [
                "check",
                str(delivery),
                "-p",
                "jrc-v3",
                "--out",
                str(tmp_path / "o"),
                "--format",
                "json",
                "--date",
                "2026-11-21",
                "--workers",
                "1",
                "--param",
                "tolerance_xy=0.5m",
                "--param",
                "map_crs=EPSG:25832",
            ]
        )
    assert exc.value.code in (
        0,
        1,
        3,
    )  # accepted, rejected, incomplete (the checker has not inspected the added images)
    doc = json.loads((tmp_path / "o" / "qcr.json").read_text())
    per_image = [sum(r["counts"].values()) for r in doc["rules"] if r["scope"] == "image"]
    assert per_image and max(per_image) == n  # the rules saw every generated image


def test_checkpoint_generator_writes_the_delivery_table_columns(tmp_path):
    cp = _bench("checkpoints")
    path = tmp_path / "checkpoints.csv"
    cp.write_checkpoints(path, 2_345)
    df = pd.read_csv(path)
    tables = yaml.safe_load((ROOT / "specs" / "delivery-tables.yaml").read_text())
    declared = tables["tables"]["checkpoints"]["columns"]
    assert set(df.columns) <= set(declared)
    assert {c for c, d in declared.items() if d.get("required")} <= set(df.columns)
    assert len(df) == 2_345 and df["point_id"].is_unique
    for block, (x0, x1, y0, y1) in cp.BLOCKS.items():
        g = df[df["block"] == block]
        assert len(g) > 0
        assert g["x_ref"].between(x0, x1).all() and g["y_ref"].between(y0, y1).all()
    dx = (df["x"] - df["x_ref"]).to_numpy()
    assert 0.1 < float(np.sqrt(np.mean(dx**2))) < 0.2  # N(0, 0.15 m) errors, as documented


def test_point_csv_reader_keeps_row_semantics_when_vectorised(tmp_path):
    """Column-wise reading (issue 14) on the one delivery CSV parser (issue 15): cells stripped,
    blank lines skipped, row N is line N+1 of the file (as evidence rows are), a row with more
    or fewer cells than the header and a number with a separator are refused naming the row."""
    from orthospec.delivery.points import read_points_csv
    from orthospec.errors import DeliveryError

    path = tmp_path / "p.csv"
    path.write_text(
        "id, x ,y,x_ref,y_ref,exclusion_reason\n"
        " A ,10.5,20,10,20.25,\n"
        "\n"
        "B,1000,5,999.5,4,blunder: cone moved\n"
        "C,3,3,3,3,\n",
        encoding="utf-8",
    )
    t = read_points_csv(path)
    assert t.ids.tolist() == ["A", "B", "C"] and t.rows.tolist() == [1, 3, 4]
    np.testing.assert_array_equal(t.dx, [0.5, 0.5, 0.0])
    np.testing.assert_array_equal(t.dy, [-0.25, 1.0, 0.0])
    assert t.exclusions == {"B": "blunder: cone moved"}
    path.write_text("id,x,y,x_ref,y_ref\nA,1,2,1,2\n\nB,1,2,1,2,extra\n")
    with pytest.raises(DeliveryError, match="row 3: has 6 fields, the header has 5"):
        read_points_csv(path)
    path.write_text("id,x,y,x_ref,y_ref\nA,1_000,2,1,2\n")
    with pytest.raises(DeliveryError, match="row 1: column 'x': expected a number, got '1_000'"):
        read_points_csv(path)
    path.write_text("id,x,y,x_ref,y_ref\nA,1,2,1,2\nB,1,2,1,2\nC,1,two,1,2\n")
    with pytest.raises(DeliveryError, match="row 3: column 'y': expected a number, got 'two'"):
        read_points_csv(path)
    path.write_text("id,x,y,x_ref,y_ref\nA,1,2,1,2\nB,1,2,1,2\nD,1,inf,1,2\n")
    with pytest.raises(DeliveryError, match="row 3: column 'y': expected a finite number"):
        read_points_csv(path)
    path.write_text("id,x,y,x_ref,y_ref\nA,1,2,1,2\nB,1,2,1,2\nA,1,2,1,2\n")
    with pytest.raises(DeliveryError, match=r"duplicate point id 'A' \(first on row 1\)"):
        read_points_csv(path)


def test_point_csv_reader_on_a_large_generated_table(tmp_path):
    from orthospec.delivery.points import read_points_csv

    n = 200_000
    rng = np.random.default_rng(5)
    xr = np.round(500000 + rng.random(n) * 6000, 3)
    x = np.round(xr + rng.normal(0, 0.15, n), 3)
    path = tmp_path / "big.csv"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("point_id,x,y,x_ref,y_ref,unit\n")
        fh.writelines(f"P{i},{x[i]:.3f},7,{xr[i]:.3f},7,m\n" for i in range(n))
    t = read_points_csv(path)
    np.testing.assert_array_equal(t.dx, x - xr)  # the same float64 operations on the same values
    assert len(t.ids) == n and t.source_unit == "m" and not t.exclusions
