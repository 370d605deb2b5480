"""Report image chips of the checker's flagged or hand-measured check points, and the inspection grid's
marked cells on the block maps (issue 29 item 6).

A copy of aerial-pass whose checker measured B01-C05 on image F01_0101 (the point moved inside that
extract, a 2.2 m blunder excluded with its reason) against a reference chip kept in the checker
folder. The chip is compared with the image window read here with rasterio.
"""

from __future__ import annotations

import base64
import csv
import hashlib
import re
import shutil
from pathlib import Path

import numpy as np
import rasterio
from click.testing import CliRunner
from pyogrio import raw
from tests.checking import CHECKERS, EXAMPLES

from orthospec.cli.main import cli
from orthospec.inspection.chips import CHIP_PX, Chip
from orthospec.inspection.grid import mark_cells


def _setup(tmp_path: Path) -> tuple[Path, Path, dict[str, float]]:
    d, c = tmp_path / "aerial-pass", tmp_path / "checker"
    shutil.copytree(EXAMPLES / "aerial-pass", d)
    shutil.copytree(CHECKERS / "aerial-pass", c)
    tif = d / "images" / "F01_0101.tif"
    with rasterio.open(tif) as ds:
        b = ds.bounds
    xr, yr = round((b.left + b.right) / 2 - 3.1, 3), round((b.bottom + b.top) / 2 + 2.2, 3)
    pt = {"x_ref": xr, "y_ref": yr, "x": round(xr + 2.0, 2), "y": round(yr - 1.0, 2)}
    (c / "chips").mkdir()
    shutil.copyfile(
        tif, c / "chips" / "B01-C05.tif"
    )  # the reference chip the point was matched against
    table = c / "tables" / "checkpoints.csv"
    with table.open(encoding="utf-8", newline="") as f:
        r = csv.DictReader(f)
        header, rows = list(r.fieldnames or []), list(r)
    header += ["reference_file"]
    for row in rows:
        row["reference_file"] = ""
        if row["point_id"] == "B01-C05":
            row.update(
                {k: f"{v}" for k, v in pt.items()},
                image_id="F01_0101",
                image_sha256=hashlib.sha256(tif.read_bytes()).hexdigest(),
                excluded="true",
                exclusion_reason="target mis-identified on the image",
                reference_file="chips/B01-C05.tif",
            )
    with table.open("w", encoding="utf-8", newline="") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    return d, c, pt


def _svgs(html: str) -> dict[str, str]:
    """alt text -> decoded SVG of every embedded figure."""
    found = re.findall(r'<img src="data:image/svg\+xml;base64,([^"]+)" alt="([^"]*)"', html)
    return {alt: base64.b64decode(data).decode("utf-8") for data, alt in found}


def test_a_flagged_point_gets_its_chips_and_the_grid_marks_show_on_the_block_map(
    tmp_path: Path,
) -> None:
    d, c, pt = _setup(tmp_path)
    cells = raw.read(c / "inspection.gpkg", layer="cells", columns=["cell_id", "image_id"])[3]
    marked = [str(i) for i, img in zip(*cells, strict=True) if img == "F01_0103"][:2]
    mark_cells(
        c / "inspection.gpkg",
        {i: {"seam": 1, "comment": "geometric break at the seam"} for i in marked},
    )
    out = tmp_path / "out"
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
            str(out),
            "--format",
            "json,html",
            "--date",
            "2026-11-21",
        ],
    )
    assert res.exit_code in (0, 1), res.output
    import json

    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    chips = doc["details"]["checker_chips"]["B01"]["points"]
    entry = next(p for p in chips if p["point_id"] == "B01-C05")
    assert entry["flagged"] and (entry["x"], entry["y"], entry["x_ref"], entry["y_ref"]) == (
        pt["x"],
        pt["y"],
        pt["x_ref"],
        pt["y_ref"],
    )
    chip = Chip.from_dict(entry["delivered"])
    left, bottom, right, top = chip.extent
    assert left < pt["x"] < right and bottom < pt["y"] < top
    assert chip.data.shape == (CHIP_PX, CHIP_PX) and right - left == CHIP_PX * 0.25
    with rasterio.open(d / "images" / "F01_0101.tif") as ds:
        win = ds.window(left, bottom, right, top)
        lum = ds.read([1, 2, 3], window=win).astype(float).mean(axis=0)
    assert np.corrcoef(lum.ravel(), chip.data.astype(float).ravel())[0, 1] > 0.99
    ref = Chip.from_dict(entry["reference"])
    assert (
        ref.extent[0] < pt["x_ref"] < ref.extent[2] and ref.extent[1] < pt["y_ref"] < ref.extent[3]
    )
    # on the point's block page: the chips with the measured shift drawn, and the grid's marks on its map
    html = (out / "report.html").read_text(encoding="utf-8")
    svgs = _svgs(html)
    chip_svg = next(s for alt, s in svgs.items() if "check point B01-C05" in alt)
    assert all(
        g in chip_svg
        for g in (
            'id="chip-delivered"',
            'id="chip-reference"',
            'id="measured-shift"',
            'id="measured-position"',
            'id="reference-position"',
        )
    )
    assert "dx +2.000 m, dy -1.000 m" in chip_svg
    block_map = next(s for alt, s in svgs.items() if alt.startswith("Block B01: check points"))
    assert 'id="inspection-defects"' in block_map
    assert "2 cell(s) of the block marked with a defect" in html and "seam" in html
    other_map = next(s for alt, s in svgs.items() if alt.startswith("Block B02: check points"))
    assert 'id="inspection-defects"' not in other_map


def test_a_reference_file_named_outside_the_checker_folder_is_not_read(tmp_path: Path) -> None:
    """A provenance cell is data: it cannot make the check read a file outside the checker's folder."""
    from tests.checking import check_with

    d, c, _ = _setup(tmp_path)
    shutil.copyfile(c / "chips" / "B01-C05.tif", tmp_path / "outside.tif")
    table = c / "tables" / "checkpoints.csv"
    for ref in ("../outside.tif", str(tmp_path / "outside.tif")):
        text = table.read_text(encoding="utf-8")
        table.write_text(
            re.sub(r"chips/B01-C05\.tif|\.\./outside\.tif", ref, text), encoding="utf-8"
        )
        doc = check_with(d, "jrc-v3", checker=c, date="2026-11-21").document
        entry = next(
            p
            for p in doc["details"]["checker_chips"]["B01"]["points"]
            if p["point_id"] == "B01-C05"
        )
        assert (
            "reference" not in entry
            and entry["reference_note"] == f"reference file {ref} is not in the checker folder"
        )
        assert "delivered" in entry
