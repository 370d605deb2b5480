"""The checker's evidence lives with the checker (issue 29 items 1 and 4; docs/CHECKER.md).

Real example deliveries and checker folders copied into tmp_path, the real check. Expected values
come from the files (numpy over the CSV rows, hashlib over the bytes), never from orthospec's output.
"""

from __future__ import annotations

import csv
import hashlib
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rasterio
import yaml
from tests.checking import CHECKERS, DATE, EXAMPLES, check_with, records, resigned

from orthospec.delivery.checker import load_checker
from orthospec.delivery.reader import open_delivery
from orthospec.errors import OrthospecError

#: the rules that read the external check points (measures checkpoints.* / checkpoint.*)
EXTERNAL = (
    "JRC-12.4-T12-MIN-CHECKPOINTS",
    "JRC-12.5-INDEPENDENT-CHECKPOINTS",
    "JRC-12.5-DISTINCT-CHECKPOINTS",
    "JRC-12.4-CHECKPOINTS-IN-BLOCK",
    "JRC-12.5-QUADRANTS",
    "JRC-12.6-BLUNDER-EXCLUSIONS",
    "JRC-12.7-RMSEX",
    "JRC-12.7-RMSEY",
    "JRC-12.4-SYSTEMATIC-X",
    "JRC-12.4-SYSTEMATIC-Y",
    "JRC-DEF-CHECKPOINT-ACCURACY",
    "JRC-12.8-BLOCK-FAIL-SHARE",
)


def _copy(tmp_path: Path, name: str) -> tuple[Path, Path]:
    """(a copy of the example delivery, a copy of its checker folder), side by side in tmp_path."""
    d, c = tmp_path / name, tmp_path / f"checker-{name}"
    shutil.copytree(EXAMPLES / name, d)
    shutil.copytree(CHECKERS / name, c)
    return d, c


def _rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(encoding="utf-8", newline="") as f:
        r = csv.DictReader(f)
        return list(r.fieldnames or []), list(r)


def _write(path: Path, header: list[str], rows: list[dict[str, str]]) -> None:
    with path.open("w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def _rmse(rows: list[dict[str, str]], block: str, axis: str) -> float:
    kept = [
        r
        for r in rows
        if r["block"] == block and not (r.get("excluded") == "true" and r.get("exclusion_reason"))
    ]
    e = np.array([float(r[axis]) - float(r[f"{axis}_ref"]) for r in kept])
    return float(np.sqrt(np.mean(e**2)))


def _by(doc: dict[str, Any], rule: str) -> dict[str, dict[str, Any]]:
    return {r["item"]: r for r in records(doc) if r["rule"] == rule}


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


# --------------------------------------------------------------------------- the folder
def test_a_checker_folder_is_read_with_its_files_named_in_the_qcr() -> None:
    chk = load_checker(CHECKERS / "aerial-pass", delivery=open_delivery(EXAMPLES / "aerial-pass"))
    assert chk.folder == CHECKERS / "aerial-pass" and chk.name == "checker.yaml"
    s = chk.summary()
    assert s["folder"] == "aerial-pass" and s["sha256"] == _sha(
        CHECKERS / "aerial-pass" / "checker.yaml"
    )
    assert s["files"] == [
        {"path": rel, "sha256": _sha(CHECKERS / "aerial-pass" / rel)}
        for rel in ("tables/checkpoints.csv", "inspection.gpkg")
    ]
    # DIR/checker.yaml stands for the folder; a file of another name is a single checker file
    assert (
        load_checker(CHECKERS / "aerial-pass" / "checker.yaml").folder == CHECKERS / "aerial-pass"
    )


def test_the_external_statistics_are_the_checkers_measurements() -> None:
    doc = check_with(
        EXAMPLES / "aerial-fail", "jrc-v3", checker=CHECKERS / "aerial-fail", date=DATE
    ).document
    _, theirs = _rows(CHECKERS / "aerial-fail" / "tables" / "checkpoints.csv")
    _, own = _rows(EXAMPLES / "aerial-fail" / "tables" / "checkpoints.csv")
    rec = _by(doc, "JRC-12.7-RMSEY")["B02"]
    assert rec["verdict"] == "fail" and rec["measured"]["value"] == pytest.approx(
        _rmse(theirs, "B02", "y"), rel=1e-9
    )
    assert rec["evidence"][0]["file"] == "checker:tables/checkpoints.csv"
    assert rec["evidence"][0]["sha256"] == _sha(
        CHECKERS / "aerial-fail" / "tables" / "checkpoints.csv"
    )
    # the contractor's own table (internal QC): its RMSE, and the disagreement with the external result
    internal = _by(doc, "JRC-12.5-INTERNAL-QC-RMSE-Y")["B02"]
    assert internal["measured"]["value"] == pytest.approx(_rmse(own, "B02", "y"), rel=1e-9)
    assert internal["measured"]["value"] < 0.5 and internal["verdict"] == "pass"
    vs = _by(doc, "JRC-12.5-INTERNAL-VS-EXTERNAL")["B02"]
    assert (
        vs["verdict"] == "warn"
        and "internal QC passes the block, the external check fails it" in vs["message"]
    )
    assert _by(doc, "JRC-12.4-EXTERNAL-CHECKPOINTS")[doc["delivery"]["id"]]["verdict"] == "pass"


@pytest.mark.parametrize(
    "name, edit",
    [
        # aerial-fail's B02 fails externally: the contractor makes its own table perfect
        ("aerial-fail", "perfect"),
        # aerial-pass passes externally: the contractor's own B01 points are off by 0.9 m
        ("aerial-pass", "shift"),
    ],
)
def test_the_contractors_table_cannot_change_an_external_accuracy_verdict(
    tmp_path: Path, name: str, edit: str
) -> None:
    """The planted case of issue 29: the contractor's table edited, the external result unchanged."""
    before = check_with(EXAMPLES / name, "jrc-v3", checker=CHECKERS / name, date=DATE).document
    d, c = _copy(tmp_path, name)
    table = d / "tables" / "checkpoints.csv"
    header, rows = _rows(table)
    for r in rows:
        if edit == "perfect":
            r["x"], r["y"] = r["x_ref"], r["y_ref"]
        elif r["block"] == "B01":
            r["x"] = f"{float(r['x']) + 0.9:.3f}"
    _write(table, header, rows)
    after = check_with(
        d, "jrc-v3", checker=resigned(c, d, c), date=DATE
    ).document  # the checker received it
    for rule in EXTERNAL:
        got = {
            i: (r["verdict"], (r.get("measured") or {}).get("value"))
            for i, r in _by(after, rule).items()
        }
        want = {
            i: (r["verdict"], (r.get("measured") or {}).get("value"))
            for i, r in _by(before, rule).items()
        }
        assert got == want, rule
    assert after["verdict"] == before["verdict"]
    assert after["rollup"]["rejected"].get("block") == before["rollup"]["rejected"].get("block")
    # the edit shows where it belongs: the contractor's internal QC
    internal = {i: r["verdict"] for i, r in _by(after, "JRC-12.5-INTERNAL-QC-RMSE-X").items()}
    if edit == "shift":
        assert (
            internal["B01"] == "warn"
            and _by(after, "JRC-12.5-INTERNAL-VS-EXTERNAL")["B01"]["verdict"] == "warn"
        )
    else:  # reference = measured everywhere: exact-zero residuals are no measurements (issue 25 item 5),
        # so the internal QC has nothing to judge - missing, never a perfect pass
        assert set(internal.values()) == {"missing"}


def test_without_the_checkers_table_the_contractors_points_count_and_nothing_is_accepted(
    tmp_path: Path,
) -> None:
    d, c = _copy(tmp_path, "aerial-pass")
    (c / "tables" / "checkpoints.csv").unlink()
    doc = check_with(d, "jrc-v3", checker=c, date=DATE).document
    ext = _by(doc, "JRC-12.4-EXTERNAL-CHECKPOINTS")[doc["delivery"]["id"]]
    assert (
        ext["verdict"] == "fail"
        and "the checker measured no check points of its own" in ext["message"]
    )
    assert f"the checker folder {c} holds no tables/checkpoints.csv" in ext["message"]
    # the checker's work still to do: incomplete (exit 3), never accepted, saying what to measure
    assert doc["verdict"] == "incomplete"
    assert any(
        t.startswith(f"{doc['delivery']['id']}: the checker measured no check points of its own")
        and "JRC-12.4-EXTERNAL-CHECKPOINTS" in t
        for t in doc["rollup"]["incomplete"]
    ), doc["rollup"]
    _, own = _rows(d / "tables" / "checkpoints.csv")
    rec = _by(doc, "JRC-12.7-RMSEX")["B01"]
    assert rec["measured"]["value"] == pytest.approx(_rmse(own, "B01", "x"), rel=1e-9)
    assert rec["evidence"][0]["file"] == "tables/checkpoints.csv"
    # nothing independent to compare the internal QC with: not applicable, never pass
    assert {r["verdict"] for r in _by(doc, "JRC-12.5-INTERNAL-VS-EXTERNAL").values()} == {
        "not_applicable"
    }


@pytest.mark.parametrize(
    "column, value, words",
    [
        (
            "decision",
            "maybe",
            ["row 1", "column 'decision'", "'maybe' is not one of accepted, by_hand"],
        ),
        ("image_sha256", "abc", ["row 1", "column 'image_sha256'", "is not a SHA-256"]),
        ("block", "B99", ["row 1", "column 'block'", "'B99' is not a block of the manifest"]),
        ("y", "nan", ["row 1", "'y'"]),
    ],
)
def test_a_bad_checker_table_is_refused_naming_file_row_and_column(
    tmp_path: Path, column: str, value: str, words: list[str]
) -> None:
    d, c = _copy(tmp_path, "aerial-pass")
    table = c / "tables" / "checkpoints.csv"
    header, rows = _rows(table)
    rows[0][column] = value
    _write(table, header, rows)
    with pytest.raises(OrthospecError) as exc:
        check_with(d, "jrc-v3", checker=c, date=DATE)
    msg = str(exc.value)
    assert "tables/checkpoints.csv" in msg and all(w in msg for w in words), msg


def test_a_checker_table_linked_into_the_delivery_is_refused(tmp_path: Path) -> None:
    d, c = _copy(tmp_path, "aerial-pass")
    (c / "tables" / "checkpoints.csv").unlink()
    (c / "tables" / "checkpoints.csv").symlink_to(d / "tables" / "checkpoints.csv")
    with pytest.raises(OrthospecError, match="inside the delivery"):
        check_with(d, "jrc-v3", checker=c, date=DATE)


# --------------------------------------------------------------------------- bound to what was measured
def _repaint(path: Path, value: int = 77) -> None:
    """The same raster, other pixels: what a swapped or edited image looks like."""
    with rasterio.open(path) as src:
        profile, arr = src.profile, src.read()
    arr[:, : arr.shape[1] // 2, :] = value
    path.unlink()
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(arr)


def test_a_point_measured_on_an_image_changed_since_is_left_out_and_named(tmp_path: Path) -> None:
    d, c = _copy(tmp_path, "aerial-pass")
    _, theirs = _rows(c / "tables" / "checkpoints.csv")
    image = "F01_0102"
    on_it = [r["point_id"] for r in theirs if r["image_id"] == image]
    assert on_it
    _repaint(d / "images" / f"{image}.tif")
    doc = check_with(d, "jrc-v3", checker=resigned(c, d, c), date=DATE).document
    bound = _by(doc, "JRC-12.6-POINTS-BOUND")["B01"]
    assert bound["verdict"] == "fail" and bound["measured"]["value"] == len(on_it)
    assert (
        all(p in bound["message"] for p in on_it) and "changed or swapped since" in bound["message"]
    )
    kept = [r for r in theirs if r["point_id"] not in on_it]
    assert _by(doc, "JRC-12.7-RMSEX")["B01"]["measured"]["value"] == pytest.approx(
        _rmse(kept, "B01", "x"), rel=1e-9
    )
    assert doc["verdict"] != "accepted"
    # hand-typed rows without the image's SHA-256 are used, and named
    header, rows = _rows(c / "tables" / "checkpoints.csv")
    for r in rows:
        r["image_sha256"] = ""
    _write(c / "tables" / "checkpoints.csv", header, rows)
    doc = check_with(d, "jrc-v3", checker=c, date=DATE).document
    assert _by(doc, "JRC-12.6-POINTS-HASHED")["B02"]["verdict"] == "warn"
    assert _by(doc, "JRC-12.6-POINTS-BOUND")["B01"]["verdict"] == "pass"


def test_a_manual_verdict_on_an_image_swapped_since_is_missing_never_the_old_verdict(
    tmp_path: Path,
) -> None:
    d, c = _copy(tmp_path, "satellite-pass")
    base = check_with(
        EXAMPLES / "satellite-pass", "jrc-v3", checker=CHECKERS / "satellite-pass", date=DATE
    ).document
    assert _by(base, "JRC-9.2-T7-VISUAL-QUALITY")["S01_SC2"]["verdict"] == "pass"
    shutil.copyfile(
        d / "images" / "S01_SC1.tif", d / "images" / "S01_SC2.tif"
    )  # another scene under its id
    doc = check_with(d, "jrc-v3", checker=c, date=DATE).document
    rec = _by(doc, "JRC-9.2-T7-VISUAL-QUALITY")["S01_SC2"]
    assert rec["verdict"] == "missing" and "changed or swapped since" in rec["message"]
    assert _by(doc, "JRC-9.2-T7-VISUAL-QUALITY")["S01_SC1"]["verdict"] == "pass"
    assert doc["verdict"] != "accepted"
    # an entry that records no file and SHA-256 of an image is never carried over either
    y = yaml.safe_load((c / "checker.yaml").read_text(encoding="utf-8"))
    for e in y["manual_checks"]:
        e.pop("file", None)
        e.pop("sha256", None)
    (c / "checker.yaml").write_text(yaml.safe_dump(y, sort_keys=False), encoding="utf-8")
    doc = check_with(EXAMPLES / "satellite-pass", "jrc-v3", checker=c, date=DATE).document
    rec = _by(doc, "JRC-9.2-T7-VISUAL-QUALITY")["S01_SC1"]
    assert rec["verdict"] == "missing" and "records no file and SHA-256" in rec["message"]


# --------------------------------------------------------------------------- pins bind every role
def _pinned(tmp_path: Path, d: Path, pins: dict[str, Any]) -> Path:
    """A single checker file for ``d`` pinning ``pins`` (path -> sha256 or {sha256, role})."""
    y = yaml.safe_load((CHECKERS / "aerial-pass" / "checker.yaml").read_text(encoding="utf-8"))
    y["delivery"]["files"] = pins
    path = tmp_path / "pins.yaml"
    path.write_text(yaml.safe_dump(y, sort_keys=False), encoding="utf-8")
    return path


def _manifest(d: Path) -> dict[str, Any]:
    return yaml.safe_load((d / "delivery.yaml").read_text(encoding="utf-8"))


def _save(d: Path, m: dict[str, Any]) -> None:
    (d / "delivery.yaml").write_text(yaml.safe_dump(m, sort_keys=False), encoding="utf-8")


def test_a_pinned_txt_table_re_pointed_by_the_manifest_is_refused(tmp_path: Path) -> None:
    d, _ = _copy(tmp_path, "aerial-pass")
    m = _manifest(d)
    (d / "tables" / "checkpoints.csv").rename(d / "tables" / "cp.txt")
    m["tables"]["checkpoints"] = "tables/cp.txt"
    _save(d, m)
    pin = _pinned(tmp_path, d, {"tables/cp.txt": _sha(d / "tables" / "cp.txt")})
    load_checker(pin, delivery=open_delivery(d))  # as signed: fine
    shutil.copyfile(d / "tables" / "cp.txt", d / "tables" / "cp2.txt")
    m["tables"]["checkpoints"] = "tables/cp2.txt"  # the pinned .txt left untouched
    _save(d, m)
    with pytest.raises(
        OrthospecError, match=r"pins tables/cp.txt, which the delivery no longer uses"
    ):
        load_checker(pin, delivery=open_delivery(d))


@pytest.mark.parametrize("role, key", [("documents.internal_qcr", ("documents", "internal_qcr"))])
def test_a_pinned_document_re_pointed_is_refused(
    tmp_path: Path, role: str, key: tuple[str, str]
) -> None:
    d, _ = _copy(tmp_path, "aerial-pass")
    rel = _manifest(d)[key[0]][key[1]]
    pin = _pinned(tmp_path, d, {rel: {"sha256": _sha(d / rel), "role": role}})
    load_checker(pin, delivery=open_delivery(d))
    (d / "documents" / "other.md").write_text(
        "# a QCR written after the checker signed\n", encoding="utf-8"
    )
    m = _manifest(d)
    m[key[0]][key[1]] = "documents/other.md"
    _save(d, m)
    with pytest.raises(OrthospecError) as exc:
        load_checker(pin, delivery=open_delivery(d))
    assert f"pins {rel} as {role}; the delivery now uses documents/other.md for it" in str(
        exc.value
    )


def test_a_pinned_area_of_interest_re_pointed_is_refused(tmp_path: Path) -> None:
    import pyogrio
    import shapely
    from shapely.geometry import box

    d, _ = _copy(tmp_path, "aerial-pass")
    (d / "vectors").mkdir()
    for name, poly in (
        ("aoi.gpkg", box(500000, 5400000, 520000, 5418200)),
        ("small.gpkg", box(500000, 5400000, 501000, 5401000)),
    ):
        pyogrio.raw.write(
            str(d / "vectors" / name),
            geometry=np.array(shapely.to_wkb([poly]), dtype=object),
            field_data=[],
            fields=[],
            driver="GPKG",
            crs="EPSG:25832",
            geometry_type="Polygon",
        )
    m = _manifest(d)
    m["project"]["area_of_interest"] = "vectors/aoi.gpkg"
    _save(d, m)
    pin = _pinned(
        tmp_path,
        d,
        {
            "vectors/aoi.gpkg": {
                "sha256": _sha(d / "vectors" / "aoi.gpkg"),
                "role": "project.area_of_interest",
            }
        },
    )
    load_checker(pin, delivery=open_delivery(d))
    m["project"]["area_of_interest"] = "vectors/small.gpkg"
    _save(d, m)
    with pytest.raises(
        OrthospecError,
        match=r"pins vectors/aoi.gpkg as project.area_of_interest; the delivery "
        r"now uses vectors/small.gpkg for it",
    ):
        load_checker(pin, delivery=open_delivery(d))


def test_a_pinned_image_re_pointed_by_the_image_table_is_refused(tmp_path: Path) -> None:
    d, _ = _copy(tmp_path, "aerial-pass")
    rel = "images/F01_0101.tif"
    header, rows = _rows(d / "tables" / "images.csv")
    role_pin = _pinned(tmp_path, d, {rel: {"sha256": _sha(d / rel), "role": "images:F01_0101"}})
    load_checker(role_pin, delivery=open_delivery(d))
    shutil.copyfile(d / "images" / "F01_0102.tif", d / "images" / "F01_0101b.tif")
    for r in rows:
        if r["image_id"] == "F01_0101":
            r["file"] = "images/F01_0101b.tif"  # the pinned file left untouched
    _write(d / "tables" / "images.csv", header, rows)
    with pytest.raises(
        OrthospecError,
        match=r"pins images/F01_0101.tif as images:F01_0101; the delivery now "
        r"uses images/F01_0101b.tif for it",
    ):
        load_checker(role_pin, delivery=open_delivery(d))
    short = _pinned(tmp_path, d, {rel: _sha(d / rel)})  # the short form: no longer used by anything
    with pytest.raises(
        OrthospecError, match=r"pins images/F01_0101.tif, which the delivery no longer uses"
    ):
        load_checker(short, delivery=open_delivery(d))


def test_a_pinned_item_whose_file_differs_from_the_one_pinned_is_refused(tmp_path: Path) -> None:
    """Two image rows swap their files: both files are still used, each for another item."""
    d, _ = _copy(tmp_path, "aerial-pass")
    pin = _pinned(
        tmp_path,
        d,
        {
            "images/F01_0101.tif": {
                "sha256": _sha(d / "images" / "F01_0101.tif"),
                "role": "images:F01_0101",
            }
        },
    )
    header, rows = _rows(d / "tables" / "images.csv")
    files = {r["image_id"]: r["file"] for r in rows}
    for r in rows:
        if r["image_id"] in ("F01_0101", "F01_0102"):
            r["file"] = files["F01_0102" if r["image_id"] == "F01_0101" else "F01_0101"]
    _write(d / "tables" / "images.csv", header, rows)
    with pytest.raises(
        OrthospecError, match="as images:F01_0101; the delivery now uses images/F01_0102.tif"
    ):
        load_checker(pin, delivery=open_delivery(d))


def _rename_image(d: Path, image: str) -> None:
    (d / "images" / f"{image}.tif").rename(d / "images" / f"{image}_renamed.tif")
    header, rows = _rows(d / "tables" / "images.csv")
    for r in rows:
        if r["image_id"] == image:
            r["file"] = f"images/{image}_renamed.tif"
    _write(d / "tables" / "images.csv", header, rows)


@pytest.mark.parametrize(
    "name, image, rules",
    [
        (
            "aerial-pass",
            "F01_0103",
            ("JRC-T6-ORTHO-INSPECTION", "JRC-6.3-ARTEFACTS"),
        ),  # the marked grid's verdicts
        (
            "satellite-pass",
            "S01_SC2",
            ("JRC-9.2-T7-VISUAL-QUALITY",),
        ),  # checker.yaml entries with file and sha256
    ],
)
def test_a_renamed_image_with_the_same_content_keeps_its_verdicts(
    tmp_path: Path, name: str, image: str, rules: tuple[str, ...]
) -> None:
    """Binding is to content: the same pixels under another file name are the image judged."""
    d, c = _copy(tmp_path, name)
    base = check_with(EXAMPLES / name, "jrc-v3", checker=CHECKERS / name, date=DATE).document
    _rename_image(d, image)
    doc = check_with(d, "jrc-v3", checker=resigned(c, d, c), date=DATE).document
    for rule in rules:
        assert _by(doc, rule)[image]["verdict"] == _by(base, rule)[image]["verdict"] == "pass", rule
    assert doc["verdict"] == base["verdict"] == "accepted"
    if name == "satellite-pass":  # the entry names the old file; its SHA-256 is the renamed file's
        y = yaml.safe_load((c / "checker.yaml").read_text(encoding="utf-8"))
        entry = next(e for e in y["manual_checks"] if e["item"] == image and e.get("file"))
        assert entry["file"] == f"images/{image}.tif" and entry["sha256"] == _sha(
            d / "images" / f"{image}_renamed.tif"
        )


def _tree(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): _sha(p) for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_check_with_the_checker_folder_writes_nothing_into_the_delivery_or_the_folder(
    tmp_path: Path,
) -> None:
    from click.testing import CliRunner

    from orthospec.cli.main import cli

    d, c = _copy(tmp_path, "aerial-fail")
    before, folder = _tree(d), _tree(c)
    res = CliRunner().invoke(
        cli(),
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
            "json,html",
            "--date",
            DATE,
        ],
    )
    assert res.exit_code == 1, res.output
    assert _tree(d) == before and _tree(c) == folder
    assert (tmp_path / "out" / "report.html").is_file()
