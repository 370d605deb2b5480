"""Issue 25, "measured, not declared": each observation as a regression test on a copy of a shipped example.

A contractor who edits what the delivery declares (tables, manifest) or writes files that do not
match them must not get a failing delivery ACCEPTED. Each case copies an example into tmp_path, makes
real edits there (CSV rows, delivery.yaml, GeoTIFFs rewritten with rasterio), has the checker's fixed
file (examples/checker/<example>.yaml) re-signed on what was delivered (tests/checking.py ``resigned``;
the checker signs what it receives and judges only the items it received), and runs the real check
with profile jrc-v3 (or the example tender) and ``--date 2026-11-21``. Each asserts the verdict the
guideline supports and the rule that carries it. Checked to fail before the fix: run this file with
``PYTHONPATH=<a checkout of main at 95a2ffd>/src``: every case but the planted-alone baselines is
ACCEPTED there.
"""

from __future__ import annotations

import csv
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rasterio
import yaml
from affine import Affine
from tests.checking import (
    CHECKERS,
    DATE,
    EXAMPLES,
    ROOT,
    check_with,
    manifest,
    read_table,
    records,
    resigned,
    write_manifest,
    write_table,
)

from orthospec.errors import OrthospecError

TENDER = ROOT / "examples" / "specs" / "tender-example.yaml"

Edit = Callable[[Path], None]


# --- edits ------------------------------------------------------------------------------------------


def _rewrite(
    path: Path,
    *,
    pixels: np.ndarray | None = None,
    transform: Affine | None = None,
    like: Path | None = None,
) -> None:
    """Rewrite a GeoTIFF in place: new pixels and/or transform (profile of ``like`` or of itself)."""
    with rasterio.open(like or path) as src:
        profile, data, colours = src.profile, src.read(), src.colorinterp
    if pixels is not None:
        data = pixels
    if transform is not None:
        profile["transform"] = transform
    path.unlink(missing_ok=True)
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(data)
        dst.colorinterp = colours


def _read(path: Path) -> tuple[np.ndarray, Affine]:
    with rasterio.open(path) as src:
        return src.read(), src.transform


def _table(
    name: str, fn: Callable[[list[str], list[dict[str, str]]], list[dict[str, str]] | None]
) -> Edit:
    def edit(d: Path) -> None:
        header, rows = read_table(d, name)
        out = fn(header, rows)
        write_table(d, name, header, rows if out is None else out)

    return edit


def _chain(*edits: Edit) -> Edit:
    def edit(d: Path) -> None:
        for e in edits:
            e(d)

    return edit


def _set(table: str, image: str, **values: str) -> Edit:
    def fn(header: list[str], rows: list[dict[str, str]]) -> None:
        for r in rows:
            if r[header[0]] == image:
                r.update(values)

    return _table(table, fn)


def _one_gcp(scene: str) -> Edit:
    """The scene keeps one GCP: its count declared 1 and one row left in gcps.csv (JRC Table 9 VHR/RPC: 2-4)."""

    def fn(header: list[str], rows: list[dict[str, str]]) -> list[dict[str, str]]:
        mine = [r for r in rows if r["point_id"].startswith(f"{scene}-")]
        return [r for r in rows if r not in mine[1:]]

    return _chain(_set("scenes", scene, gcp_count="1"), _table("gcps", fn))


def _every_raster(
    fn: Callable[[np.ndarray, Affine], tuple[np.ndarray | None, Affine | None]],
) -> Edit:
    def edit(d: Path) -> None:
        _, rows = read_table(d, "images")
        for r in rows:
            path = d / r["file"]
            data, t = _read(path)
            pixels, transform = fn(data, t)
            _rewrite(path, pixels=pixels, transform=transform)

    return edit


def _decimate_to(pixel: float) -> Edit:
    """Every raster's geotransform says `pixel` m (the same pixels over a larger ground): the tables still
    say 0.25 m."""
    return _every_raster(lambda data, t: (None, Affine(pixel, 0.0, t.c, 0.0, -pixel, t.f)))


def _shift_all(east: float) -> Edit:
    return _every_raster(lambda data, t: (None, Affine(t.a, t.b, t.c + east, t.d, t.e, t.f)))


def _one_pixel_changed(data: np.ndarray, k: int = 0) -> np.ndarray:
    out = data.copy()
    out[:, 64 + k % 7, 64] = np.clip(out[:, 64 + k % 7, 64].astype(int) + 9, 1, 254).astype(
        out.dtype
    )
    return out


def _drop_strip_f02_02(d: Path) -> None:
    header, rows = read_table(d, "images")
    gone = [r for r in rows if r["image_id"].startswith("F02_02")]
    for r in gone:
        (d / r["file"]).unlink()
    write_table(d, "images", header, [r for r in rows if r not in gone])


def _camera_format_times(factor: int) -> Edit:
    def fn(header: list[str], rows: list[dict[str, str]]) -> None:
        for r in rows:
            r["format_across_px"] = str(int(r["format_across_px"]) * factor)
            r["format_along_px"] = str(int(r["format_along_px"]) * factor)

    return _table("cameras", fn)


def _strip_f02_02_as_copies(*, own_place: bool) -> Edit:
    """Keep strip F02_02's rows but deliver one-pixel-changed copies of strip F02_01's rasters as its files,
    georeferenced where F02_01's are (a plain copy) or where F02_02's were (``own_place``)."""

    def edit(d: Path) -> None:
        for k in range(1, 6):
            src, dst = d / f"images/F02_01{k:02d}.tif", d / f"images/F02_02{k:02d}.tif"
            data, t_src = _read(src)
            _, t_dst = _read(dst)
            _rewrite(
                dst,
                pixels=_one_pixel_changed(data, k),
                transform=t_dst if own_place else t_src,
                like=src,
            )

    return edit


def _scene_under_other_georeference(d: Path) -> None:
    """S01_SC2.tif becomes S01_SC1's pixels under S01_SC2's georeference (gdal_translate -a_ullr), and the
    S01_SC2 row's statistics are copied from S01_SC1's row."""
    data, _ = _read(d / "images/S01_SC1.tif")
    _, t2 = _read(d / "images/S01_SC2.tif")
    _rewrite(d / "images/S01_SC2.tif", pixels=data, transform=t2, like=d / "images/S01_SC1.tif")
    header, rows = read_table(d, "images")
    sc1 = next(r for r in rows if r["image_id"] == "S01_SC1")
    for r in rows:
        if r["image_id"] == "S01_SC2":
            for k in (
                "mean_dn",
                "std_dn",
                "min_dn",
                "max_dn",
                "saturation_low",
                "saturation_high",
                "cloud_cover",
            ):
                r[k] = sc1[k]
    write_table(d, "images", header, rows)


def _two_images_unreadable(d: Path) -> None:
    """F01_0101 and F01_0102 truncated: two images rejected (JRC-9.2-T7-READABLE), 2 / 30 = 6.7 % > 5 %."""
    for name in ("F01_0101", "F01_0102"):
        path = d / f"images/{name}.tif"
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 3])


def _pad_with_copies(n: int) -> Edit:
    """Pad the images table with ``n`` one-pixel-changed copies of good images (own files, own rows)."""

    def edit(d: Path) -> None:
        header, rows = read_table(d, "images")
        good = [r for r in rows if r["image_id"].startswith("F03_")][:n]
        for k, r in enumerate(good):
            new_id = f"{r['flight_id']}_c{90 + k:04d}"
            rel = f"images/{new_id}.tif"
            data, t = _read(d / r["file"])
            shutil.copyfile(d / r["file"], d / rel)
            _rewrite(d / rel, pixels=_one_pixel_changed(data, k), transform=t, like=d / r["file"])
            rows.append(
                {
                    **r,
                    "image_id": new_id,
                    "file": rel,
                    "photo_number": f"{90 + k:04d}",
                    "exposure_y": f"{float(r['exposure_y']) + 0.5:.2f}",
                }
            )
        write_table(d, "images", header, rows)

    return edit


def _dem_delivered_declared_false(d: Path) -> None:
    """A DEM file and a dem table naming it are delivered; product.dem_delivered says false; B01's check point
    heights are 1 m off (RMSEz 1 m against tolerance_z 0.5 m)."""
    (d / "dem").mkdir()
    with rasterio.open(
        d / "dem/dem_b01.tif",
        "w",
        driver="GTiff",
        width=70,
        height=72,
        count=1,
        dtype="float32",
        crs="EPSG:25832",
        transform=Affine(100.0, 0, 500_000.0, 0, -100.0, 5_407_200.0),
    ) as dst:
        dst.write(np.full((1, 72, 70), 411.0, dtype=np.float32))
    (d / "tables/dem.csv").write_text(
        "dem_id,block,file,source,grid_spacing,rmse_z,checkpoints\n"
        "DEM-01,B01,dem/dem_b01.tif,contractor DEM 2026,5,0.3,25\n",
        encoding="utf-8",
    )
    m = manifest(d)
    m["tables"]["dem"] = "tables/dem.csv"
    m["product"]["dem_delivered"] = False
    write_manifest(d, m)
    header, rows = read_table(d, "checkpoints")
    header += [c for c in ("z", "z_ref") if c not in header]
    for r in rows:
        r.setdefault("z", "")
        r.setdefault("z_ref", "")
        if r["block"] == "B01":
            r["z"], r["z_ref"] = "412.0", "411.0"
    write_table(d, "checkpoints", header, rows)


def _checker_heights_1m_off_in_b01(folder: Path) -> None:
    """The checker measured heights on its B01 check points: each 1 m above the reference (RMSEz 1 m)."""
    table = folder / "tables" / "checkpoints.csv"
    with table.open(encoding="utf-8", newline="") as f:
        r = csv.DictReader(f)
        header, rows = list(r.fieldnames or []), list(r)
    header += [c for c in ("z", "z_ref") if c not in header]
    for row in rows:
        row.setdefault("z", "")
        row.setdefault("z_ref", "")
        if row["block"] == "B01":
            row["z"], row["z_ref"] = "412.0", "411.0"
    with table.open("w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def _dem_table_removed(d: Path) -> None:
    """The satellite dem table removed (manifest entry and file) while the scenes record dem_accuracy and
    dem_grid_size (the DEM they were orthorectified with)."""
    m = manifest(d)
    del m["tables"]["dem"]
    write_manifest(d, m)
    (d / "tables/dem.csv").unlink()


def _clouds_in_pixels(image: str, share: float) -> Edit:
    """Paint a bright, white cloud over about ``share`` of ``image``'s pixels; its row keeps cloud_cover 0 and
    its statistics are updated to the new pixels (so nothing declared gives it away)."""

    def edit(d: Path) -> None:
        from scipy.ndimage import gaussian_filter

        path = d / f"images/{image}.tif"
        data, _ = _read(path)
        field = gaussian_filter(np.random.default_rng(5).standard_normal(data.shape[1:]), 10.0)
        cloud = field > np.quantile(field, 1.0 - share)
        out = data.copy()
        out[:, cloud] = 236
        _rewrite(path, pixels=out)
        valid = out.astype(float)
        header, rows = read_table(d, "images")
        for r in rows:
            if r["image_id"] == image:
                r.update(
                    mean_dn=f"{valid.mean():.2f}",
                    std_dn=f"{valid.std():.2f}",
                    min_dn=f"{valid.min():.0f}",
                    max_dn=f"{valid.max():.0f}",
                )
        write_table(d, "images", header, rows)

    return edit


# --- running ----------------------------------------------------------------------------------------


def _delivered_items(d: Path) -> set[str]:
    import csv

    items = {b["id"] for b in manifest(d)["blocks"]}
    for table in (d / "tables").glob("*.csv"):
        with table.open(encoding="utf-8", newline="") as f:
            items.update(row[0] for row in list(csv.reader(f))[1:] if row)
    return items


def _run(
    example: str,
    edit: Edit,
    tmp_path: Path,
    *,
    profile: str | Path = "jrc-v3",
    parameters: dict[str, Any] | None = None,
    checker_edit: Edit | None = None,
) -> tuple[int, dict[str, Any] | None, str]:
    d = tmp_path / example
    shutil.copytree(EXAMPLES / example, d)
    edit(d)
    path = resigned(CHECKERS / f"{example}.yaml", d, tmp_path / f"checker-{example}.yaml")
    if checker_edit is not None:
        checker_edit(
            path.parent
        )  # the checker's own measurements (its folder's tables/checkpoints.csv)
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    items = _delivered_items(d)
    doc["manual_checks"] = [
        m for m in doc.get("manual_checks") or [] if m["item"] == "*" or m["item"] in items
    ]
    if parameters:
        doc.setdefault("parameters", {}).update(parameters)
    path.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8")
    try:
        result = check_with(d, profile, checker=path, date=DATE)
    except OrthospecError as exc:
        return 2, None, str(exc)
    return (0 if result.accepted else 1), result.document, ""


def _verdicts(doc: dict[str, Any], rule: str) -> dict[str, str]:
    return {r["item"]: r["verdict"] for r in records(doc) if r["rule"] == rule}


def _record(doc: dict[str, Any], rule: str, item: str) -> dict[str, Any]:
    return next(r for r in records(doc) if r["rule"] == rule and r["item"] == item)


def _rejected_for(doc: dict[str, Any], rule: str, items: set[str], verdict: str = "fail") -> None:
    got = _verdicts(doc, rule)
    assert {i for i in items if got.get(i) == verdict} == items, {i: got.get(i) for i in items}


# --- the observations -------------------------------------------------------------------------------


def test_planted_vhr_gcp_shortage_alone_is_rejected(tmp_path: Path) -> None:
    """Baseline of the class cases: S02_SC1 (VHR, vendor RPC) with one GCP breaks Table 9 (2-4 per scene)."""
    code, doc, err = _run("satellite-pass", _one_gcp("S02_SC1"), tmp_path)
    assert code == 1 and doc is not None, err
    assert _verdicts(doc, "JRC-T9-GCP-VHR-RPC")["S02_SC1"] == "fail"


@pytest.mark.parametrize(
    "declare",
    [
        pytest.param(
            _chain(_set("scenes", "S02_SC1", input_pixel_size="4", resolution_class="HR")),
            id="input-pixel-4m",
        ),
        pytest.param(
            _chain(
                _set("scenes", "S02_SC1", input_pixel_size="", resolution_class="HR"),
                _set("images", "S02_SC1", gsd="3.5"),
            ),
            id="images-gsd-3.5m",
        ),
    ],
)
def test_resolution_class_comes_from_the_raster_not_the_declaration(
    tmp_path: Path, declare: Edit
) -> None:
    """Declaring 4 m input pixels (or a 3.5 m GSD) for a 0.5 m raster made the VHR scene HR and switched its
    GCP minimum off: ACCEPTED. The class is the file's (0.5 m: VHR, §9.1 "<3m"), so Table 9's VHR minimum
    still applies and fails."""
    code, doc, err = _run("satellite-pass", _chain(_one_gcp("S02_SC1"), declare), tmp_path)
    assert code == 1 and doc is not None, err
    assert _verdicts(doc, "JRC-T9-GCP-VHR-RPC")["S02_SC1"] == "fail"
    cls = _record(doc, "JRC-9.1-RESOLUTION-CLASS", "S02_SC1")
    assert (
        cls["verdict"] == "warn" and "VHR" in cls["message"]
    )  # the declared HR contradicts the computed VHR


def test_images_gsd_declared_beside_the_file_pixel_is_a_finding(tmp_path: Path) -> None:
    code, doc, err = _run("satellite-pass", _set("images", "S02_SC1", gsd="3.5"), tmp_path)
    assert code == 1 and doc is not None, err
    rec = _record(doc, "JRC-3.1-GSD-DECLARED", "S02_SC1")
    assert rec["verdict"] == "fail" and rec["measured"]["value"] == pytest.approx(600.0)
    assert "S02_SC1" in doc["rollup"]["rejected"]["image"]


def test_rasters_decimated_to_1m_under_tables_saying_025m(tmp_path: Path) -> None:
    code, doc, err = _run("aerial-pass", _decimate_to(1.0), tmp_path)
    assert code == 1 and doc is not None, err
    got = _verdicts(doc, "JRC-3.1-GSD-DECLARED")
    assert len(got) == 30 and set(got.values()) == {"fail"}
    assert _record(doc, "JRC-3.1-GSD-DECLARED", "F01_0101")["measured"]["value"] == pytest.approx(
        75.0
    )
    assert len(doc["rollup"]["rejected"]["image"]) == 30


def test_rasters_georeferenced_20km_outside_every_block(tmp_path: Path) -> None:
    code, doc, err = _run("aerial-pass", _shift_all(20_000.0), tmp_path)
    assert code == 1 and doc is not None, err
    got = _verdicts(doc, "JRC-12.4-T12-ORTHO-LOCATION")
    assert len(got) == 30 and set(got.values()) == {"fail"}
    assert (
        "outside the outline of block B01"
        in _record(doc, "JRC-12.4-T12-ORTHO-LOCATION", "F01_0101")["message"]
    )
    assert len(doc["rollup"]["rejected"]["image"]) == 30


def test_missing_strip_hidden_by_a_camera_format_declared_3x_larger(tmp_path: Path) -> None:
    """Strip F02_02 removed (rows and files) and the UltraCam Eagle's format declared 3 x larger: the lay-down
    uses the camera's published format (Passini et al. Table 1), so the hole in B02 shows."""
    code, doc, err = _run(
        "aerial-pass", _chain(_drop_strip_f02_02, _camera_format_times(3)), tmp_path
    )
    assert code == 1 and doc is not None, err
    cov = _record(doc, "JRC-5.2.2-COVERAGE", doc["delivery"]["id"])
    assert cov["verdict"] == "fail" and cov["measured"]["value"] < 100.0
    assert _verdicts(doc, "JRC-T1-CAMERA-FORMAT")["UCE-01"] == "warn"
    assert any(r.startswith("JRC-5.2.2-COVERAGE") for r in doc["rollup"]["reasons"])


@pytest.mark.parametrize(
    "own_place", [False, True], ids=["copies-where-the-originals-are", "copies-re-georeferenced"]
)
def test_missing_strip_hidden_by_one_pixel_changed_copies(tmp_path: Path, own_place: bool) -> None:
    """Strip F02_02's rows kept, its files one-pixel-changed copies of strip F02_01's: near copies, both
    rejected (JRC Table 12, each image its own picture), 10 / 30 images: the delivery is returned."""
    code, doc, err = _run("aerial-pass", _strip_f02_02_as_copies(own_place=own_place), tmp_path)
    assert code == 1 and doc is not None, err
    copies = {f"F02_02{k:02d}" for k in range(1, 6)} | {f"F02_01{k:02d}" for k in range(1, 6)}
    _rejected_for(doc, "JRC-12.4-T12-ORTHO-OWN-FILE", copies)
    note = _record(doc, "JRC-12.4-T12-ORTHO-OWN-FILE", "F02_0201")["message"]
    assert "F02_0101" in note and "thumbnail correlation" in note
    assert copies <= set(doc["rollup"]["rejected"]["image"])


def test_one_scene_under_another_georeference_with_its_stats_row_copied(tmp_path: Path) -> None:
    """The shipped satellite-pass with S01_SC1's pixels under S01_SC2's georeference: not ACCEPTED."""
    code, doc, err = _run("satellite-pass", _scene_under_other_georeference, tmp_path)
    assert code == 1 and doc is not None, err
    _rejected_for(doc, "JRC-12.4-T12-ORTHO-OWN-FILE", {"S01_SC1", "S01_SC2"})
    assert (
        "equal decoded pixels" in _record(doc, "JRC-12.4-T12-ORTHO-OWN-FILE", "S01_SC2")["message"]
    )


def test_two_rejected_images_alone_return_the_delivery(tmp_path: Path) -> None:
    code, doc, err = _run("aerial-pass", _two_images_unreadable, tmp_path)
    assert code == 1 and doc is not None, err
    assert _verdicts(doc, "JRC-12.3-IMAGE-FAIL-SHARE")[doc["delivery"]["id"]] == "fail"


def test_ten_padded_near_copies_do_not_dilute_the_rejected_share(tmp_path: Path) -> None:
    """2 / 30 = 6.7 % rejected; ten one-pixel-changed copies of good images made it 2 / 40 = 5 %: ACCEPTED.
    The copies are not new images: each copy and its original fail JRC-12.4-T12-ORTHO-OWN-FILE."""
    code, doc, err = _run(
        "aerial-pass", _chain(_two_images_unreadable, _pad_with_copies(10)), tmp_path
    )
    assert code == 1 and doc is not None, err
    pads = {f"F03_c{90 + k:04d}" for k in range(10)}
    _rejected_for(doc, "JRC-12.4-T12-ORTHO-OWN-FILE", pads)
    share = _record(doc, "JRC-12.3-IMAGE-FAIL-SHARE", doc["delivery"]["id"])
    assert share["verdict"] == "fail" and share["measured"]["value"] > 5.0


def test_dem_delivered_declared_false_beside_a_delivered_dem(tmp_path: Path) -> None:
    code, doc, err = _run(
        "aerial-pass",
        _dem_delivered_declared_false,
        tmp_path,
        parameters={"tolerance_z": {"value": 0.5, "unit": "m"}},
        checker_edit=_checker_heights_1m_off_in_b01,
    )
    assert code == 1 and doc is not None, err
    assert _verdicts(doc, "JRC-12.7-RMSEZ")["B01"] == "fail"
    assert "B01" in doc["rollup"]["rejected"]["block"]
    assert _verdicts(doc, "JRC-12.7-DEM-DECLARED")[doc["delivery"]["id"]] == "warn"


def test_dem_delivered_without_a_z_tolerance_is_missing_not_silent(tmp_path: Path) -> None:
    code, doc, err = _run("aerial-pass", _dem_delivered_declared_false, tmp_path)
    assert code == 1 and doc is not None, err
    assert set(_verdicts(doc, "JRC-12.7-RMSEZ").values()) == {"missing"}


def test_satellite_dem_table_removed_while_scenes_record_the_dem(tmp_path: Path) -> None:
    code, doc, err = _run("satellite-pass", _dem_table_removed, tmp_path)
    assert code == 1 and doc is not None, err
    got = _verdicts(doc, "JRC-9.2-T7-DEM-VERTICAL-CHECK")
    assert got == {"*": "missing"}
    assert any(r.startswith("JRC-9.2-T7-DEM-VERTICAL-CHECK") for r in doc["rollup"]["reasons"])


def test_cloud_cap_is_judged_on_the_pixels_not_the_declaration(tmp_path: Path) -> None:
    """The example tender makes the 5 % cloud cap mandatory (reject_item); clouds painted over a quarter of
    F01_0101 and F01_0102 with their rows still declaring 0 % were ACCEPTED. Judged on the measured cover
    both images are rejected, 2 / 30 = 6.7 % > 5 %: the delivery is returned (§12.3)."""
    edit = _chain(_clouds_in_pixels("F01_0101", 0.25), _clouds_in_pixels("F01_0102", 0.25))
    code, doc, err = _run("aerial-pass", edit, tmp_path, profile=TENDER)
    assert code == 1 and doc is not None, err
    for image in ("F01_0101", "F01_0102"):
        rec = _record(doc, "JRC-6.3-CLOUD-COVER", image)
        assert rec["verdict"] == "fail" and rec["measured"]["value"] == pytest.approx(25.0, abs=8.0)
        assert _verdicts(doc, "JRC-6.3-CLOUD-DECLARED")[image] == "warn"
    assert {"F01_0101", "F01_0102"} <= set(doc["rollup"]["rejected"]["image"])
    assert _verdicts(doc, "JRC-12.3-IMAGE-FAIL-SHARE")[doc["delivery"]["id"]] == "fail"
