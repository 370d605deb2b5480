"""The bundled example deliveries: up to date, deterministic, and saying what they claim.

``examples/generate.py`` writes ``examples/deliveries/*`` and the external QC's file for each,
``examples/checker/<name>.yaml`` (manual-check verdicts and waivers in force). These tests
regenerate them into a temporary folder and compare every file's SHA-256 with the committed
ones, then check the committed data against the convention (specs/delivery-tables.yaml) and
against the claims of each delivery's ``expected.yaml``: the pass example meets the JRC
guidelines, and the fail example breaks them for exactly the documented reasons.
"""

from __future__ import annotations

import hashlib
import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd
import pytest
import rasterio
import yaml
from shapely.geometry import Point, Polygon
from tests.checking import CHECKERS, EXAMPLES, ROOT

NAMES = ("aerial-pass", "aerial-fail")
SATELLITE = ("satellite-pass", "satellite-fail")
SPEC = yaml.safe_load((ROOT / "specs" / "delivery-tables.yaml").read_text(encoding="utf-8"))[
    "tables"
]
GSD = 0.25


def _generator() -> ModuleType:
    """Import examples/generate.py (a script, not a package module) once."""
    name = "orthospec_examples_generate"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / "generate.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses resolve string annotations through sys.modules
        spec.loader.exec_module(module)
    return sys.modules[name]


def _digests(root: Path) -> dict[str, str]:
    return {
        p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("examples") / "deliveries"
    _generator().generate(out)  # checker files into out/../checker, as examples/checker
    return out


def _external(name: str) -> pd.DataFrame:
    """The checker's own check point measurements (the checker folder's tables/checkpoints.csv): what the
    external-accuracy rules read; the delivery's table is the contractor's internal QC (JRC §12.5)."""
    return pd.read_csv(
        CHECKERS / name / "tables" / "checkpoints.csv",
        dtype=str,
        keep_default_na=False,
        encoding="utf-8",
    )


def _grid_cells(name: str) -> pd.DataFrame:
    """The cells of the checker's marked inspection grid (empty when the example has none)."""
    from pyogrio import raw

    path = CHECKERS / name / "inspection.gpkg"
    if not path.is_file():
        return pd.DataFrame(columns=["cell_id", "image_id", "inspected", "haze", "comment"])
    meta, _, _, values = raw.read(path, layer="cells")
    return pd.DataFrame({str(f): v for f, v in zip(meta["fields"], values, strict=True)})


def _checker(name: str) -> dict[str, Any]:
    return yaml.safe_load((CHECKERS / name / "checker.yaml").read_text(encoding="utf-8"))


def _manifest(name: str) -> dict[str, Any]:
    return yaml.safe_load((EXAMPLES / name / "delivery.yaml").read_text(encoding="utf-8"))


def _expected(name: str) -> dict[str, Any]:
    return yaml.safe_load((EXAMPLES / name / "expected.yaml").read_text(encoding="utf-8"))


def _table(name: str, table: str) -> pd.DataFrame:
    path = EXAMPLES / name / _manifest(name)["tables"][table]
    return pd.read_csv(path, dtype=str, keep_default_na=False, encoding="utf-8")


def _num(series: pd.Series) -> pd.Series:
    return pd.to_numeric(series.replace("", np.nan))


# --------------------------------------------------------------------------- up to date
@pytest.mark.parametrize("name", (*NAMES, *SATELLITE, "tiles-real"))
def test_committed_example_equals_a_fresh_generation(regenerated: Path, name: str) -> None:
    fresh, committed = _digests(regenerated / name), _digests(EXAMPLES / name)
    assert sorted(fresh) == sorted(committed), (
        "file lists differ: run `python examples/generate.py`"
    )
    stale = [f for f in fresh if fresh[f] != committed[f]]
    assert not stale, f"stale files {stale}: run `python examples/generate.py`"


def test_committed_checker_files_equal_a_fresh_generation(regenerated: Path) -> None:
    fresh, committed = _digests(regenerated.parent / "checker"), _digests(CHECKERS)
    folders = {
        f"{n}/{f}" for n in NAMES + SATELLITE for f in ("checker.yaml", "tables/checkpoints.csv")
    }
    measured = {
        f"{n}/{f}"
        for n in ("tiles-real", "tiles-real-fail")
        for f in (  # issue 29: measured by the tool
            "checker.yaml",
            "tables/checkpoints.csv",
            "checkpoints-to-measure.gpkg",
            "reference/reference.tif",
            "survey.csv",
        )
    }
    assert (
        sorted(fresh)
        == sorted(committed)
        == sorted(
            folders | {f"{n}/inspection.gpkg" for n in NAMES} | {"tiles-real.yaml"} | measured
        )
    )
    assert fresh == committed, "stale checker files: run `python examples/generate.py`"


def test_generation_is_byte_identical_twice(regenerated: Path, tmp_path: Path) -> None:
    _generator().generate(tmp_path / "deliveries")
    for name in (*NAMES, *SATELLITE, "tiles-real"):
        assert _digests(tmp_path / "deliveries" / name) == _digests(regenerated / name)
    assert _digests(tmp_path / "checker") == _digests(regenerated.parent / "checker")


@pytest.mark.parametrize("name", NAMES + SATELLITE)
def test_the_delivery_holds_statements_and_the_checker_file_the_verdicts(name: str) -> None:
    """JRC §2: the contractor's internal QC (the delivery's manual_checks, by its own QA manager)
    is evidence; the external QC's verdicts and waivers are in the checker's file, outside it."""
    from orthospec.delivery.checker import load_checker

    m, own = _manifest(name), _table(name, "manual_checks")
    assert not m.get("waivers")  # the snow waiver of aerial-pass is granted by the checker
    assert set(own["inspector"]) == {f"{m['operator']['name']}, {m['operator']['role']}"}
    chk = load_checker(CHECKERS / name, delivery_root=EXAMPLES / name)
    assert chk.party.role == "external QC" and chk.party.name not in m["operator"]["name"]
    # the visual checks per image are answered by the checker's marked inspection grid, the rest are typed
    gridded = {
        (rule, i)
        for rule in ("JRC-6.3-ARTEFACTS", "JRC-T6-ORTHO-INSPECTION")
        for i in set(_grid_cells(name)["image_id"])
    }
    signed = {(r.check, r.item) for r in chk.model.manual_checks}
    assert not signed & gridded
    assert signed | gridded == set(zip(own["check"], own["item"], strict=True))
    assert _expected(name)["checker"] == f"../../checker/{name}"


def test_examples_stay_small() -> None:
    size = sum(p.stat().st_size for p in EXAMPLES.rglob("*") if p.is_file())
    assert 500_000 < size < 4_000_000
    for name in SATELLITE:
        assert sum(p.stat().st_size for p in (EXAMPLES / name).rglob("*") if p.is_file()) < 600_000


# --------------------------------------------------------------------------- satellite
@pytest.mark.parametrize("name", SATELLITE)
def test_satellite_example_is_a_vhr_delivery_with_its_records(name: str) -> None:
    """VHR by the §9.1 classes (PAN < 3 m), RPC block / single-scene RPC with Table 9 GCP counts,
    GCP residuals saved, independent check points >= 300 m from every GCP, rasters at 0.5 m."""
    m = _manifest(name)
    assert m["sensor"]["type"] == "satellite" and m["product"]["gsd"] == {"value": 0.5, "unit": "m"}
    scenes, gcps, cps = _table(name, "scenes"), _table(name, "gcps"), _external(name)
    assert (_num(scenes["input_pixel_size"]) < 3).all() and set(scenes["resolution_class"]) == {
        "VHR"
    }
    assert set(scenes["correction_method"]) == {"rpc_block", "rpc"}
    per_scene = gcps["point_id"].str.rsplit("-", n=1).str[0].value_counts()
    assert (
        per_scene.reindex(scenes["image_id"]).to_numpy() == _num(scenes["gcp_count"]).to_numpy()
    ).all()
    assert (gcps[["residual_x", "residual_y"]] != "").all().all()
    g = gcps[["x", "y"]].astype(float).to_numpy()
    for x, y in cps[["x_ref", "y_ref"]].astype(float).to_numpy():
        assert np.hypot(*(g - (x, y)).T).min() >= 300.0
    for row in _table(name, "images").itertuples(index=False):
        with rasterio.open(EXAMPLES / name / row.file) as ds:
            assert ds.res == (0.5, 0.5) and ds.crs.to_epsg() == 25832 and ds.count == 4
    exp = _expected(name)
    for site, rec in exp["recomputed"].items():
        pts = cps[cps["block"] == site]
        dx = pts["x"].astype(float) - pts["x_ref"].astype(float)
        assert round(float(np.sqrt(np.mean(dx**2))), 3) == rec["rmse_x"] and len(pts) == rec["n"]
    fail = name == "satellite-fail"
    master = scenes[scenes["is_master"] == "true"]
    assert len(master) == 1 and (int(master["checkpoint_count"].iloc[0]) < 20) == fail
    assert ((_num(scenes["gcp_count"]) < 2) & (scenes["correction_method"] == "rpc")).any() == fail
    assert (exp["recomputed"]["S02"]["rmse_x"] > 1.0) == fail


# --------------------------------------------------------------------------- convention
@pytest.mark.parametrize("name", NAMES)
def test_documents_are_delivered_and_consistent(name: str) -> None:
    """Every manifest document is a small text file in the delivery; GCP references resolve."""
    m, root = _manifest(name), EXAMPLES / name
    assert {"internal_qcr", "gcp_report", "geodetic_control", "gcp_plot", "rejected_items"} <= set(
        m["documents"]
    )
    texts = {}
    for rel in m["documents"].values():
        path = root / rel
        assert (
            path.is_file() and rel.startswith("documents/") and 100 < path.stat().st_size < 60_000
        ), rel
        texts[rel] = path.read_text(encoding="utf-8")
    assert m["product"]["extracts"] is True
    gcp = _table(name, "gcps")
    report = texts[m["documents"]["gcp_report"]]
    assert all(f"| {pid} |" in report for pid in gcp["point_id"])
    assert (_num(gcp["images_measured"]) >= 2).all()
    for ref in pd.concat([gcp["sketch"], gcp["photo"]]):
        rel, anchor = ref.split("#")
        assert f"## {anchor}\n" in texts[rel], ref
    assert "EPSG:25832" in texts[m["documents"]["geodetic_control"]]
    assert texts[m["documents"]["gcp_plot"]].startswith("<svg") and texts[
        m["documents"]["gcp_plot"]
    ].count("<circle") == len(_table(name, "images"))


@pytest.mark.parametrize("name", NAMES)
def test_flight_and_at_records_are_consistent(name: str) -> None:
    """Overlaps, GSD and AT accuracy agree with the camera, the photos and the tolerance."""
    cam = _table(name, "cameras").iloc[0]
    img = _table(name, "images")
    fh = _num(img["flying_height"])
    gsd = fh * float(cam["pixel_size"]) * 1e-3 / float(cam["focal_length"])
    ok = fh.notna()
    assert np.allclose(gsd[ok], _num(img["acquisition_gsd"])[ok], atol=6e-5)
    assert (_num(img["acquisition_gsd"]) <= GSD).all()
    fl = _table(name, "flights")
    assert (_num(fl["forward_overlap"]) >= 60).all() and _num(fl["side_overlap"]).between(
        15, 60
    ).all()
    at = _table(name, "aerotriangulation")
    assert set(at["block"]) == {b["id"] for b in _manifest(name)["blocks"]}
    assert (_num(at["checkpoint_rmse_x"]) <= 0.5 / 3).all() and (
        _num(at["gcp_rmse_y"]) < 0.25
    ).all()
    assert (
        _num(_table(name, "checkpoints")["precision_xy"]) <= 0.5 / 3
    ).all()  # the contractor's (§7.2)
    assert (_num(_external(name)["precision_xy"]) <= 0.5 / 3).all()  # the checker's


@pytest.mark.parametrize("name", NAMES)
def test_manifest_follows_the_delivery_convention(name: str) -> None:
    m = _manifest(name)
    assert m["orthospec_delivery"] == 1
    assert m["project"]["crs"] == "EPSG:25832"
    assert m["sensor"] == {**m["sensor"], "type": "aerial", "digital": True}
    assert m["product"]["gsd"] == {"value": GSD, "unit": "m"}
    assert m["product"]["dem_delivered"] is False
    assert m["dates"]["acquired_from"] <= m["dates"]["acquired_to"] < m["dates"]["delivered"]
    assert set(m["tables"]) <= set(SPEC)
    for rel in m["tables"].values():
        assert (EXAMPLES / name / rel).is_file(), rel
    images = _table(name, "images")
    block_ids = [b["id"] for b in m["blocks"]]
    assert (
        set(images["block"])
        == set(block_ids)
        == set(_table(name, "checkpoints")["block"])
        == set(_external(name)["block"])
    )
    assert 2 <= len(block_ids) <= 3 and 24 <= len(images) <= 36
    for b in m["blocks"]:
        assert Polygon(b["polygon"]).is_valid and Polygon(b["polygon"]).area > 1e7
        assert set(b["reported"]) == {"rmse_x", "rmse_y"}
        assert all(v["unit"] == "m" for v in b["reported"].values())
    for w in m["waivers"]:
        assert set(w["items"]) <= set(images["image_id"]) and w["justification"].strip()


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize(
    "table",
    ["images", "checkpoints", "gcps", "flights", "cameras", "aerotriangulation", "manual_checks"],
)
def test_table_has_only_spec_columns_and_its_required_ones(name: str, table: str) -> None:
    df = _table(name, table)
    allowed = SPEC[table]["columns"]
    required = {c for c, spec in allowed.items() if spec.get("required")}
    assert set(df.columns) <= set(allowed), f"unknown columns {set(df.columns) - set(allowed)}"
    assert required <= set(df.columns)
    assert len(df) > 0
    assert (df[sorted(required)] != "").all().all(), "a required value is empty"
    for column, spec in allowed.items():
        if column in df and spec["type"] == "number":
            assert _num(df[column]).notna().sum() > 0
            _num(df[column])  # raises if a value is not numeric
        if column in df and spec["type"] == "bool":
            assert set(df[column]) <= {"true", "false", ""}
    id_col = SPEC[table]["id"]
    if id_col:
        assert df[id_col].is_unique


@pytest.mark.parametrize("name", NAMES)
def test_rasters_match_their_reported_statistics_and_location(name: str) -> None:
    images, root = _table(name, "images"), EXAMPLES / name
    polygons = {b["id"]: Polygon(b["polygon"]) for b in _manifest(name)["blocks"]}
    missing = {
        i for d in _expected(name)["defects"] if d["kind"] == "file_missing" for i in d["items"]
    }
    opened = 0
    for row in images.itertuples(index=False):
        path = root / row.file
        if row.image_id in missing:
            assert not path.exists()
            continue
        with rasterio.open(path) as ds:
            assert ds.crs.to_epsg() == 25832 and ds.res == (GSD, GSD)
            assert (ds.count, ds.dtypes[0], ds.nodata) == (4, "uint8", 0)
            assert ds.compression.name.lower() == "deflate" and not ds.profile.get("tiled")
            arr = ds.read().astype(np.float64)
            centre = ds.xy(ds.height // 2, ds.width // 2)
        opened += 1
        v = arr.ravel()
        assert float(row.mean_dn) == pytest.approx(v.mean(), abs=0.005 + 1e-9)
        assert float(row.std_dn) == pytest.approx(v.std(), abs=0.005 + 1e-9)
        assert (float(row.min_dn), float(row.max_dn)) == (v.min(), v.max())
        assert float(row.saturation_low) == pytest.approx(np.mean(v == 0) * 100, abs=5e-4 + 1e-9)
        assert float(row.saturation_high) == pytest.approx(np.mean(v == 255) * 100, abs=5e-4 + 1e-9)
        exposure = (float(row.exposure_x), float(row.exposure_y))
        assert math.dist(centre, exposure) < 1.0
        assert polygons[row.block].contains(Point(exposure))
    assert opened == len(images) - len(missing)


# --------------------------------------------------------------------------- what they claim
def _block_rmse(name: str) -> dict[str, dict[str, float]]:
    """Per block, from the checker's measurements: RMSE with justified exclusions out, and with every
    requested exclusion out (as the contractor computed its reported figure)."""
    cp = _external(name)
    dx = _num(cp["x"]) - _num(cp["x_ref"])
    dy = _num(cp["y"]) - _num(cp["y_ref"])
    excluded = cp["excluded"] == "true"
    justified = excluded & (cp["exclusion_reason"].str.strip() != "")
    out = {}
    for block in sorted(set(cp["block"])):
        inb = cp["block"] == block
        kept, contractor = inb & ~justified, inb & ~excluded
        out[block] = {
            "n": int(kept.sum()),
            "rmse_x": float(np.sqrt(np.mean(dx[kept] ** 2))),
            "rmse_y": float(np.sqrt(np.mean(dy[kept] ** 2))),
            "contractor_x": float(np.sqrt(np.mean(dx[contractor] ** 2))),
            "contractor_y": float(np.sqrt(np.mean(dy[contractor] ** 2))),
            "limit_x": 3 * float(np.sqrt(np.mean(dx[inb] ** 2))),
        }
    return out


def _findings(name: str) -> set[tuple[str, str]]:
    """(defect kind, item) for every guideline breach a checker could find in the data."""
    m, root, tol = _manifest(name), EXAMPLES / name, 0.5
    assert m["tender"]["parameters"]["tolerance_xy"] == {"value": tol, "unit": "m"}
    found: set[tuple[str, str]] = set()
    img = _table(name, "images")
    sat = np.maximum(_num(img["saturation_low"]), _num(img["saturation_high"]))
    cv = _num(img["std_dn"]) / 256 * 100
    for i, row in img.iterrows():
        item = row["image_id"]
        checks = {
            "saturation_high": sat[i] > 0.5,
            "contrast_out_of_range": not 10 <= cv[i] <= 20,
            "cloud_cover_above_max": float(row["cloud_cover"]) > 10,
            "roll_above_max": abs(float(row["roll"])) > 3,
            "sun_below_min": float(row["sun_elevation"]) < 30,
            "missing_field": row["flying_height"] == "",
            "file_missing": not (root / row["file"]).is_file(),
            "file_name_space": " " in row["file"],
        }
        found |= {(kind, item) for kind, hit in checks.items() if hit}
    manual = _checker(name)["manual_checks"]  # the external QC's verdicts
    absent = {i for kind, i in found if kind == "file_missing"}  # its 'fail' row is a consequence
    found |= {
        ("manual_check_fail", r["item"])
        for r in manual
        if r["verdict"] == "fail" and r["item"] not in absent
    }
    assert {r["verdict"] for r in manual} <= {"pass", "fail"}
    cells = _grid_cells(name)  # and its marks on the inspection grid (any defect class)
    codes = [
        c
        for c in cells.columns
        if c
        not in (
            "cell_id",
            "image_id",
            "image_file",
            "image_sha256",
            "col",
            "row",
            "inspected",
            "comment",
            "inspector",
            "date",
        )
    ]
    found |= {
        ("manual_check_fail", i) for i in cells[cells[codes].astype(int).any(axis=1)]["image_id"]
    }
    cp = _external(name)
    found |= {
        ("unjustified_exclusion", r["point_id"])
        for _, r in cp.iterrows()
        if r["excluded"] == "true" and not r["exclusion_reason"].strip()
    }
    reported = {b["id"]: b["reported"] for b in m["blocks"]}
    for block, r in _block_rmse(name).items():
        if max(r["rmse_x"], r["rmse_y"]) > tol:
            found.add(("rmse_above_tolerance", block))
        if r["n"] < 20:
            found.add(("too_few_checkpoints", block))
        for axis in "xy":
            if (
                abs(reported[block][f"rmse_{axis}"]["value"] - r[f"contractor_{axis}"])
                > 0.005 + 1e-9
            ):
                found.add(("reported_rmse_mismatch", block))
    own = _table(
        name, "checkpoints"
    )  # the contractor's internal QC (JRC §12.5): does it see what we see?
    for block in sorted(set(own["block"])):
        inb = own[own["block"] == block]
        rx, ry = (
            float(np.sqrt(np.mean((_num(inb[a]) - _num(inb[f"{a}_ref"])) ** 2))) for a in "xy"
        )
        ext = _block_rmse(name)[block]
        if (rx <= tol and ry <= tol) != (ext["rmse_x"] <= tol and ext["rmse_y"] <= tol):
            found.add(("internal_qc_disagrees", block))
    return found


def test_pass_example_meets_the_guidelines_except_its_waiver() -> None:
    waived = {
        ("contrast_out_of_range", i) for w in _checker("aerial-pass")["waivers"] for i in w["items"]
    }
    assert _findings("aerial-pass") == waived
    assert (
        _expected("aerial-pass")["verdict"] == "accepted"
        and not _expected("aerial-pass")["defects"]
    )


def test_pass_example_blocks_use_realistic_accuracy_and_justified_blunders() -> None:
    cp = _external("aerial-pass")
    rmse = _block_rmse("aerial-pass")
    reported = {b["id"]: b["reported"] for b in _manifest("aerial-pass")["blocks"]}
    for block, r in rmse.items():
        assert 0.2 <= r["rmse_x"] <= 0.4 and 0.2 <= r["rmse_y"] <= 0.4 and r["n"] >= 20
        assert reported[block]["rmse_x"]["value"] == pytest.approx(r["rmse_x"], abs=0.005 + 1e-9)
        assert reported[block]["rmse_y"]["value"] == pytest.approx(r["rmse_y"], abs=0.005 + 1e-9)
    blunders = cp[cp["excluded"] == "true"]
    assert len(blunders) == 1  # one documented blunder, beyond 3 x RMSE of all its block's points
    b = blunders.iloc[0]
    assert abs(float(b["x"]) - float(b["x_ref"])) > rmse[b["block"]]["limit_x"]
    gcp = _table("aerial-pass", "gcps")
    g = np.column_stack([_num(gcp["x"]), _num(gcp["y"])])
    c = np.column_stack([_num(cp["x_ref"]), _num(cp["y_ref"])])
    assert np.min(np.linalg.norm(c[:, None, :] - g[None, :, :], axis=2)) >= 300.0


def test_fail_example_breaks_exactly_the_documented_rules() -> None:
    expected = _expected("aerial-fail")
    documented = {(d["kind"], i) for d in expected["defects"] for i in d["items"]}
    assert expected["verdict"] == "rejected"
    assert _findings("aerial-fail") == documented
    for d in expected["defects"]:
        assert d["clause"]["document"] == "JRC EUR 23638 EN" and d["clause"]["section"]
        assert (EXAMPLES / "aerial-fail" / d["file"]).is_file()
        if d["file"].endswith(".csv") and d["kind"] not in (
            "rmse_above_tolerance",
            "too_few_checkpoints",
            "internal_qc_disagrees",
        ):  # whole blocks
            df = pd.read_csv(EXAMPLES / "aerial-fail" / d["file"], dtype=str, keep_default_na=False)
            id_col = "point_id" if "point_id" in df else ("item" if "item" in df else "image_id")
            assert sorted(df.iloc[[r - 1 for r in d["rows"]]][id_col]) == sorted(d["items"])


def test_fail_example_measured_values_agree_with_the_data() -> None:
    defects = {d["kind"]: d for d in _expected("aerial-fail")["defects"]}
    rmse = _block_rmse("aerial-fail")
    assert defects["rmse_above_tolerance"]["measured"]["value"] == pytest.approx(
        rmse["B02"]["rmse_y"], abs=5e-4
    )
    assert defects["too_few_checkpoints"]["measured"]["value"] == rmse["B03"]["n"] < 20
    reported = {b["id"]: b["reported"] for b in _manifest("aerial-fail")["blocks"]}
    assert abs(reported["B02"]["rmse_y"]["value"] - rmse["B02"]["rmse_y"]) > 0.1
    assert reported["B01"]["rmse_x"]["value"] == pytest.approx(
        rmse["B01"]["contractor_x"], abs=0.005
    )
    with rasterio.open(EXAMPLES / "aerial-fail" / defects["saturation_high"]["raster"]) as ds:
        arr = ds.read()
    assert all(np.mean(band == 255) * 100 > 0.5 for band in arr)
    assert defects["saturation_high"]["measured"]["value"] == pytest.approx(
        np.mean(arr == 255) * 100, abs=5e-4
    )
