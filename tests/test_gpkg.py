"""`check --format gpkg` (issue 30 items 1-2): the findings layers read back with pyogrio.

The expected values come from qcr.json (the records, grouped here by item without orthospec's
code), from the image files' headers as rasterio reads them, and from QGIS's layer_styles schema.
"""

from __future__ import annotations

import json
import math
import sqlite3
from collections import Counter, defaultdict
from contextlib import closing
from pathlib import Path
from typing import Any

import numpy as np
import pyogrio
import pytest
import rasterio
import shapely
from click.testing import CliRunner
from lxml import etree
from tests.conftest import ROOT

from orthospec.cli.main import cli

SEVERITY = ("error", "fail", "missing", "warn", "waived", "pass", "not_applicable")
STYLE_COLUMNS = [
    "id",
    "f_table_catalog",
    "f_table_schema",
    "f_table_name",
    "f_geometry_column",
    "styleName",
    "styleQML",
    "styleSLD",
    "useAsDefault",
    "description",
    "owner",
    "ui",
    "update_time",
]


def run(out: Path, fmts: str = "json,gpkg,html") -> Any:
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(ROOT / "examples/deliveries/aerial-fail"),
            "--profile",
            "jrc-v3",
            "--checker",
            str(ROOT / "examples/checker/aerial-fail"),
            "--format",
            fmts,
            "--out",
            str(out),
            "--date",
            "2026-11-21",
        ],
    )
    assert res.exit_code == 1, res.output + repr(res.exception)  # aerial-fail is rejected
    return res


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("gpkg") / "out"
    run(out)
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    return {"out": out, "doc": doc, "gpkg": out / "findings.gpkg"}


def layer(path: Path, name: str) -> tuple[list[Any], dict[str, np.ndarray]]:
    meta, _fids, geom, fields = pyogrio.raw.read(path, layer=name)
    cols = {n: fields[k] for k, n in enumerate(meta["fields"])}
    geoms = [] if geom is None else [None if g is None else shapely.from_wkb(g) for g in geom]
    return geoms, cols


def records_by_item(doc: dict[str, Any], scope: str) -> dict[str, list[dict[str, Any]]]:
    from orthospec.qcr import all_records

    scopes = {r["rule"]: r["scope"] for r in doc["rules"]}
    out: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in all_records(doc):
        if scopes[r["rule"]] == scope:
            out[str(r["item"])].append(r)
    return out


def worst(recs: list[dict[str, Any]]) -> str:
    return min((r["verdict"] for r in recs), key=SEVERITY.index)


def test_layers_in_the_delivery_crs_and_nothing_written_into_the_delivery(
    checked: dict[str, Any],
) -> None:
    names = {n for n, _ in pyogrio.list_layers(checked["gpkg"])}
    assert {
        "blocks",
        "images",
        "seamlines",
        "inspection_cells",
        "checkpoints",
        "residuals",
        "rules",
        "layer_styles",
    } <= names
    for name in ("blocks", "images", "checkpoints", "residuals", "inspection_cells"):
        assert (
            pyogrio.read_info(checked["gpkg"], layer=name)["crs"]
            == checked["doc"]["delivery"]["project"]["crs"]
        )
    assert not list((ROOT / "examples/deliveries/aerial-fail").rglob("*.gpkg"))


@pytest.mark.parametrize(
    ("name", "scope", "key"), [("images", "image", "id"), ("blocks", "block", "id")]
)
def test_every_non_pass_record_is_on_its_feature_and_counts_agree(
    checked: dict[str, Any], name: str, scope: str, key: str
) -> None:
    _geoms, cols = layer(checked["gpkg"], name)
    by_item = records_by_item(checked["doc"], scope)
    ids = [str(v) for v in cols[key]]
    feature = {i: k for k, i in enumerate(ids)}
    non_pass = [
        r
        for recs in by_item.values()
        for r in recs
        if r["verdict"] not in ("pass", "not_applicable")
    ]
    assert non_pass, "aerial-fail has findings on this scope"
    for r in non_pass:
        k = feature[str(r["item"])]
        assert r["rule"] in (cols["reasons"][k] or ""), (r["rule"], r["item"])
    # the verdict of each feature is the worst of its records; counts per verdict equal qcr.json's
    expected = Counter(worst(recs) for recs in by_item.values())
    got = Counter(str(v) for i, v in zip(ids, cols["verdict"], strict=True) if i in by_item)
    assert got == expected


def test_image_footprints_are_the_raster_bounds(checked: dict[str, Any]) -> None:
    geoms, cols = layer(checked["gpkg"], "images")
    root = ROOT / "examples/deliveries/aerial-fail"
    import csv

    with open(root / "tables/images.csv", encoding="utf-8") as f:
        files = {row["image_id"]: row["file"] for row in csv.DictReader(f)}
    seen = 0
    for iid, g in zip(cols["id"], geoms, strict=True):
        path = root / files[str(iid)]
        if not path.exists():
            assert (
                g is None
            )  # F03_0202 is listed but not delivered: no footprint, the finding stays
            continue
        with rasterio.open(path) as ds:
            assert g.bounds == pytest.approx(tuple(ds.bounds))
        seen += 1
    assert seen >= 28


def test_blocks_carry_the_statistics_of_qcr_json(checked: dict[str, Any]) -> None:
    geoms, cols = layer(checked["gpkg"], "blocks")
    cps = checked["doc"]["details"]["checkpoints"]
    rejected = set(checked["doc"]["rollup"]["rejected"]["block"])
    for k, bid in enumerate(cols["id"]):
        stats = cps[bid]["stats"]
        assert cols["rmse_x"][k] == pytest.approx(stats["rmse_x"]) and cols["rmse_y"][
            k
        ] == pytest.approx(stats["rmse_y"])
        assert geoms[k].equals(shapely.Polygon(cps[bid]["polygon"]))
        assert cols["rejected"][k] == (bid in rejected)  # the §12.8 roll-up of qcr.json
        if bid in rejected:
            assert cols["consequence"][k] in ("reject_block", "return_delivery")


def test_checkpoints_and_residuals(checked: dict[str, Any]) -> None:
    from orthospec.qcr import point_rows

    geoms, cols = layer(checked["gpkg"], "checkpoints")
    points = [
        (b, p)
        for b, d in checked["doc"]["details"]["checkpoints"].items()
        for p in point_rows(d["points"])
    ]
    assert len(geoms) == len(points)
    want = {(b, p["point_id"]): p for b, p in points}
    status = Counter()
    for k, g in enumerate(geoms):
        p = want[(cols["block"][k], cols["point_id"][k])]
        assert (g.x, g.y) == pytest.approx((p["x_ref"], p["y_ref"]))
        assert cols["dx"][k] == pytest.approx(p["dx"]) and cols["dr"][k] == pytest.approx(p["dr"])
        status[cols["status"][k]] += 1
        assert (cols["status"][k] == "used") == (p["status"] == "pass" and p["decision"] == "kept")
    assert status["blunder candidate"] >= 1 and status["used"] >= 1
    info = pyogrio.read_info(checked["gpkg"], layer="residuals")
    scale = float(info["layer_metadata"]["residual_scale"])
    lines, rc = layer(checked["gpkg"], "residuals")
    assert len(lines) == len(geoms)
    for k, line in enumerate(lines):
        assert line.length == pytest.approx(rc["dr"][k] * scale, rel=1e-6)
        assert rc["scale"][k] == scale
    # the longest arrow is a readable share of the map, not a dot or the whole map
    x0, y0, x1, y1 = shapely.total_bounds([*geoms])
    assert 0.005 < max(line.length for line in lines) / math.hypot(x1 - x0, y1 - y0) < 0.2


def test_rules_table_joins_clause_and_quote(checked: dict[str, Any]) -> None:
    _, rules = layer(checked["gpkg"], "rules")
    _, imgs = layer(checked["gpkg"], "images")
    by_id = {r["rule"]: r for r in checked["doc"]["rules"]}
    assert sorted(rules["rule"]) == sorted(by_id)
    for k, rid in enumerate(rules["rule"]):
        assert (
            rules["quote"][k] == by_id[rid]["quote"] and rules["clause"][k] == by_id[rid]["clause"]
        )
    assert {r for r in imgs["rule"] if r} <= set(rules["rule"])


def test_qgis_styles_table(checked: dict[str, Any]) -> None:
    with closing(sqlite3.connect(checked["gpkg"])) as con:
        cols = [r[1] for r in con.execute("PRAGMA table_info(layer_styles)")]
        rows = con.execute(
            "SELECT f_table_name, f_geometry_column, styleQML, styleSLD, useAsDefault "
            "FROM layer_styles"
        ).fetchall()
        geom_cols = dict(
            con.execute("SELECT table_name, column_name FROM gpkg_geometry_columns").fetchall()
        )
        contents = dict(con.execute("SELECT table_name, data_type FROM gpkg_contents").fetchall())
    assert cols == STYLE_COLUMNS
    assert contents["layer_styles"] == "attributes"
    assert {r[0] for r in rows} == set(geom_cols)  # one default style per geometry layer
    for table, gcol, q, s, default in rows:
        assert gcol == geom_cols[table] and default == 1
        root = etree.fromstring(q.split("\n", 1)[1].encode())
        rend = root.find("renderer-v2")
        assert rend.get("type") == "categorizedSymbol" and rend.get("attr") == "verdict"
        values = {c.get("value") for c in rend.iter("category")}
        _, fc = layer(checked["gpkg"], table)
        assert {
            str(v) for v in fc["verdict"] if v is not None
        } <= values  # every verdict present is coloured
        colours = {c.get("value"): c.get("symbol") for c in rend.iter("category")}
        assert colours["fail"] != colours["pass"]
        etree.fromstring(s.encode())


def test_same_inputs_same_bytes(checked: dict[str, Any], tmp_path: Path) -> None:
    run(tmp_path / "again", "gpkg")
    assert (tmp_path / "again" / "findings.gpkg").read_bytes() == checked["gpkg"].read_bytes()
