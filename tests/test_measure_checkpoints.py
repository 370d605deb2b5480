"""``orthospec measure checkpoints`` end to end (issue 29): a real Landsat image delivered with a
known georeference error, the checker's chips and survey, the table and hand list it writes, the
hand list round trip, and bad input.

Truth: the delivered image holds the reference's own pixels (the Landsat scene given a 0.5 px
Gaussian PSF) with its georeference moved by
(+0.37, -1.21) px, so every feature lies exactly 0.37 px east and 1.21 px south of its true
position on the delivered image: x - x_ref = +111 m, y - y_ref = -363 m (300 m pixels).
"""

from __future__ import annotations

import csv
import hashlib
import os
from pathlib import Path

import numpy as np
import pyogrio
import pytest
import rasterio
import shapely
from click.testing import CliRunner
from rasterio.transform import Affine
from rasterio.windows import Window
from scipy import ndimage

from orthospec.cli.main import cli
from orthospec.raster.checkpoints import COLUMNS, HAND_FILE

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SRC = REAL / "RGB.byte.tif"
OFFSET_PX = (0.37, -1.21)  # east, north, in pixels
RES = 300.0
DX_M, DY_M = OFFSET_PX[0] * RES, OFFSET_PX[1] * RES

MANIFEST = """orthospec_delivery: 1
id: D-MATCH
project: {id: P1, name: matching, crs: "EPSG:32618"}
contractor: {name: ACME}
operator: {name: Jane}
sensor: {type: satellite, digital: true}
product: {gsd: {value: 300, unit: m}}
blocks: [{id: B1}]
tables: {images: tables/images.csv}
"""

# scene pixels (row, col) of surveyed points: textured land, 60+ px from the scene's no-data
POINTS = [
    (532, 394),
    (351, 166),
    (545, 519),
    (346, 237),
    (454, 358),
    (281, 220),
    (598, 434),
    (471, 429),
]


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _snapshot(root: Path) -> dict[str, tuple[str, int]]:
    return {
        str(p.relative_to(root)): (_sha(p), p.stat().st_mtime_ns)
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("matching")
    with rasterio.open(SRC) as ds:
        data, prof, t = ds.read(), ds.profile, ds.transform
    # a camera's PSF (Gaussian, 0.5 px): the file was decimated and is aliased, and aliased texture
    # has no single position at a fractional offset (interpolators disagree by 0.04 px on it)
    data = np.where(
        data > 0,
        np.clip(
            np.round(np.stack([ndimage.gaussian_filter(b.astype(float), 0.5) for b in data])),
            1,
            255,
        ),
        0,
    ).astype(np.uint8)
    reference = base / "reference.tif"  # the checker's reference orthoimage
    with rasterio.open(reference, "w", **prof) as o:
        o.write(data)
    d = base / "delivery"
    (d / "images").mkdir(parents=True)
    (d / "tables").mkdir()
    (d / "delivery.yaml").write_text(MANIFEST)
    (d / "tables" / "images.csv").write_text("image_id,file,block\nI1,images/i1.tif,B1\n")
    moved = dict(
        prof,
        transform=Affine.translation(DX_M, DY_M) * t,
        tiled=True,
        blockxsize=256,
        blockysize=256,
        compress="deflate",
    )
    with rasterio.open(d / "images" / "i1.tif", "w", **moved) as o:
        o.write(data)
    chips = base / "chips"
    chips.mkdir()
    lines = ["point_id,x,y,z,source,precision_xy"]
    for k, (r, c) in enumerate(POINTS, 1):
        x, y = t * (c + 0.5, r + 0.5)
        lines.append(f"P{k},{x:.3f},{y:.3f},{10 * k},GNSS survey,0.05")
        w = Window(c - 48, r - 48, 96, 96)
        cp = dict(prof, width=96, height=96, transform=rasterio.windows.transform(w, t))
        with rasterio.open(chips / f"P{k}.tif", "w", **cp) as o:
            o.write(data[:, r - 48 : r + 48, c - 48 : c + 48])
    survey = base / "survey.csv"
    survey.write_text("\n".join(lines) + "\n")
    return {
        "base": base,
        "reference": reference,
        "delivery": d,
        "chips": chips,
        "survey": survey,
        "image": d / "images" / "i1.tif",
    }


def run(*args: str | Path) -> tuple[int, str, str]:
    r = CliRunner().invoke(
        cli(), ["measure", "checkpoints", *map(str, args)], catch_exceptions=False
    )
    assert "Traceback" not in r.output + r.stderr
    return r.exit_code, r.stdout, r.stderr


def table(out: Path) -> list[dict[str, str]]:
    with open(out / "tables" / "checkpoints.csv", newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_chip_library_measures_the_known_error(world: dict[str, Path], tmp_path: Path) -> None:
    before = _snapshot(world["delivery"])
    out = tmp_path / "checker"
    code, _out, err = run(
        world["delivery"], "--reference", world["chips"], "--points", world["survey"], "--out", out
    )
    assert code == 0, err
    rows = table(out)
    with open(out / "tables" / "checkpoints.csv", encoding="utf-8") as fh:
        assert next(csv.reader(fh)) == list(COLUMNS)
    assert len(rows) == len(POINTS)  # every point textured and inside: all automatic
    image_sha = _sha(world["image"])
    for row in rows:
        assert row["decision"] == "accepted"
        assert float(row["x"]) - float(row["x_ref"]) == pytest.approx(DX_M, abs=0.02 * RES)
        assert float(row["y"]) - float(row["y_ref"]) == pytest.approx(DY_M, abs=0.02 * RES)
        assert row["image_sha256"] == image_sha
        assert row["reference_file"].endswith(f"{row['point_id']}.tif")
        assert row["reference_sha256"] == _sha(world["chips"] / f"{row['point_id']}.tif")
        assert row["method"].startswith("phase-correlation")
        assert row["chip_px"] == "64"
        assert float(row["score"]) > 0.9
        assert row["block"] == "B1" and row["image_id"] == "I1" and row["source"] == "GNSS survey"
        assert row["z_ref"] == str(10 * int(row["point_id"][1:])) and row["precision_xy"] == "0.05"
        assert row["tool_version"]
    assert _snapshot(world["delivery"]) == before  # nothing written into the delivery
    assert not (out / HAND_FILE).exists()  # nothing to measure by hand


def test_same_inputs_same_bytes(world: dict[str, Path], tmp_path: Path) -> None:
    survey = tmp_path / "survey.csv"  # one point far off the image: a hand list is written too
    survey.write_text(world["survey"].read_text() + "P99,300000,2700000,,flat,\n")
    outs = []
    for name in ("a", "b"):
        out = tmp_path / name
        code, _o, err = run(
            world["delivery"], "--reference", world["chips"], "--points", survey, "--out", out
        )
        assert code == 0, err
        outs.append(out)
    assert _sha(outs[0] / "tables" / "checkpoints.csv") == _sha(
        outs[1] / "tables" / "checkpoints.csv"
    )


def test_one_reference_orthoimage(world: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "checker"
    code, _o, err = run(
        world["delivery"],
        "--reference",
        world["reference"],
        "--points",
        world["survey"],
        "--out",
        out,
    )
    assert code == 0, err
    rows = table(out)
    assert len(rows) >= len(POINTS) - 1
    for row in rows:
        assert float(row["x"]) - float(row["x_ref"]) == pytest.approx(DX_M, abs=0.02 * RES)
        assert float(row["y"]) - float(row["y_ref"]) == pytest.approx(DY_M, abs=0.02 * RES)
        assert row["reference_sha256"] == _sha(world["reference"])


def test_reference_in_another_crs(world: dict[str, Path], tmp_path: Path) -> None:
    """The reference reprojected to Web Mercator (GDAL, Lanczos): resampled onto the image's grid
    again by the tool, the error is still found."""
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    ref = tmp_path / "ref3857.tif"
    with rasterio.open(world["reference"]) as ds:
        tr, w, h = calculate_default_transform(ds.crs, "EPSG:3857", ds.width, ds.height, *ds.bounds)
        prof = dict(ds.profile, crs="EPSG:3857", transform=tr, width=w, height=h)
        with rasterio.open(ref, "w", **prof) as o:
            for b in range(1, 4):
                reproject(rasterio.band(ds, b), rasterio.band(o, b), resampling=Resampling.lanczos)
    out = tmp_path / "checker"
    code, _o, err = run(
        world["delivery"], "--reference", ref, "--points", world["survey"], "--out", out
    )
    assert code == 0, err
    rows = table(out)
    assert len(rows) >= len(POINTS) - 2
    for row in rows:
        assert float(row["x"]) - float(row["x_ref"]) == pytest.approx(DX_M, abs=0.1 * RES)
        assert float(row["y"]) - float(row["y_ref"]) == pytest.approx(DY_M, abs=0.1 * RES)


def _flat_chip(world: dict[str, Path], chips: Path, k: int) -> None:
    """Replace chip P<k> by a flat field on the same footprint: nothing to match on."""
    with rasterio.open(world["chips"] / f"P{k}.tif") as ds:
        prof = ds.profile
    with rasterio.open(chips / f"P{k}.tif", "w", **prof) as o:
        o.write(np.full((3, 96, 96), 90, dtype=np.uint8))


def test_hand_list_round_trip(world: dict[str, Path], tmp_path: Path) -> None:
    chips = tmp_path / "chips"
    chips.mkdir()
    for f in world["chips"].iterdir():
        (chips / f.name).write_bytes(f.read_bytes())
    _flat_chip(world, chips, 2)
    _flat_chip(world, chips, 5)
    out = tmp_path / "checker"
    code, stdout, err = run(
        world["delivery"], "--reference", chips, "--points", world["survey"], "--out", out
    )
    assert code == 0, err
    assert "To measure by hand" in stdout
    assert {r["point_id"] for r in table(out)} == {f"P{k}" for k in range(1, 9)} - {"P2", "P5"}
    hand = out / HAND_FILE
    meta, _f, geom, fields = pyogrio.raw.read(hand)
    cols = dict(zip(meta["fields"], fields, strict=True))
    assert sorted(cols["point_id"]) == ["P2", "P5"]
    assert set(cols["status"]) == {"to measure"}
    assert all("low texture" in r for r in cols["reason"])
    assert meta["crs"] == "EPSG:32618"
    # the checker measures P2 in a GIS (moves the point, sets the status), finds P5 destroyed
    survey = {
        line.split(",")[0]: line.split(",") for line in world["survey"].read_text().splitlines()[1:]
    }
    x2, y2 = float(survey["P2"][1]) + 100.0, float(survey["P2"][2]) - 350.0
    status = np.array(
        ["measured" if p == "P2" else "unusable" for p in cols["point_id"]], dtype=object
    )
    comment = np.array(
        ["on the road crossing" if p == "P2" else "mark destroyed" for p in cols["point_id"]],
        dtype=object,
    )
    pts = [
        shapely.Point(x2, y2) if p == "P2" else shapely.from_wkb(g)
        for p, g in zip(cols["point_id"], geom, strict=True)
    ]
    edited = tmp_path / "edited.gpkg"
    pyogrio.raw.write(
        str(edited),
        shapely.to_wkb(pts),
        [np.asarray(cols["point_id"], dtype=object), status, comment],
        fields=["point_id", "status", "comment"],
        layer="checkpoints_to_measure",
        driver="GPKG",
        crs="EPSG:32618",
        geometry_type="Point",
    )
    hand.unlink()
    edited.rename(hand)
    hand_sha = _sha(hand)
    # run again: the hand list in the checker folder is merged
    code, _o, err = run(
        world["delivery"], "--reference", chips, "--points", world["survey"], "--out", out
    )
    assert code == 0, err
    rows = {r["point_id"]: r for r in table(out)}
    assert "P5" not in rows  # unusable: not a check point
    p2 = rows["P2"]
    assert p2["decision"] == "by_hand" and p2["method"] == "by hand"
    assert float(p2["x"]) == pytest.approx(x2) and float(p2["y"]) == pytest.approx(y2)
    assert p2["reference_sha256"] == hand_sha and HAND_FILE in p2["reference_file"]
    assert "low texture" in p2["reason"] and "on the road crossing" in p2["reason"]
    assert rows["P1"]["decision"] == "accepted"
    # the rewritten hand list keeps the checker's answers
    meta, _f, geom, fields = pyogrio.raw.read(out / HAND_FILE)
    cols = dict(zip(meta["fields"], fields, strict=True))
    assert dict(zip(cols["point_id"], cols["status"], strict=True)) == {
        "P2": "measured",
        "P5": "unusable",
    }


def test_hand_list_as_csv(world: dict[str, Path], tmp_path: Path) -> None:
    hand = tmp_path / "hand.csv"
    hand.write_text("point_id,status,x,y,comment\nP3,measured,1000.5,2000.25,checked twice\n")
    out = tmp_path / "checker"
    code, _o, err = run(
        world["delivery"],
        "--reference",
        world["chips"],
        "--points",
        world["survey"],
        "--out",
        out,
        "--hand",
        hand,
    )
    assert code == 0, err
    p3 = {r["point_id"]: r for r in table(out)}["P3"]
    assert (p3["decision"], p3["x"], p3["y"]) == ("by_hand", "1000.5", "2000.25")
    assert p3["reason"] == "accepted automatically; measured by hand: checked twice"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("point_id,status,x,y\nP3,done,1,2\n", "row 1: column 'status': unknown status 'done'"),
        (
            "point_id,status,x,y\nP3,measured,,2\n",
            "row 1: column 'x': a measured point needs a finite x",
        ),
        (
            "point_id,status,x,y\nP77,measured,1,2\n",
            "row 1: column 'point_id': point_id 'P77' is not in the survey",
        ),
    ],
)
def test_bad_hand_list(world: dict[str, Path], tmp_path: Path, text: str, message: str) -> None:
    hand = tmp_path / "hand.csv"
    hand.write_text(text)
    out = tmp_path / "checker"
    code, _o, err = run(
        world["delivery"],
        "--reference",
        world["chips"],
        "--points",
        world["survey"],
        "--out",
        out,
        "--hand",
        hand,
    )
    assert code == 2
    assert f"{hand}: {message}" in err
    assert not (out / "tables" / "checkpoints.csv").exists()


# ----------------------------------------------------------------------------- bad input


def _survey(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "survey.csv"
    p.write_text(text)
    return p


def test_points_outside_every_image(world: dict[str, Path], tmp_path: Path) -> None:
    survey = _survey(tmp_path, "point_id,x,y\nA,100,200\nB,300,400\n")
    code, _o, err = run(
        world["delivery"],
        "--reference",
        world["chips"],
        "--points",
        survey,
        "--out",
        tmp_path / "c",
    )
    assert code == 2
    assert (
        f"{survey}: none of its 2 point(s) lies on a delivered image: nothing can be measured"
        in err
    )
    assert (
        f"{survey}: row 1: point A at (100.000, 200.000) lies outside every delivered image" in err
    )
    assert not (tmp_path / "c").exists()


def test_some_points_outside(world: dict[str, Path], tmp_path: Path) -> None:
    survey = _survey(tmp_path, world["survey"].read_text() + "FAR,100,200,,,\n")
    code, _o, err = run(
        world["delivery"],
        "--reference",
        world["chips"],
        "--points",
        survey,
        "--out",
        tmp_path / "c",
    )
    assert code == 0
    assert (
        f"warning: {survey}: row 9: point FAR at (100.000, 200.000) lies outside every delivered image"
        in err
    )
    assert "FAR" not in {r["point_id"] for r in table(tmp_path / "c")}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("point_id,x,y\nA,1,2\nA,3,4\n", "column 'point_id': duplicate id 'A' in rows 1, 2"),
        ("point_id,x,y\nA,nan,2\n", "row 1: column 'x': expected a finite number"),
        ("point_id,x,y\nA,1,\n", "row 1: column 'y': required value is empty"),
        ("point_id,x\nA,1\n", "missing required column(s) y"),
        ("point_id,x,y,colour\nA,1,2,red\n", "unexpected column(s) colour"),
        ("point_id,x,y\n", "no survey point"),
    ],
)
def test_bad_survey(world: dict[str, Path], tmp_path: Path, text: str, message: str) -> None:
    survey = _survey(tmp_path, text)
    code, _o, err = run(
        world["delivery"],
        "--reference",
        world["chips"],
        "--points",
        survey,
        "--out",
        tmp_path / "c",
    )
    assert code == 2
    assert err.startswith(f"error: {survey}")
    assert message in err
    assert not (tmp_path / "c").exists()


def test_out_inside_the_delivery(world: dict[str, Path]) -> None:
    before = _snapshot(world["delivery"])
    code, _o, err = run(
        world["delivery"],
        "--reference",
        world["chips"],
        "--points",
        world["survey"],
        "--out",
        world["delivery"] / "checker",
    )
    assert code == 2 and "lies inside the delivery" in err
    assert _snapshot(world["delivery"]) == before


def test_reference_without_overlap(world: dict[str, Path], tmp_path: Path) -> None:
    ref = tmp_path / "far.tif"
    with rasterio.open(SRC) as ds:
        prof = dict(ds.profile, transform=Affine.translation(5e5, 0) * ds.transform)
        data = ds.read()
    with rasterio.open(ref, "w", **prof) as o:
        o.write(data)
    code, _o, err = run(
        world["delivery"], "--reference", ref, "--points", world["survey"], "--out", tmp_path / "c"
    )
    assert code == 2
    assert f"error: {ref}: the reference gives no usable chip for any surveyed point" in err
    assert "no reference chip covers the point" in err


@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_reference_without_crs(world: dict[str, Path], tmp_path: Path) -> None:
    ref = tmp_path / "nocrs.tif"
    with rasterio.open(ref, "w", driver="GTiff", width=50, height=50, count=1, dtype="uint8") as o:
        o.write(np.zeros((1, 50, 50), np.uint8))
    code, _o, err = run(
        world["delivery"], "--reference", ref, "--points", world["survey"], "--out", tmp_path / "c"
    )
    assert code == 2
    assert f"{ref}: has no coordinate reference system" in err


def test_tiny_and_huge_chips(world: dict[str, Path], tmp_path: Path) -> None:
    """A 1 px chip cannot be matched (that point goes to the hand list, naming the chip); a
    10^8 px chip is read only in the window around its point (bounded memory)."""
    chips = tmp_path / "chips"
    chips.mkdir()
    for k in (1, 3, 4):
        (chips / f"P{k}.tif").write_bytes((world["chips"] / f"P{k}.tif").read_bytes())
    with rasterio.open(world["chips"] / "P2.tif") as ds:
        t2, crs = ds.transform, ds.crs
    with rasterio.open(
        chips / "P2.tif",
        "w",
        driver="GTiff",
        width=1,
        height=1,
        count=1,
        dtype="uint8",
        crs=crs,
        transform=t2 * Affine.translation(48, 48),
    ) as o:
        o.write(np.full((1, 1, 1), 90, np.uint8))
    huge = chips / "P3.tif"  # replaces P3: 10,000 x 10,000 px around P3, constant, tiled
    with rasterio.open(world["chips"] / "P3.tif") as ds:
        t3 = ds.transform * Affine.translation(48 - 5000, 48 - 5000)
    with rasterio.open(
        huge,
        "w",
        driver="GTiff",
        width=10000,
        height=10000,
        count=1,
        dtype="uint8",
        crs=crs,
        transform=t3,
        tiled=True,
        compress="deflate",
        sparse_ok=True,
    ) as o:
        o.write(np.full((1, 512, 512), 90, np.uint8), window=Window(4744, 4744, 512, 512))
    survey = _survey(tmp_path, "\n".join(world["survey"].read_text().splitlines()[:5]) + "\n")
    out = tmp_path / "c"
    code, stdout, err = run(
        world["delivery"], "--reference", chips, "--points", survey, "--out", out, "--json"
    )
    assert code == 0, err
    import json

    doc = {p["point_id"]: p for p in json.loads(stdout)["points"]}
    assert doc["P2"]["decision"] == "to_measure" and doc["P2"]["reason_code"] == "reference"
    assert (
        f"{chips}/P2.tif covers too little around the point" in doc["P2"]["reason"]
        or "does not cover the point" in doc["P2"]["reason"]
    )
    assert doc["P3"]["decision"] == "to_measure" and doc["P3"]["reason_code"] == "low_texture"
    assert doc["P1"]["decision"] == doc["P4"]["decision"] == "accepted"


def test_all_chips_too_small(world: dict[str, Path], tmp_path: Path) -> None:
    chips = tmp_path / "chips"
    chips.mkdir()
    with rasterio.open(world["chips"] / "P1.tif") as ds:
        t1, crs = ds.transform, ds.crs
    with rasterio.open(
        chips / "P1.tif",
        "w",
        driver="GTiff",
        width=1,
        height=1,
        count=1,
        dtype="uint8",
        crs=crs,
        transform=t1 * Affine.translation(48, 48),
    ) as o:
        o.write(np.full((1, 1, 1), 90, np.uint8))
    survey = _survey(tmp_path, "\n".join(world["survey"].read_text().splitlines()[:2]) + "\n")
    code, _o, err = run(
        world["delivery"], "--reference", chips, "--points", survey, "--out", tmp_path / "c"
    )
    assert code == 2
    assert "the reference gives no usable chip for any surveyed point" in err


def test_no_reference(world: dict[str, Path], tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    code, _o, err = run(
        world["delivery"],
        "--reference",
        empty,
        "--points",
        world["survey"],
        "--out",
        tmp_path / "c",
    )
    assert code == 2 and f"{empty}: no usable reference chip: no .tif/.tiff file in it" in err
    code, _o, err = run(
        world["delivery"],
        "--reference",
        tmp_path / "nope.tif",
        "--points",
        world["survey"],
        "--out",
        tmp_path / "c",
    )
    assert code == 2 and "reference not found" in err


def test_subprocess_exit_codes(world: dict[str, Path], tmp_path: Path) -> None:
    """The installed command: exit 2 and one line on stderr for bad input, no traceback."""
    import subprocess
    import sys

    exe = Path(sys.executable).with_name("orthospec")
    survey = _survey(tmp_path, "point_id,x,y\nA,1,2\nA,3,4\n")
    r = subprocess.run(
        [
            str(exe),
            "measure",
            "checkpoints",
            str(world["delivery"]),
            "--reference",
            str(world["chips"]),
            "--points",
            str(survey),
            "--out",
            str(tmp_path / "c"),
        ],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert r.returncode == 2
    assert (
        r.stderr.startswith("error: ")
        and "duplicate id 'A'" in r.stderr
        and "Traceback" not in r.stderr
    )
