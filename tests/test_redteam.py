"""Red team: a dishonest or careless contractor edits only what it controls, and must not get a
defective delivery ACCEPTED (docs/CHECKER.md: the delivery is evidence, never authority).

Each case copies a shipped example delivery into tmp_path, makes real file edits there (manifest,
CSV tables, images), and runs the real check with the checker's own fixed file
(``examples/checker/<example>.yaml``), profile jrc-v3 and ``--date 2026-11-21``. Exit codes are those
of ``orthospec check``: 1 rejected, 2 could not evaluate (an ``OrthospecError``).

Most checkpoint cases start from ``aerial-pass`` with one planted defect (``_plant_rmse``): block
B02's northing residuals scaled by 2.2, giving RMSEy = 0.627 m over 24 check points against the
0.5 m tolerance (JRC EUR 23638 EN §12.7: "The planimetric threshold will be applied independently
in X, and Y"), in the checker's measurements (the checker folder's tables/checkpoints.csv, what the
external-accuracy rules read) and in the contractor's internal-QC table alike, its reported RMSEy set
to match so that JRC-12.7-RMSEY is the only block finding. The contractor's trick then tries to hide
it; a trick on the contractor's own check point table can no longer reach the external verdict
(issue 29 item 1: ``_check_external_stands``). The checker's file is re-signed (tests/checking.py
``resigned``) on what the contractor delivers: the
checker signs what it receives; ``_signed_then`` edits the delivery after signing. Cases marked
xfail(strict) are wrong ACCEPTED verdicts written up in tests/REDTEAM.md; they flip (and fail
as XPASS) once fixed.
"""

from __future__ import annotations

import csv
import math
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from tests.checking import (
    CHECKERS,
    DATE,
    EXAMPLES,
    check_with,
    manifest,
    read_table,
    remeasured,
    resigned,
    write_manifest,
    write_table,
)
from tests.checking import records as all_records

from orthospec.errors import OrthospecError

#: the fixed checker's name in examples/checker/*.yaml (aerial-*)
CHECKER_NAME = "M. Keller (fictional)"

Edit = Callable[[Path], None]


# --- file edits ------------------------------------------------------------------------------


def _manifest_edit(fn: Callable[[dict[str, Any]], None]) -> Edit:
    def edit(d: Path) -> None:
        m = manifest(d)
        fn(m)
        write_manifest(d, m)

    return edit


def _table_edit(
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


def _worst(rows: list[dict[str, str]], k: int, block: str = "B02") -> list[dict[str, str]]:
    """The block's k check points with the largest northing residual (the ones a cheat hides)."""
    rs = [r for r in rows if r["block"] == block]
    return sorted(rs, key=lambda r: -abs(float(r["y"]) - float(r["y_ref"])))[:k]


def _fix_reported(d: Path, table: str = "checkpoints") -> None:
    """Set every block's reported RMSE to what its non-excluded check points give (in metres), so
    JRC-9.5-REPORTED-RMSE-* cannot be what catches a trick."""
    _, rows = read_table(d, table)
    m = manifest(d)
    factor = {"m": 1.0, "ft": 0.3048, "usft": 1200 / 3937, "mm": 0.001}[
        (m.get("units") or {}).get("checkpoints", "m")
    ]
    for b in m["blocks"]:
        pts = [r for r in rows if r["block"] == b["id"] and r.get("excluded", "false") != "true"]
        for ax in ("x", "y"):
            v = (
                math.sqrt(sum((float(r[ax]) - float(r[f"{ax}_ref"])) ** 2 for r in pts) / len(pts))
                * factor
            )
            b["reported"][f"rmse_{ax}"] = {"value": round(v, 3), "unit": "m"}
    write_manifest(d, m)


def _scale_b02_dy(header: list[str], rows: list[dict[str, str]]) -> None:
    for r in rows:
        if r["block"] == "B02":
            r["y"] = f"{float(r['y_ref']) + 2.2 * (float(r['y']) - float(r['y_ref'])):.3f}"


def _external_edit(
    fn: Callable[[list[str], list[dict[str, str]]], list[dict[str, str]] | None],
) -> Edit:
    """Edit the checker's own check point table (its folder beside the delivery, see ``_run``)."""

    def edit(d: Path) -> None:
        path = _checker_folder(d) / "tables" / "checkpoints.csv"
        with path.open(encoding="utf-8", newline="") as f:
            r = csv.DictReader(f)
            header, rows = list(r.fieldnames or []), list(r)
        out = fn(header, rows)
        with path.open("w", encoding="utf-8", newline="") as f:
            w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
            w.writeheader()
            w.writerows(rows if out is None else out)

    return edit


def _checker_folder(d: Path) -> Path:
    """The copy of the example's checker folder a case runs with (made by ``_run`` before the edits)."""
    return d.parent / f"checker-{d.name}"


#: the planted defect: B02 RMSEy 0.627 m > 0.5 m in the checker's measurements and the contractor's own,
#: reported values consistent
_plant_rmse = _chain(
    _table_edit("checkpoints", _scale_b02_dy), _external_edit(_scale_b02_dy), _fix_reported
)


def _planted(*tricks: Edit) -> Edit:
    return _chain(_plant_rmse, *tricks)


# the contractor's tricks


def _sensor(kind: str) -> Edit:
    return _manifest_edit(lambda m: m["sensor"].update(type=kind))


def _declare_tolerance(value: float) -> Edit:
    return _manifest_edit(
        lambda m: m["tender"]["parameters"].update(tolerance_xy={"value": value, "unit": "m"})
    )


def _units(unit: str) -> Edit:
    return _manifest_edit(lambda m: m.update(units={"checkpoints": unit, "gcps": "m"}))


def _exclude_worst(header: list[str], rows: list[dict[str, str]]) -> None:
    for r in _worst(rows, 4):
        r["excluded"] = "true"
        r["exclusion_reason"] = "blunder: target not identifiable on the image"


def _move_worst(block: str, k: int) -> Edit:
    def fn(header: list[str], rows: list[dict[str, str]]) -> None:
        for r in _worst(rows, k):
            r["block"] = block

    return _table_edit("checkpoints", fn)


def _delete_worst(header: list[str], rows: list[dict[str, str]]) -> list[dict[str, str]]:
    drop = {r["point_id"] for r in _worst(rows, 4)}
    return [r for r in rows if r["point_id"] not in drop]


def _duplicate_ids(header: list[str], rows: list[dict[str, str]]) -> list[dict[str, str]]:
    best = sorted(
        (r for r in rows if r["block"] == "B02"),
        key=lambda r: abs(float(r["y"]) - float(r["y_ref"])),
    )
    return rows + [dict(r) for r in best[:10] for _ in range(3)]


def _fabricated_copies(header: list[str], rows: list[dict[str, str]]) -> list[dict[str, str]]:
    best = sorted(
        (r for r in rows if r["block"] == "B02"),
        key=lambda r: abs(float(r["y"]) - float(r["y_ref"])),
    )
    return rows + [{**r, "point_id": f"B02-X{i:02d}"} for i, r in enumerate(best[:10] * 3)]


def _set_worst_y(value: str) -> Edit:
    def fn(header: list[str], rows: list[dict[str, str]]) -> None:
        for r in _worst(rows, 6):
            r["y"] = value

    return _table_edit("checkpoints", fn)


def _gcps_as_checkpoints(d: Path) -> None:
    _, gcps = read_table(d, "gcps")
    header, rows = read_table(d, "checkpoints")
    for g in gcps:
        if g["block"] == "B02":
            rows.append(
                {
                    **dict.fromkeys(header, ""),
                    "point_id": g["point_id"],
                    "block": "B02",
                    "x": g["x"],
                    "y": g["y"],
                    "x_ref": g["x"],
                    "y_ref": g["y"],
                    "excluded": "false",
                    "source": "GNSS RTK",
                    "precision_xy": "0.02",
                }
            )
    write_table(d, "checkpoints", header, rows)


def _self_granted_waiver(d: Path) -> None:
    """Waiver request in delivery.yaml, 'waived'/'pass' rows signed with the checker's name in the
    delivery's manual_checks table, and the checker named as the delivery's operator."""
    m = manifest(d)
    m["waivers"] = [
        {
            "rule": "JRC-12.7-RMSEY",
            "items": ["B02"],
            "justification": "haze over B02",
            "approver": CHECKER_NAME,
        }
    ]
    m["operator"] = {"name": CHECKER_NAME, "role": "external QC"}
    write_manifest(d, m)
    header, rows = read_table(d, "manual_checks")
    for verdict in ("waived", "pass"):
        rows.append(
            {
                **dict.fromkeys(header, ""),
                "check": "JRC-12.7-RMSEY",
                "item": "B02",
                "inspector": f"{CHECKER_NAME}, external QC",
                "date": "2026-06-21",
                "verdict": verdict,
                "note": "waiver granted by the external QC",
            }
        )
    write_table(d, "manual_checks", header, rows)


def _second_checkpoints_entry(d: Path) -> None:
    """A second `checkpoints:` key in the manifest's tables, pointing at a cleaned copy."""
    header, rows = read_table(d, "checkpoints")
    drop = {r["point_id"] for r in _worst(rows, 6)}
    write_table(d, "checkpoints_clean", header, [r for r in rows if r["point_id"] not in drop])
    text = (d / "delivery.yaml").read_text(encoding="utf-8")
    line = "  checkpoints: tables/checkpoints.csv\n"
    assert line in text
    (d / "delivery.yaml").write_text(
        text.replace(line, line + "  checkpoints: tables/checkpoints_clean.csv\n"), encoding="utf-8"
    )


def _drop_reported(m: dict[str, Any]) -> None:
    for b in m["blocks"]:
        b.pop("reported", None)


def _rename_block_everywhere(d: Path, old: str = "B02", new: str = "B99") -> None:
    text = (d / "delivery.yaml").read_text(encoding="utf-8")
    (d / "delivery.yaml").write_text(text.replace(f"id: {old}", f"id: {new}"), encoding="utf-8")
    for name in ("checkpoints", "gcps", "images", "aerotriangulation"):
        header, rows = read_table(d, name)
        for r in rows:
            if r.get("block") == old:
                r["block"] = new
        write_table(d, name, header, rows)


def _scene(image_id: str, **values: str) -> Edit:
    def fn(header: list[str], rows: list[dict[str, str]]) -> None:
        for r in rows:
            if r["image_id"] == image_id:
                r.update(values)

    return _table_edit("scenes", fn)


def _precision(values: dict[str, str]) -> Edit:
    """Set the reference precision of every check point of the given blocks."""

    def fn(header: list[str], rows: list[dict[str, str]]) -> None:
        for r in rows:
            if r["block"] in values:
                r["precision_xy"] = values[r["block"]]

    return _table_edit("checkpoints", fn)


def _drop_strip_f02_02(d: Path) -> None:
    """Remove the second strip of flight F02 (five photos: rows and files), a hole in the coverage."""
    header, rows = read_table(d, "images")
    gone = [r for r in rows if r["image_id"].startswith("F02_02")]
    for r in gone:
        (d / r["file"]).unlink()
    write_table(d, "images", header, [r for r in rows if r not in gone])


def _inflate_f02_01_heights(header: list[str], rows: list[dict[str, str]]) -> None:
    for r in rows:
        if r["image_id"].startswith("F02_01"):
            r["flying_height"] = f"{float(r['flying_height']) * 2.5:.1f}"


def _manual_rows_as_checker(check: str, verdict: str = "pass") -> Edit:
    """Rows in the delivery's manual_checks table signed with the checker's name (evidence only)."""

    def fn(header: list[str], rows: list[dict[str, str]]) -> list[dict[str, str]]:
        return [
            *rows,
            {
                **dict.fromkeys(header, ""),
                "check": check,
                "item": "*",
                "inspector": f"{CHECKER_NAME}, external QC",
                "date": "2026-06-21",
                "verdict": verdict,
                "note": "inspected by the external QC",
            },
        ]

    return _table_edit("manual_checks", fn)


def _empty_document(d: Path) -> None:
    (d / "documents" / "internal_qcr.md").write_text("", encoding="utf-8")


def _remove_document(d: Path) -> None:
    (d / "documents" / "internal_qcr.md").unlink()


def _copy_image_over_missing(d: Path) -> None:
    """aerial-fail's F03_0202 is not on the medium: deliver a copy of its neighbour F03_0201 instead."""
    shutil.copyfile(d / "images" / "F03_0201.tif", d / "images" / "F03_0202.tif")


def _shrink_b02_to_first_strip(m: dict[str, Any]) -> None:
    """Redraw B02's outline around what the remaining strip F02_01 covers (x <= 511,500 m)."""
    for b in m["blocks"]:
        if b["id"] == "B02":
            b["polygon"] = [
                [507500.0, 5403000.0],
                [511500.0, 5403000.0],
                [511500.0, 5410200.0],
                [507500.0, 5410200.0],
                [507500.0, 5403000.0],
            ]


def _negative_precision_b02(header: list[str], rows: list[dict[str, str]]) -> None:
    for r in rows:
        if r["block"] == "B02":
            r["precision_xy"] = "-0.5"


def _drop_image_row(image_id: str) -> Edit:
    return _table_edit(
        "images", lambda header, rows: [r for r in rows if r["image_id"] != image_id]
    )


def _reproject_label_everything(d: Path) -> None:
    """Every image re-labelled EPSG:25833 (same numbers: ~500 km off) and project.crs declared to match."""
    import rasterio
    from rasterio.crs import CRS

    for tif in sorted((d / "images").glob("*.tif")):
        with rasterio.open(tif, "r+") as ds:
            ds.crs = CRS.from_epsg(25833)
    text = (d / "delivery.yaml").read_text(encoding="utf-8")
    assert "EPSG:25832" in text
    (d / "delivery.yaml").write_text(text.replace("EPSG:25832", "EPSG:25833"), encoding="utf-8")


def _b01_outline_swallows_b02(m: dict[str, Any]) -> None:
    """Redraw B01's outline as B01 + B02 (+ the 500 m gap between them): overlapping blocks."""
    for b in m["blocks"]:
        if b["id"] == "B01":
            b["polygon"] = [
                [500000.0, 5400000.0],
                [507000.0, 5400000.0],
                [507000.0, 5403000.0],
                [514500.0, 5403000.0],
                [514500.0, 5409000.0],
                [513500.0, 5410200.0],
                [507500.0, 5410200.0],
                [507500.0, 5406000.0],
                [507000.0, 5406000.0],
                [506000.0, 5407200.0],
                [500000.0, 5407200.0],
                [500000.0, 5400000.0],
            ]


def _b02_outline_bowtie(m: dict[str, Any]) -> None:
    """B02's outline drawn as a self-intersecting ring (its two top vertices swapped)."""
    for b in m["blocks"]:
        if b["id"] == "B02":
            b["polygon"] = [
                [507500.0, 5403000.0],
                [514500.0, 5403000.0],
                [507500.0, 5410200.0],
                [514500.0, 5410200.0],
                [507500.0, 5403000.0],
            ]


#: the example's true outlines (examples/generate.py, also stated in examples/checker/aerial-*.yaml)
_B01 = [
    [500000.0, 5400000.0],
    [507000.0, 5400000.0],
    [507000.0, 5406000.0],
    [506000.0, 5407200.0],
    [500000.0, 5407200.0],
    [500000.0, 5400000.0],
]
_B02 = [
    [507500.0, 5403000.0],
    [514500.0, 5403000.0],
    [514500.0, 5409000.0],
    [513500.0, 5410200.0],
    [507500.0, 5410200.0],
    [507500.0, 5403000.0],
]


def _snake_b01_around_its_strays(d: Path) -> None:
    """B01's outline snaked around the B02 points relabelled B01: 2 m corridors from each point west
    into the 500 m gap, a spine down the gap and a link into B01; B02's outline notched by the same
    corridors, so no two outlines share area (R17's refusal does not apply). Integer vertices: the
    union and difference are exact."""
    import shapely
    from shapely.geometry import Point, Polygon, box

    b01, b02 = Polygon(_B01), Polygon(_B02)
    _, rows = read_table(d, "checkpoints")
    strays = [
        (float(r["x_ref"]), float(r["y_ref"]))
        for r in rows
        if r["block"] == "B01" and not b01.covers(Point(float(r["x_ref"]), float(r["y_ref"])))
    ]
    assert strays, "no B02 point relabelled B01"
    low = min(math.floor(min(y for _, y in strays)) - 1, 5404990)
    top = max(math.ceil(max(y for _, y in strays)) + 1, 5405010)
    parts = [box(507240, low, 507260, top), box(506990, 5404990, 507260, 5405010)]
    parts += [box(507240, math.floor(y) - 1, math.ceil(x) + 1, math.ceil(y) + 1) for x, y in strays]
    snake = shapely.union_all(parts)
    new01, new02 = b01.union(snake), b02.difference(snake)
    assert new01.geom_type == new02.geom_type == "Polygon" and new01.intersection(new02).area == 0
    assert all(new01.covers(Point(p)) for p in strays)
    m = manifest(d)
    for b in m["blocks"]:
        if b["id"] in ("B01", "B02"):
            b["polygon"] = [
                [float(x), float(y)]
                for x, y in (new01 if b["id"] == "B01" else new02).exterior.coords
            ]
    write_manifest(d, m)


def _aoi_file_without_strip_f02_02(d: Path) -> None:
    """Strip F02_02 removed, and an area of interest declared (vectors/aoi.gpkg) as B01, B03 and B02 cut
    at x = 511,500 m, what the remaining strip F02_01 covers (R13 with the area instead of the block)."""
    import numpy as np
    import pyogrio
    import shapely
    from shapely.geometry import Polygon, box

    _drop_strip_f02_02(d)
    m = manifest(d)
    polys = {b["id"]: Polygon(b["polygon"]) for b in m["blocks"]}
    area = [
        polys["B01"],
        polys["B02"].intersection(box(507000, 5400000, 511500, 5420000)),
        polys["B03"],
    ]
    (d / "vectors").mkdir(exist_ok=True)
    pyogrio.raw.write(
        str(d / "vectors" / "aoi.gpkg"),
        geometry=np.array(shapely.to_wkb(area), dtype=object),
        field_data=[],
        fields=[],
        driver="GPKG",
        crs="EPSG:25832",
        geometry_type="Polygon",
    )
    m["project"]["area_of_interest"] = "vectors/aoi.gpkg"
    write_manifest(d, m)


def _checker_states(edit: Edit, fn: Callable[[dict[str, Any]], None]) -> Edit:
    """``edit``, with the checker's file changed by ``fn`` (the checker's side, not the contractor's)."""

    def wrapped(d: Path) -> None:
        edit(d)

    wrapped.checker_edit = fn  # type: ignore[attr-defined]
    return wrapped


def _no_outlines(doc: dict[str, Any]) -> None:
    """A checker's file that states no block outlines or area: the manifest's are in force."""
    doc.pop("blocks", None)
    doc.pop("area_of_interest", None)


def _aoi_is_b02(doc: dict[str, Any]) -> None:
    """The checker states the area of interest (here B02's true outline, where strip F02_02 lies)."""
    doc["area_of_interest"] = _B02[:-1]


def _project_crs(value: str | None) -> Edit:
    """The manifest's project.crs set to ``value`` (None: removed); the images are left as delivered."""

    def fn(m: dict[str, Any]) -> None:
        if value is None:
            m["project"].pop("crs", None)
        else:
            m["project"]["crs"] = value

    return _manifest_edit(fn)


def _inflate_f02_01_heights_and_gsds(header: list[str], rows: list[dict[str, str]]) -> None:
    """R7's trick again, with the rows' declared GSDs inflated to agree (the rasters stay 0.25 m)."""
    for r in rows:
        if r["image_id"].startswith("F02_01"):
            for col, fmt in (
                ("flying_height", "{:.1f}"),
                ("acquisition_gsd", "{:.4f}"),
                ("gsd", "{:.2f}"),
            ):
                r[col] = fmt.format(float(r[col]) * 2.5)


def _swap_in_cleaned_table(d: Path) -> None:
    """The pinned tables/checkpoints.csv stays untouched; the manifest names another file without the
    4 worst B02 points, reported RMSEs to match."""
    header, rows = read_table(d, "checkpoints")
    drop = {r["point_id"] for r in _worst(rows, 4)}
    write_table(d, "checkpoints_v2", header, [r for r in rows if r["point_id"] not in drop])
    m = manifest(d)
    m["tables"]["checkpoints"] = "tables/checkpoints_v2.csv"
    write_manifest(d, m)
    _fix_reported(d, "checkpoints_v2")


def _drop_failing_scenes(header: list[str], rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [r for r in rows if r["image_id"] not in ("S01_SC1", "S01_SC3", "S02_SC2")]


# --- running ---------------------------------------------------------------------------------


def _signed_then(before: Edit, after: Edit) -> Edit:
    """``before`` is what the contractor delivers and the checker signs (its file re-signed on that
    content); ``after`` is changed in the delivery once the checker's file exists."""

    def edit(d: Path) -> None:
        before(d)

    edit.after_signing = after  # type: ignore[attr-defined]
    return edit


def _delivered_items(d: Path) -> set[str]:
    """Every item id the delivery lists: manifest blocks and the id column of each CSV table."""
    items = {b["id"] for b in manifest(d)["blocks"]}
    for table in (d / "tables").glob("*.csv"):
        with table.open(encoding="utf-8", newline="") as f:
            items.update(row[0] for row in list(csv.reader(f))[1:] if row)
    return items


def _checker_for(
    example: str,
    delivery: Path,
    tmp_path: Path,
    checker_edit: Callable[[dict[str, Any]], None] | None = None,
) -> Path:
    """The checker's fixed folder re-signed on the delivered content (tests/checking.py ``resigned``): the
    checker signs what it receives and judges only the items it received. Outside the delivery."""
    remeasured(_checker_folder(delivery), delivery)
    path = resigned(_checker_folder(delivery), delivery, _checker_folder(delivery))
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    items = _delivered_items(delivery)
    doc["manual_checks"] = [
        m for m in doc.get("manual_checks") or [] if m["item"] == "*" or m["item"] in items
    ]
    if checker_edit is not None:
        checker_edit(doc)
    path.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def _run(example: str, edit: Edit, tmp_path: Path) -> tuple[int, dict[str, Any] | None, str]:
    """(exit code, qcr document or None, error text) of `orthospec check` on an edited copy."""
    d = tmp_path / example
    shutil.copytree(EXAMPLES / example, d)
    shutil.copytree(CHECKERS / example, _checker_folder(d))
    # the red team is about the contractor's edits, not the checker's inspection grid (written for the
    # images as shipped): its visual verdicts are then unsigned (recommended rules, a warning)
    (_checker_folder(d) / "inspection.gpkg").unlink(missing_ok=True)
    edit(d)
    checker = _checker_for(example, d, tmp_path, getattr(edit, "checker_edit", None))
    after = getattr(edit, "after_signing", None)
    if after is not None:
        after(d)
    try:
        result = check_with(d, "jrc-v3", checker=checker, date=DATE)
    except OrthospecError as exc:
        return 2, None, str(exc)
    return (0 if result.accepted else 1), result.document, ""


def _verdicts(doc: dict[str, Any], rule: str) -> dict[str, str]:
    return {r["item"]: r["verdict"] for r in all_records(doc) if r["rule"] == rule}


def _rejects(doc: dict[str, Any], rule: str, item: str, verdict: str = "fail") -> None:
    got = _verdicts(doc, rule)
    assert got.get(item) == verdict, f"{rule} {item}: {got}"
    assert any(reason.startswith(rule) for reason in doc["rollup"]["reasons"]), doc["rollup"][
        "reasons"
    ]


# --- cases -----------------------------------------------------------------------------------


def _check_planted_alone(code: int, doc: dict[str, Any] | None, err: str) -> None:
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-12.7-RMSEY", "B02")
    assert doc["rollup"]["rejected"] == {"block": ["B02"]}


def _check_sensor_satellite(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # §12.7 applies to every sensor; the aerial rules switched off, the satellite ones lack their evidence
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-12.7-RMSEY", "B02")
    assert _verdicts(doc, "JRC-9.2-T7-ORIENTATION-DATA")["F01_0101"] == "missing"
    # the contractor's rows in the checker's name are evidence, not the checker's verdict
    assert set(_verdicts(doc, "JRC-9.2-T7-VISUAL-QUALITY").values()) == {"missing"}


def _check_rename(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # the checker's measurements still name B02: the renamed delivery does not match them (exit 2)
    assert code == 2 and doc is None
    assert "tables/checkpoints.csv: row" in err and "'B02' is not a block of the manifest" in err, (
        err
    )


def _check_external_stands(*untouched: str) -> Callable[[int, dict[str, Any] | None, str], None]:
    """Issue 29 item 1: the trick edited the contractor's own check point table (its internal QC, JRC
    §12.5); the external-accuracy rules read the checker's measurements, so the planted B02 failure
    stands and the rules the trick aimed at (``untouched``) judge the checker's unchanged points."""

    def check(code: int, doc: dict[str, Any] | None, err: str) -> None:
        assert code == 1 and doc is not None
        _rejects(doc, "JRC-12.7-RMSEY", "B02")
        assert "B02" in doc["rollup"]["rejected"]["block"], doc["rollup"]["rejected"]
        for rule in untouched:
            assert set(_verdicts(doc, rule).values()) == {"pass"}, (rule, _verdicts(doc, rule))

    return check


# §12.6 only a point beyond 3 x RMSE may be excluded: the contractor's exclusions touch its own table only
_check_excluded = _check_external_stands("JRC-12.6-BLUNDER-EXCLUSIONS")
# points relabelled to B01 in the contractor's table: the checker's B01 and B02 are unchanged
_check_moved_to_b01 = _check_external_stands(
    "JRC-12.4-T12-MIN-CHECKPOINTS", "JRC-12.4-CHECKPOINTS-IN-BLOCK"
)
# §12.5 check points independent of the GCPs: GCPs added to the contractor's table are not the checker's
_check_gcps = _check_external_stands("JRC-12.5-INDEPENDENT-CHECKPOINTS")


def _check_self_waiver(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # docs/CHECKER.md: waivers and manual verdicts only from the checker's file or the tender profile
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-12.7-RMSEY", "B02")
    assert "waived" not in _verdicts(doc, "JRC-12.7-RMSEY").values()
    assert [w["rule"] for w in doc["waiver_requests"]] == ["JRC-12.7-RMSEY"]


def _check_no_reported(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # Table 6 QCR 11 / §9.5: no reported RMSE, nothing to compare: missing, never pass. Since issue 26 the
    # §9.5 comparison is recommended ("should"): a missing record is a warning-level gap, and the block's
    # accuracy is judged on the checker's points (JRC-12.7), not on the contractor's figure
    assert doc is not None
    recs = [r for r in all_records(doc) if r["rule"] == "JRC-9.5-REPORTED-RMSE-Y"]
    assert {r["verdict"] for r in recs} == {"missing"} and {r["level"] for r in recs} == {
        "recommended"
    }


def _check_satellite_as_aerial(code: int, doc: dict[str, Any] | None, err: str) -> None:
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-12.7-RMSEX", "S02")
    _rejects(doc, "JRC-12.7-RMSEY", "S02")
    _rejects(doc, "JRC-5.2.2-COVERAGE", doc["delivery"]["id"], "missing")


def _check_scenes_dropped(code: int, doc: dict[str, Any] | None, err: str) -> None:
    assert code == 1 and doc is not None
    for item in ("S01_SC1", "S01_SC3", "S02_SC2"):
        assert _verdicts(doc, "JRC-T9-ORBIT-MODEL")[item] == "missing"
    assert {"S01_SC1", "S01_SC3", "S02_SC2"} <= set(doc["rollup"]["rejected"]["image"])


def _check_coverage_hole(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # §5.2.2, Table 1 "Completeness": 100 % coverage, computed from the lay-down even for extracts
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-5.2.2-COVERAGE", doc["delivery"]["id"])


def _check_reference_accuracy(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # Definitions, "Check Point": reference coordinates at least 3x more accurate than the tolerance.
    # Careless precision in the contractor's internal-QC table (§7.2 "the same quality requirements
    # apply"): a finding on B02 and B03; the checker's own points are judged by JRC-DEF-CHECKPOINT-ACCURACY
    assert doc is not None
    got = _verdicts(doc, "JRC-7.2-INTERNAL-QC-PRECISION")
    assert (got["B01"], got["B02"], got["B03"]) == ("pass", "warn", "warn"), got
    assert set(_verdicts(doc, "JRC-DEF-CHECKPOINT-ACCURACY").values()) == {"pass"}


def _check_document_removed(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # §2.5: the internal QCRs are delivered with the data
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-2.5-INTERNAL-QCR", doc["delivery"]["id"])


def _check_document_empty(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # §2.5: a 0-byte file is no internal QCR (R11)
    _check_document_removed(code, doc, err)
    from orthospec.qcr import all_records

    msgs = [r["message"] for r in all_records(doc) if r["rule"] == "JRC-2.5-INTERNAL-QCR"]
    assert any("0 bytes" in m for m in msgs), msgs


def _check_scene_controls(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # Table 9: PRESS and the scene's check-point RMSE below the tolerance (1.0 m in satellite-fail)
    assert code == 1 and doc is not None
    assert _verdicts(doc, "JRC-T9-PRESS")["S02_SC1"] == "fail"
    assert _verdicts(doc, "JRC-T9-CHECKPOINT-RMSE")["S02_SC3"] == "fail"
    assert {"S02_SC1", "S02_SC3"} <= set(doc["rollup"]["rejected"]["image"])


def _check_outside_block(block: str) -> Callable[[int, dict[str, Any] | None, str], None]:
    # R6/R13 (fixed by d44b081): §12.4 "QC is well distributed within the block/site area"; the points
    # moved into B01 are the contractor's own (issue 29): the checker's B01 holds none of them
    return _check_external_stands("JRC-12.4-CHECKPOINTS-IN-BLOCK")


def _check_outlines_in_force(
    *, redrawn: bool, stray: str | None = None, coverage: bool = False, aoi: bool = False
) -> Callable[[int, dict[str, Any] | None, str], None]:
    # R13/R17 with the checker's outlines in force (examples/checker/aerial-*.yaml `blocks:`): a redrawn
    # declaration is itself a finding, and the true outlines decide the in-block test (``stray``: the
    # block holding points outside its true outline) and the area the photos must cover (JRC §12.4
    # "within the block/site area", §5.2.2)
    def check(code: int, doc: dict[str, Any] | None, err: str) -> None:
        assert code == 1 and doc is not None
        did = doc["delivery"]["id"]
        if redrawn:
            _rejects(doc, "JRC-12.4-BLOCK-OUTLINES-AGREE", did)
        else:
            assert _verdicts(doc, "JRC-12.4-BLOCK-OUTLINES-AGREE")[did] == "pass"
        in_block = _verdicts(doc, "JRC-12.4-CHECKPOINTS-IN-BLOCK")
        if stray is not None:
            _rejects(doc, "JRC-12.4-CHECKPOINTS-IN-BLOCK", stray)
        assert {b for b, v in in_block.items() if v != "pass"} == ({stray} if stray else set()), (
            in_block
        )
        if coverage:
            _rejects(doc, "JRC-5.2.2-COVERAGE", did)
            message = next(
                r["message"] for r in all_records(doc) if r["rule"] == "JRC-5.2.2-COVERAGE"
            )
            assert "of the checker file" in message, message
        if aoi:
            _rejects(doc, "JRC-5.2.2-AOI-AGREES", did)

    return check


def _check_outlines_unused(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # (c) the checker's file states no outlines: the manifest's are in force, as before (R6's rule
    # catches the shrunk B02), and the agreement rules are not applicable
    # the points outside the shrunk outline are left out and listed for the checker (issue 26:
    # consequence incomplete): never accepted
    assert code == 1 and doc is not None and doc["verdict"] == "incomplete"
    assert _verdicts(doc, "JRC-12.4-CHECKPOINTS-IN-BLOCK")["B02"] == "fail"
    assert any(
        t.startswith("B02: ") and "JRC-12.4-CHECKPOINTS-IN-BLOCK" in t
        for t in doc["rollup"]["incomplete"]
    )
    did = doc["delivery"]["id"]
    assert _verdicts(doc, "JRC-12.4-BLOCK-OUTLINES-AGREE")[did] == "not_applicable"
    assert _verdicts(doc, "JRC-5.2.2-AOI-AGREES")[did] == "not_applicable"


def _check_inflated_heights(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # R7 (fixed by d44b081), R18 (after 543dba9): photos whose H/f x pixel contradicts the
    # raster's 0.25 m pixels cover nothing -> coverage missing, naming them
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-5.2.2-COVERAGE", doc["delivery"]["id"], "missing")
    message = next(r["message"] for r in all_records(doc) if r["rule"] == "JRC-5.2.2-COVERAGE")
    assert "F02_0101 (0.6 m vs 0.2" in message, message  # vs 0.24 m acquisition / 0.25 m raster


def _check_master_declared(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # R8 (fixed by d44b081): Table 9 "identify as master image"; the delivery is returned
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-T9-MASTER-DECLARED", doc["delivery"]["id"])


def _check_master_identified(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # R8 with every trace erased: the checker names the master (master_images), so Table 9's master rules
    # still judge S01_SC1 (12 check points < 20) and the flags' disagreement returns the delivery
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-T9-MASTER-IDENTIFIED", doc["delivery"]["id"])
    assert _verdicts(doc, "JRC-T9-MASTER-CHECKPOINTS")["S01_SC1"] == "fail"
    assert "S01_SC1" in doc["rollup"]["rejected"]["image"]


def _check_scene_rule(
    rule: str, image_id: str
) -> Callable[[int, dict[str, Any] | None, str], None]:
    # R9/R10/R14 (fixed by d44b081): a recorded PRESS / check-point RMSE is judged, a negative one fails
    def check(code: int, doc: dict[str, Any] | None, err: str) -> None:
        assert code == 1 and doc is not None
        assert _verdicts(doc, rule)[image_id] == "fail"
        assert image_id in doc["rollup"]["rejected"]["image"]

    return check


def _check_itt_declared(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # R1 (fixed by b333f7a): the tolerance in force is the checker's (JRC §2.5 "the tolerance stated in
    # the ITT"); the contractor's other number is itself a finding
    assert code == 1 and doc is not None
    _rejects(doc, "JRC-12.7-RMSEY", "B02")
    _rejects(doc, "ORTHOSPEC-ITT-DECLARED", "tolerance_xy")


def _check_map_projection(
    images_rejected: bool,
) -> Callable[[int, dict[str, Any] | None, str], None]:
    # R16: §12.4 Table 12 "georeferenced to the (national) map projection": the projection is the ITT's
    # (map_crs, stated in the checker's file), the manifest's project.crs only a declaration compared with it
    def check(code: int, doc: dict[str, Any] | None, err: str) -> None:
        assert code == 1 and doc is not None
        _rejects(doc, "JRC-12.4-T12-MAP-PROJECTION", doc["delivery"]["id"])
        georef = _verdicts(doc, "JRC-12.4-T12-ORTHO-GEOREFERENCED")
        assert set(georef.values()) == ({"fail"} if images_rejected else {"pass"}), georef

    return check


# §12.5 "independent measurements": copies of good points under new ids (R4) in the contractor's table
_check_distinct_points = _check_external_stands("JRC-12.5-DISTINCT-CHECKPOINTS")


def _refused(*words: str) -> Callable[[int, dict[str, Any] | None, str], None]:
    def check(code: int, doc: dict[str, Any] | None, err: str) -> None:
        assert code == 2, doc and doc["verdict"]
        for w in words:
            assert w in err, err

    return check


def _check_item_vanished(item: str) -> Callable[[int, dict[str, Any] | None, str], None]:
    # R15 (fixed by 904bfe5): the checker's verdicts on an item the delivery no longer lists return it
    def check(code: int, doc: dict[str, Any] | None, err: str) -> None:
        assert code == 1 and doc is not None
        assert any(
            f"the checker's verdict on {item} refers to an item the delivery no longer lists" in r
            for r in doc["rollup"]["reasons"]
        ), doc["rollup"]["reasons"]
        assert {r["rule"] for r in all_records(doc) if r["item"] == item} >= {
            "JRC-T6-ORTHO-INSPECTION"
        }

    return check


def _check_own_file(code: int, doc: dict[str, Any] | None, err: str) -> None:
    # R12: §12.4 Table 12 "Ortho-image": each image its own raster; the copy rejects both
    assert code == 1 and doc is not None
    assert _verdicts(doc, "JRC-12.4-T12-ORTHO-OWN-FILE")["F03_0202"] == "fail"
    assert {"F03_0201", "F03_0202"} <= set(doc["rollup"]["rejected"]["image"])


def _not_accepted(code: int, doc: dict[str, Any] | None, err: str) -> None:
    assert code in (1, 2), "ACCEPTED a delivery whose B02 RMSEy exceeds the tolerance"


def _xfail(finding: str) -> pytest.MarkDecorator:
    return pytest.mark.xfail(strict=True, reason=f"tests/REDTEAM.md {finding}")


CASES = [
    pytest.param("aerial-pass", _plant_rmse, _check_planted_alone, id="planted-defect-alone"),
    pytest.param(
        "aerial-fail",
        _chain(_sensor("satellite"), _manual_rows_as_checker("JRC-9.2-T7-VISUAL-QUALITY")),
        _check_sensor_satellite,
        id="aerial-declared-satellite",
    ),
    pytest.param(
        "aerial-fail", _rename_block_everywhere, _check_rename, id="failing-block-renamed"
    ),
    pytest.param(
        "aerial-pass",
        _planted(_table_edit("checkpoints", _exclude_worst)),
        _check_excluded,
        id="worst-points-excluded-with-reason",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_move_worst("B01", 6)),
        _check_moved_to_b01,
        id="worst-points-moved-to-B01",
    ),
    pytest.param(
        "aerial-pass", _planted(_gcps_as_checkpoints), _check_gcps, id="gcps-as-checkpoints"
    ),
    pytest.param(
        "aerial-pass", _planted(_self_granted_waiver), _check_self_waiver, id="self-granted-waiver"
    ),
    pytest.param(
        "aerial-pass",
        _manifest_edit(_drop_reported),
        _check_no_reported,
        id="reported-rmse-removed",
    ),
    pytest.param(
        "satellite-fail",
        _sensor("aerial"),
        _check_satellite_as_aerial,
        id="satellite-declared-aerial",
    ),
    pytest.param(
        "satellite-fail",
        _table_edit("scenes", _drop_failing_scenes),
        _check_scenes_dropped,
        id="failing-scenes-rows-deleted",
    ),
    pytest.param(
        "aerial-pass",
        _precision({"B02": "0.5", "B03": ""}),
        _check_reference_accuracy,
        id="careless-reference-precision-0.5m-and-blank",
    ),
    pytest.param(
        "aerial-pass",
        _drop_strip_f02_02,
        _check_coverage_hole,
        id="strip-removed-extracts-declared",
    ),
    pytest.param(
        "aerial-pass", _remove_document, _check_document_removed, id="internal-qcr-removed"
    ),
    pytest.param(
        "satellite-fail",
        _chain(
            _scene("S02_SC1", press_sqrt="1.5"),
            _scene("S02_SC3", checkpoint_rmse="1.3", checkpoint_count="8"),
        ),
        _check_scene_controls,
        id="scene-press-and-rmse-planted",
    ),
    # refused before any rule runs (exit 2, file/row/column named)
    pytest.param(
        "aerial-pass",
        _planted(_table_edit("checkpoints", _duplicate_ids)),
        _refused("checkpoints.csv", "duplicate id"),
        id="good-points-duplicated",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_set_worst_y("")),
        _refused("checkpoints.csv", "'y'", "empty"),
        id="worst-y-blank",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_set_worst_y("nan")),
        _refused("checkpoints.csv", "'y'", "finite"),
        id="worst-y-nan",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_set_worst_y("inf")),
        _refused("checkpoints.csv", "'y'", "finite"),
        id="worst-y-inf",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_second_checkpoints_entry),
        _refused("delivery.yaml", "duplicate key"),
        id="second-checkpoints-table-entry",
    ),
    # wrongly ACCEPTED today (findings R1-R5 in tests/REDTEAM.md)
    pytest.param(
        "aerial-pass",
        _planted(_declare_tolerance(1.0)),
        _check_itt_declared,
        id="R1-tolerance-declared-1m",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_units("ft"), _fix_reported),
        _refused("delivery.yaml", "units.checkpoints is ft", "EPSG:25832", "in m"),
        id="R2-units-ft-in-metre-crs",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_units("mm"), _fix_reported),
        _refused("delivery.yaml", "units.checkpoints is mm", "EPSG:25832"),
        id="R2-units-mm-in-metre-crs",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_move_worst("B99", 4), _fix_reported),
        _refused(
            "tables/checkpoints.csv", "column 'block'", "'B99' is not a block of the manifest"
        ),
        id="R3-worst-points-to-unknown-block",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_table_edit("checkpoints", _fabricated_copies), _fix_reported),
        _check_distinct_points,
        id="R4-fabricated-copies-new-ids",
    ),
    pytest.param(
        "aerial-pass",
        _signed_then(_plant_rmse, _chain(_table_edit("checkpoints", _delete_worst), _fix_reported)),
        _refused("pins tables/checkpoints.csv", "other content"),
        id="R5-worst-points-deleted-after-signing",
    ),
    pytest.param(
        "aerial-pass",
        _planted(_move_worst("B01", 4), _fix_reported),
        _check_outside_block("B01"),
        id="R6-worst-points-moved-outside-into-B01",
    ),
    pytest.param(
        "aerial-pass",
        _chain(_drop_strip_f02_02, _table_edit("images", _inflate_f02_01_heights)),
        _check_inflated_heights,
        id="R7-strip-removed-heights-inflated",
    ),
    # item-level: satellite-fail stays rejected for its other defects, but the planted scene defect is hidden
    pytest.param(
        "satellite-fail",
        _scene("S01_SC1", is_master="false"),
        _check_master_declared,
        id="R8-master-declared-not-master",
    ),
    pytest.param(
        "satellite-fail",
        _scene("S01_SC1", is_master="false", master_check_date=""),
        _check_master_identified,
        id="R8-master-unflagged-every-trace-erased",
    ),
    pytest.param(
        "satellite-fail",
        _scene("S02_SC1", press_sqrt="-1.5"),
        _check_scene_rule("JRC-T9-PRESS-VALID", "S02_SC1"),
        id="R9-negative-press",
    ),
    pytest.param(
        "satellite-fail",
        _scene("S02_SC1", checkpoint_rmse="1.3", checkpoint_count="0"),
        _check_scene_rule("JRC-T9-CHECKPOINT-RMSE", "S02_SC1"),
        id="R10-checkpoint-count-zero",
    ),
    pytest.param(
        "aerial-pass", _empty_document, _check_document_empty, id="R11-internal-qcr-empty-file"
    ),
    pytest.param(
        "aerial-fail",
        _copy_image_over_missing,
        _check_own_file,
        id="R12-missing-image-replaced-by-neighbour-copy",
    ),
    pytest.param(
        "aerial-fail",
        _signed_then(_chain(), _drop_image_row("F03_0202")),
        _check_item_vanished("F03_0202"),
        id="R15-checker-rejected-image-row-deleted",
    ),
    pytest.param(
        "aerial-pass",
        _reproject_label_everything,
        _check_map_projection(images_rejected=True),
        id="R16-all-images-and-project-crs-relabelled",
    ),
    pytest.param(
        "aerial-pass",
        _project_crs("EPSG:25833"),
        _check_map_projection(images_rejected=False),
        id="R16-project-crs-relabelled-images-right",
    ),
    # without project.crs the coordinate unit has nothing to be checked against (R2): the ft trick
    # is then caught by the missing declaration of the ITT's projection
    pytest.param(
        "aerial-pass",
        _planted(_project_crs(None), _units("ft"), _fix_reported),
        _check_map_projection(images_rejected=False),
        id="R16-project-crs-removed-units-ft",
    ),
    pytest.param(
        "aerial-pass",
        _chain(_drop_strip_f02_02, _manifest_edit(_shrink_b02_to_first_strip)),
        _check_outlines_in_force(redrawn=True, coverage=True, aoi=True),
        id="R13-strip-removed-block-outline-shrunk",
    ),
    pytest.param(
        "aerial-pass",
        _checker_states(
            _chain(_drop_strip_f02_02, _manifest_edit(_shrink_b02_to_first_strip)), _no_outlines
        ),
        _check_outlines_unused,
        id="R13-block-outline-shrunk-checker-states-no-outlines",
    ),
    # the points moved into the snaked B01 are the contractor's own (issue 29): the redrawn outline is the
    # finding, the checker's points (none of them moved) lie in their true blocks
    pytest.param(
        "aerial-pass",
        _planted(_move_worst("B01", 4), _snake_b01_around_its_strays, _fix_reported),
        _check_outlines_in_force(redrawn=True),
        id="R13-B01-outline-snaked-around-B02-points",
    ),
    # was xfail (R13: without the checker's outlines the snaked outline took B02's worst points into B01);
    # closed by issue 29: the external statistics are the checker's measurements, the moved points the
    # contractor's, so B02 stays rejected on its RMSEy
    pytest.param(
        "aerial-pass",
        _checker_states(
            _planted(_move_worst("B01", 4), _snake_b01_around_its_strays, _fix_reported),
            _no_outlines,
        ),
        _check_external_stands(),
        id="R13-B01-outline-snaked-checker-states-no-outlines",
    ),
    pytest.param(
        "aerial-pass",
        _aoi_file_without_strip_f02_02,
        _check_outlines_in_force(redrawn=False, coverage=True, aoi=True),
        id="R13-area-of-interest-shrunk-checker-states-blocks",
    ),
    pytest.param(
        "aerial-pass",
        _checker_states(_aoi_file_without_strip_f02_02, _aoi_is_b02),
        _check_outlines_in_force(redrawn=False, coverage=True, aoi=True),
        id="R13-area-of-interest-shrunk-checker-states-it",
    ),
    pytest.param(
        "aerial-pass",
        _checker_states(_aoi_file_without_strip_f02_02, _no_outlines),
        _not_accepted,
        id="R13-area-of-interest-shrunk-checker-states-no-outlines",
        marks=_xfail(
            "R13: without the checker's outlines the area of interest is the contractor's "
            "project.area_of_interest; stating it in the checker's file closes it"
        ),
    ),
    pytest.param(
        "aerial-pass",
        _planted(_move_worst("B01", 4), _manifest_edit(_b01_outline_swallows_b02), _fix_reported),
        _refused("delivery.yaml:", "blocks[1] (B02)", "overlaps the outline of block B01"),
        id="R17-B01-outline-redrawn-over-B02",
    ),
    pytest.param(
        "aerial-pass",
        _manifest_edit(_b02_outline_bowtie),
        _refused(
            "delivery.yaml:", "blocks[1] (B02)", "not a valid block outline", "Self-intersection"
        ),
        id="R17-self-intersecting-block-outline",
    ),
    pytest.param(
        "aerial-pass",
        _chain(_drop_strip_f02_02, _table_edit("images", _inflate_f02_01_heights_and_gsds)),
        _check_inflated_heights,
        id="R18-heights-and-declared-gsds-inflated",
    ),
    pytest.param(
        "aerial-pass",
        _signed_then(_plant_rmse, _swap_in_cleaned_table),
        _refused(
            "pins tables/checkpoints.csv as tables.checkpoints",
            "the delivery now uses tables/checkpoints_v2.csv for it",
        ),
        id="R19-after-signing-manifest-names-another-checkpoint-file",
    ),
    pytest.param(
        "aerial-pass",
        _table_edit("checkpoints", _negative_precision_b02),
        _refused("tables/checkpoints.csv", "'precision_xy'", "below the minimum 0"),
        id="R14-negative-reference-precision",
    ),
    pytest.param(
        "satellite-fail",
        _scene("S02_SC1", checkpoint_rmse="-1.3", checkpoint_count="8"),
        _check_scene_rule("JRC-T9-CHECKPOINT-RMSE-VALID", "S02_SC1"),
        id="R14-negative-scene-checkpoint-rmse",
    ),
]


@pytest.mark.parametrize(("example", "edit", "expect"), CASES)
def test_contractor_cannot_get_defect_accepted(
    example: str,
    edit: Edit,
    expect: Callable[[int, dict[str, Any] | None, str], None],
    tmp_path: Path,
) -> None:
    code, doc, err = _run(example, edit, tmp_path)
    expect(code, doc, err)
