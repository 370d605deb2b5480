"""The visual inspection grid (issue 29 item 3; inspection/grid.py, docs/CHECKER.md).

`orthospec inspect grid` writes the GeoPackage, the test marks it as a checker would in QGIS (pyogrio,
or the library's ``mark_cells``), `check` reads the marks. Expected counts and areas come from the
rasters' bounds read with rasterio and plain arithmetic; edits are real GeoPackage rewrites.
"""

from __future__ import annotations

import hashlib
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pyogrio
import pytest
import rasterio
from click.testing import CliRunner
from pyogrio import raw
from tests.checking import CHECKERS, DATE, EXAMPLES, ROOT, check_with, records

from orthospec.cli.main import cli
from orthospec.errors import OrthospecError
from orthospec.inspection.defects import catalogue
from orthospec.inspection.grid import fields, mark_cells

SEED = ROOT.parent / "shared" / "seeds" / "002_7421c4ca450e31c6.txt"


def _grid(delivery: Path, out: Path, *extra: str) -> Any:
    return CliRunner().invoke(
        cli(), ["inspect", "grid", str(delivery), "--cell", "8", "--out", str(out), *extra]
    )


def _cells(path: Path) -> dict[str, np.ndarray]:
    meta, fids, _, values = raw.read(path, layer="cells", return_fids=True)
    return {
        "fid": np.asarray(fids),
        **{str(f): v for f, v in zip(meta["fields"], values, strict=True)},
    }


def _folder(tmp_path: Path, name: str = "aerial-pass") -> tuple[Path, Path]:
    d, c = tmp_path / name, tmp_path / f"checker-{name}"
    shutil.copytree(EXAMPLES / name, d)
    shutil.copytree(CHECKERS / name, c)
    return d, c


def _by(doc: dict[str, Any], rule: str) -> dict[str, dict[str, Any]]:
    return {r["item"]: r for r in records(doc) if r["rule"] == rule}


def test_the_defect_classes_quote_the_seed_verbatim() -> None:
    seed = " ".join(SEED.read_text(encoding="utf-8").split())
    cat = catalogue()
    assert cat.codes == (
        "smear",
        "seam",
        "ghosting",
        "colour_break",
        "haze",
        "cloud",
        "saturation",
        "missing_data",
        "blur",
        "artefact",
    )
    assert all(" ".join(d.quote.split()) in seed for d in cat.defects)
    assert set(cat.rules["JRC-T6-ORTHO-INSPECTION"]) == set(cat.codes)


def test_inspect_grid_writes_the_cells_over_the_images_deterministically(tmp_path: Path) -> None:
    res = _grid(EXAMPLES / "aerial-pass", tmp_path / "a.gpkg")
    assert res.exit_code == 0, res.output
    assert _grid(EXAMPLES / "aerial-pass", tmp_path / "b.gpkg").exit_code == 0
    assert (tmp_path / "a.gpkg").read_bytes() == (tmp_path / "b.gpkg").read_bytes()
    info = pyogrio.read_info(tmp_path / "a.gpkg", layer="cells")
    assert tuple(info["fields"]) == fields() and info["geometry_type"] == "Polygon"
    cells = _cells(tmp_path / "a.gpkg")
    expected = 0
    for tif in sorted((EXAMPLES / "aerial-pass" / "images").glob("*.tif")):
        with rasterio.open(tif) as ds:
            b = ds.bounds
            sha = hashlib.sha256(tif.read_bytes()).hexdigest()
        n = (math.ceil(b.right / 8) - math.floor(b.left / 8)) * (
            math.ceil(b.top / 8) - math.floor(b.bottom / 8)
        )
        expected += n
        mine = cells["image_id"] == tif.stem
        assert int(mine.sum()) == n and set(cells["image_sha256"][mine]) == {sha}
    assert len(cells["fid"]) == expected
    assert f"{len(cells['fid'])} cells of 8m over 30 images" in res.output
    # a sample of images: only those are gridded
    (tmp_path / "s.csv").write_text(
        "item,scope\nF01_0101,image\nF02_0203,image\n", encoding="utf-8"
    )
    assert (
        _grid(
            EXAMPLES / "aerial-pass", tmp_path / "s.gpkg", "--sample", str(tmp_path / "s.csv")
        ).exit_code
        == 0
    )
    assert set(_cells(tmp_path / "s.gpkg")["image_id"]) == {"F01_0101", "F02_0203"}


@pytest.mark.parametrize("cell", ["0.001", "1e-320", "0.0005px"])
def test_a_cell_far_too_small_is_refused_before_any_cell_is_built(
    tmp_path: Path, cell: str
) -> None:
    """30 extracts of 32 m: at 1 mm that is about 3e10 cells; refused from the bounds alone, in well under a
    second (the first version built the polygons of a whole image before counting)."""
    import time

    t0 = time.perf_counter()
    res = CliRunner().invoke(
        cli(),
        [
            "inspect",
            "grid",
            str(EXAMPLES / "aerial-pass"),
            "--cell",
            cell,
            "--out",
            str(tmp_path / "tiny.gpkg"),
        ],
    )
    assert res.exit_code != 0 and "more than 2,000,000 cells" in str(res.exception or res.output)
    assert not (tmp_path / "tiny.gpkg").exists() and time.perf_counter() - t0 < 30


def test_inspect_grid_never_writes_into_the_delivery(tmp_path: Path) -> None:
    d, _ = _folder(tmp_path)
    res = _grid(d, d / "inspection.gpkg")
    assert res.exit_code != 0 and not (d / "inspection.gpkg").exists()
    assert "inside the delivery" in str(res.exception or res.output)


def test_marked_cells_give_the_image_verdicts_with_the_cells_as_evidence(tmp_path: Path) -> None:
    d, c = _folder(tmp_path)
    cells = _cells(c / "inspection.gpkg")
    f0101 = [
        str(i)
        for i, img in zip(cells["cell_id"], cells["image_id"], strict=True)
        if img == "F01_0101"
    ]
    mark_cells(
        c / "inspection.gpkg",
        {f0101[0]: {"haze": 1, "comment": "haze bank over the field"}, f0101[1]: {"smear": 1}},
    )
    doc = check_with(d, "jrc-v3", checker=c, date=DATE).document
    art = _by(doc, "JRC-6.3-ARTEFACTS")["F01_0101"]
    # haze is one of JRC-6.3-ARTEFACTS' classes, smear is not (Table 11): one cell names it
    assert (
        art["verdict"] == "warn"
        and f0101[0] in art["message"]
        and "haze bank over the field" in art["message"]
    )
    assert f0101[1] not in art["message"]
    grid_ev = [e for e in art["evidence"] if e["file"] == "checker:inspection.gpkg"]
    assert (
        grid_ev
        and grid_ev[0]["sha256"] == hashlib.sha256((c / "inspection.gpkg").read_bytes()).hexdigest()
    )
    t6 = _by(doc, "JRC-T6-ORTHO-INSPECTION")["F01_0101"]
    assert t6["verdict"] == "warn" and f0101[0] in t6["message"] and f0101[1] in t6["message"]
    assert _by(doc, "JRC-6.3-ARTEFACTS")["F01_0102"]["verdict"] == "pass"
    assert _by(doc, "JRC-12.3-INSPECTED-SHARE")[doc["delivery"]["id"]]["verdict"] == "pass"
    marked = {x["cell_id"]: x for x in doc["details"]["inspection"]["cells"]}
    assert marked[f0101[0]]["defects"] == ["haze"] and marked[f0101[0]]["block"] == "B01"


def test_the_inspected_share_counts_the_area_of_the_inspected_cells(tmp_path: Path) -> None:
    d, c = _folder(tmp_path)
    meta, _, geometry, values = raw.read(c / "inspection.gpkg", layer="cells")
    import shapely

    col = dict(zip(meta["fields"], values, strict=True))
    areas = shapely.area(shapely.from_wkb(geometry))
    todo = [
        str(i) for i, img in zip(col["cell_id"], col["image_id"], strict=True) if img == "F02_0101"
    ]
    mark_cells(c / "inspection.gpkg", {i: {"inspected": 0} for i in todo})
    left = np.isin(col["cell_id"].astype(str), todo)
    share = float(areas[~left].sum() / areas.sum() * 100.0)
    doc = check_with(d, "jrc-v3", checker=c, date=DATE).document
    rec = _by(doc, "JRC-12.3-INSPECTED-SHARE")[doc["delivery"]["id"]]
    assert rec["verdict"] == "fail" and rec["measured"]["value"] == pytest.approx(share, rel=1e-9)
    miss = _by(doc, "JRC-6.3-ARTEFACTS")["F02_0101"]
    assert (
        miss["verdict"] == "missing"
        and f"{len(todo)} of {len(todo)} cells of F02_0101 not inspected" in miss["message"]
    )
    assert doc["verdict"] != "accepted"


def test_a_mark_on_an_image_changed_since_is_not_carried_over(tmp_path: Path) -> None:
    d, c = _folder(tmp_path)
    shutil.copyfile(
        d / "images" / "F01_0102.tif", d / "images" / "F01_0101.tif"
    )  # other pixels under its id
    doc = check_with(d, "jrc-v3", checker=c, date=DATE).document
    rec = _by(doc, "JRC-T6-ORTHO-INSPECTION")["F01_0101"]
    assert rec["verdict"] == "missing" and "changed or swapped since" in rec["message"]
    assert _by(doc, "JRC-12.3-INSPECTED-SHARE")[doc["delivery"]["id"]]["verdict"] == "fail"


def _rewrite(path: Path, change: Any) -> None:
    """Rewrite the cells layer after ``change(meta, fields, values, geometry)`` (what a GIS edit does)."""
    layers = {}
    for layer in ("cells", "images", "grid"):
        meta, _, geometry, values = raw.read(path, layer=layer)
        layers[layer] = (
            meta,
            [str(f) for f in meta["fields"]],
            [np.asarray(v) for v in values],
            geometry,
        )
    meta, names, values, geometry = layers["cells"]
    names, values, geometry = change(names, values, geometry)
    path.unlink()
    raw.write(
        path,
        geometry,
        values,
        names,
        crs=meta["crs"],
        geometry_type="Polygon",
        driver="GPKG",
        layer="cells",
    )
    for layer in ("images", "grid"):
        _, n, v, _ = layers[layer]
        if layer == "grid" and getattr(change, "delivery", None):
            v = [v[0], np.where(v[0] == "delivery", change.delivery, v[1]).astype(object)]
        if layer == "grid" and getattr(change, "cell", None):
            v = [v[0], np.where(v[0] == "cell", change.cell, v[1]).astype(object)]
        raw.write(path, None, v, n, driver="GPKG", layer=layer, append=True, geometry_type=None)


def _added_cell(names: list[str], values: list[np.ndarray], geometry: np.ndarray) -> Any:
    import shapely

    i = 0
    new = [np.append(v, v[i]) for v in values]
    new[names.index("col")][-1] = int(values[names.index("col")][i]) + 500  # far outside the image
    new[names.index("cell_id")][-1] = (
        f"{values[names.index('image_id')][i]}/{new[names.index('col')][-1]}/"
        f"{values[names.index('row')][i]}"
    )
    g = shapely.from_wkb(geometry[i])
    moved = shapely.affinity.translate(g, 4000.0, 0.0)
    return names, new, np.append(geometry, shapely.to_wkb(moved))


def _unknown_field(names: list[str], values: list[np.ndarray], geometry: np.ndarray) -> Any:
    return [*names, "scratch"], [*values, np.zeros(len(values[0]), dtype=np.int32)], geometry


def _bad_mark(names: list[str], values: list[np.ndarray], geometry: np.ndarray) -> Any:
    values[names.index("haze")][3] = 2
    return names, values, geometry


def _other_image(names: list[str], values: list[np.ndarray], geometry: np.ndarray) -> Any:
    ids = values[names.index("image_id")].astype(object)
    ids[5] = "F09_0909"
    values[names.index("image_id")] = ids
    return names, values, geometry


def _other_delivery(names: list[str], values: list[np.ndarray], geometry: np.ndarray) -> Any:
    return names, values, geometry


_other_delivery.delivery = "D-2026-999"  # type: ignore[attr-defined]


def _deleted_cell(names: list[str], values: list[np.ndarray], geometry: np.ndarray) -> Any:
    """A cell the checker did not inspect, deleted (its area would vanish from the inspected share)."""
    keep = np.ones(len(values[0]), dtype=bool)
    keep[7] = False
    return names, [v[keep] for v in values], geometry[keep]


def _tiny_cell_size(names: list[str], values: list[np.ndarray], geometry: np.ndarray) -> Any:
    return names, values, geometry


_tiny_cell_size.cell = "0.0001m"  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    "edit, words",
    [
        (_added_cell, ["layer cells: fid", "is not a cell of image", "added or moved"]),
        (_unknown_field, ["unknown field 'scratch'", "defect class of specs/inspection.yaml"]),
        (
            _bad_mark,
            ["fid 4: field 'haze'", "2 is not a mark of defect class haze", "unknown defect codes"],
        ),
        (_other_image, ["fid 6: field 'image_id'", "F09_0909", "did not sample"]),
        (_other_delivery, ["written for delivery D-2026-999", "this delivery is D-2026-014"]),
        (_deleted_cell, ["layer cells: cell", "is missing (1 of its", "cells deleted)"]),
        (
            _tiny_cell_size,
            [
                "layer grid: cell size 0.0001m over image",
                "more than 2,000,000",
                "cell size was edited",
            ],
        ),
    ],
)
def test_a_grid_edited_beyond_marks_is_refused_naming_file_cell_and_field(
    tmp_path: Path, edit: Any, words: list[str]
) -> None:
    d, c = _folder(tmp_path)
    _rewrite(c / "inspection.gpkg", edit)
    with pytest.raises(OrthospecError) as exc:
        check_with(d, "jrc-v3", checker=c, date=DATE)
    msg = str(exc.value)
    assert "inspection.gpkg" in msg and all(w in msg for w in words), msg
    from orthospec.cli.main import main

    with pytest.raises(SystemExit) as ex:  # through `orthospec check`: exit 2, nothing written
        main(
            [
                "check",
                str(d),
                "-p",
                "jrc-v3",
                "--checker",
                str(c),
                "--out",
                str(tmp_path / "out"),
                "--format",
                "json",
            ]
        )
    assert ex.value.code == 2 and not (tmp_path / "out").exists()
