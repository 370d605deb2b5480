"""Red team findings fixed where the delivery is read (tests/REDTEAM.md R2, R3, R4).

R14: a number outside its column's min/max is refused where the table is read.
R3: a row naming a block the manifest does not declare is refused (exit 2), in every table with a
block column. R2: a table's coordinate unit is the project CRS's axis unit (pyproj), and block
polygons are read in the CRS unit, never in the points' unit. R4: distinct ids at one reference
position are counted (checkpoints.duplicate_locations) - since issue 25, positions nearer than the
separation (max(tolerance, 2 px)), not a 1 mm grid, and only the repeats (the first point stays).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.conftest import MANIFEST

from orthospec.delivery.convention import ColumnSpec, TableSpec
from orthospec.delivery.reader import open_delivery, parse_csv
from orthospec.engine.providers import checkpoints as cp
from orthospec.engine.registry import ProviderContext, describe
from orthospec.errors import DeliveryError
from orthospec.measures.independence import repeated_positions

CP = "point_id,block,x,y,x_ref,y_ref\n"
US_FT = 1200 / 3937  # the US survey foot in metres (NIST)


def _with(table: str, rel: str, manifest: str = MANIFEST) -> str:
    return manifest.replace(
        "tables: {images: tables/images.csv,",
        f"tables: {{{table}: {rel}, images: tables/images.csv,",
    )


# --- R3 -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("table", "text"),
    [
        ("checkpoints", CP + "P1,B1,1,2,1,2\nP2,B99,1,2,1,2\n"),
        ("gcps", "point_id,block,x,y\nG1,B1,1,2\nG2,B99,3,4\n"),
        ("aerotriangulation", "block\nB1\nB99\n"),
    ],
)
def test_row_of_an_undeclared_block_is_refused(make_delivery, table, text):
    d = open_delivery(
        make_delivery(manifest=_with(table, "tables/t.csv"), extra={"tables/t.csv": text})
    )
    with pytest.raises(DeliveryError) as err:
        d.table(table)
    msg = str(err.value)
    assert msg.startswith("tables/t.csv: row 2: column 'block': ")
    assert "'B99'" in msg and "blocks: B1, B2" in msg


def test_images_of_an_undeclared_block_are_refused(make_delivery):
    images = "image_id,file,block\nI1,images/i1.tif,B1\nI2,images/i2.tif,B2\nI3,images/i3.tif,B3\n"
    d = open_delivery(make_delivery(images=images))
    with pytest.raises(
        DeliveryError, match=r"tables/images.csv: row 3: column 'block': block 'B3'"
    ):
        d.table("images")


def test_without_manifest_blocks_the_tables_name_them(make_delivery):
    manifest = MANIFEST.replace("blocks: [{id: B1}, {id: B2}]\n", "")
    d = open_delivery(make_delivery(manifest=manifest))
    assert d.table("images").df["block"].tolist() == ["B1", "B1", "B2"]
    assert d.block_ids == ["B1", "B2"]


def test_example_with_points_moved_to_unknown_block_is_refused(example_copy):
    """aerial-pass with one B02 point relabelled B99: refused when the delivery is opened (exit 2),
    before any check can leave the point out of B02's statistics."""
    root = example_copy("aerial-pass")
    path = root / "tables" / "checkpoints.csv"
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    col = lines[0].split(",").index("block")
    row = next(i for i, line in enumerate(lines) if line.split(",")[col] == "B02")
    cells = lines[row].split(",")
    cells[col] = "B99"
    lines[row] = ",".join(cells)
    path.write_text("".join(lines), encoding="utf-8")
    with pytest.raises(DeliveryError) as err:
        open_delivery(root).load_all_tables()
    assert str(err.value).startswith(
        f"tables/checkpoints.csv: row {row}: column 'block': block 'B99'"
    )
    assert "blocks: B01, B02" in str(err.value)


# --- R2 -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("crs", "unit", "words"),
    [
        (
            "EPSG:25832",
            "ft",
            ["units.checkpoints is ft", "axes are in m", "set units.checkpoints: m"],
        ),
        ("EPSG:25832", "mm", ["units.checkpoints is mm", "axes are in m"]),
        ("EPSG:2263", None, ["units.checkpoints is not given (m is assumed)", "axes are in usft"]),
        ("EPSG:2263", "ft", ["units.checkpoints is ft", "axes are in usft"]),
        ("EPSG:4326", "m", ["axes in degree, not a length"]),
    ],
)
def test_coordinate_unit_must_be_the_crs_unit(make_delivery, crs, unit, words):
    manifest = _with("checkpoints", "tables/cp.csv", MANIFEST.replace("EPSG:25832", crs))
    if unit:
        manifest += f"units: {{checkpoints: {unit}}}\n"
    d = open_delivery(
        make_delivery(manifest=manifest, extra={"tables/cp.csv": CP + "P1,B1,1,2,1,2\n"})
    )
    with pytest.raises(DeliveryError) as err:
        d.table("checkpoints")
    msg = str(err.value)
    assert msg.startswith("delivery.yaml:"), msg
    for w in words:
        assert w in msg, msg


def test_matching_units_are_read(make_delivery):
    manifest = _with("checkpoints", "tables/cp.csv", MANIFEST.replace("EPSG:25832", "EPSG:2263"))
    manifest += "units: {checkpoints: usft}\n"
    d = open_delivery(
        make_delivery(manifest=manifest, extra={"tables/cp.csv": CP + "P1,B1,1,2,1,2\n"})
    )
    assert d.table("checkpoints").units["x"] == "usft"
    assert d.crs_unit == "usft"


def test_block_polygon_is_in_the_crs_unit_not_the_points_unit(make_delivery):
    """A 1000 x 1000 usft block in EPSG:2263 is 304.8 m wide (NIST US survey foot); in EPSG:25832
    the same numbers are metres."""
    square = "polygon: [[0, 0], [1000, 0], [1000, 1000], [0, 1000]]"
    for crs, units, side in (
        ("EPSG:2263", "units: {checkpoints: usft}\n", 1000 * US_FT),
        ("EPSG:25832", "", 1000.0),
    ):
        manifest = _with("checkpoints", "tables/cp.csv", MANIFEST.replace("EPSG:25832", crs))
        manifest = manifest.replace("{id: B1}", "{id: B1, " + square + "}") + units
        d = open_delivery(
            make_delivery(
                crs[5:], manifest=manifest, extra={"tables/cp.csv": CP + "P1,B1,1,2,1,2\n"}
            )
        )
        polys, broken = cp._outlines(ProviderContext(d, {}))
        assert not broken
        assert polys["B1"].bounds == pytest.approx((0.0, 0.0, side, side), rel=1e-12)


# --- R4 -------------------------------------------------------------------------------------------


def test_repeats_within_the_separation_keep_the_first_point():
    x = np.array([100.0, 100.004, 200.0, 300.0, 300.3, 300.0, 400.0])
    y = np.array([50.0, 50.0, 60.0, 70.0, 70.0, 70.2, 70.0])
    # 0.5 m: the copy 4 mm off repeats point 0; 300.3 and (300, 70.2) repeat point 3
    assert repeated_positions(x, y, 0.5).tolist() == [-1, 0, -1, -1, 3, 3, -1]
    assert (
        repeated_positions(np.array([0.0, 0.6]), np.array([0.0, 0.0]), 0.5) == -1
    ).all()  # 0.6 m apart


@given(
    st.lists(
        st.tuples(
            st.sampled_from([0.0, 0.3, 0.45, 0.9, 5.0, 5.4, 1e6, float("nan")]),
            st.sampled_from([0.0, 0.2, 0.49, 3.0, 3.5, 7e6, float("nan")]),
        ),
        max_size=40,
    )
)
@settings(max_examples=300, deadline=None)
def test_repeated_positions_leave_a_separated_set(points):
    """Against the definition over all pairs: no two kept points are nearer than the separation, every
    repeat is near a point it was grouped with, the earliest point of each group is kept, and a point
    with no neighbour within the separation (NaN positions included) is kept."""
    x = np.array([p[0] for p in points], dtype=float)
    y = np.array([p[1] for p in points], dtype=float)
    sep = 0.5
    rep = repeated_positions(x, y, sep)
    kept = [i for i in range(len(x)) if rep[i] < 0]
    ok = np.isfinite(x) & np.isfinite(y)
    near = [
        [
            j
            for j in range(len(x))
            if j != i and ok[i] and ok[j] and np.hypot(x[i] - x[j], y[i] - y[j]) < sep
        ]
        for i in range(len(x))
    ]
    assert all(not (set(near[i]) & set(kept)) for i in kept)  # the kept set is separated
    assert all(
        rep[i] < i for i in range(len(x)) if rep[i] >= 0
    )  # a repeat names an earlier point...
    assert all(rep[rep[i]] < 0 for i in range(len(x)) if rep[i] >= 0)  # ...that is kept
    assert all(rep[i] < 0 for i in range(len(x)) if not near[i])  # alone: kept
    assert all(
        rep[i] < 0 for i in range(len(x)) if near[i] and i < min(near[i])
    )  # earliest of its neighbours


def test_block_measure_counts_copies_under_new_ids(make_delivery):
    rows = "".join(f"P{i},B1,{i * 10 + 0.1},{i * 7 + 0.2},{i * 10},{i * 7}\n" for i in range(10))
    copies = "".join(f"X{i},B1,{i * 10 + 0.1},{i * 7 + 0.2},{i * 10},{i * 7}\n" for i in range(3))
    other = "".join(f"Q{i},B2,{i}.1,{i}.2,{i},{i}\n" for i in range(5))
    d = open_delivery(
        make_delivery(
            manifest=_with("checkpoints", "tables/cp.csv"),
            extra={"tables/cp.csv": CP + rows + copies + other},
        )
    )
    got = {m.name: m for m in cp.block_checkpoint_stats(ProviderContext(d, {"tolerance_xy": 0.5}))}
    m = got["checkpoints.duplicate_locations"]
    assert m.unit == "1"
    assert m.values.to_dict() == {
        "B1": 3,
        "B2": 0,
    }  # the copies X0-X2 (P0-P2 stay in the statistics)
    assert "X0" in m.notes["B1"] and "JRC §12.5" in m.notes["B1"] and "P0" in m.notes["B1"]
    assert got["checkpoints.n"].values["B1"] == 10  # the copies dilute nothing
    assert "separation" in describe("checkpoints.duplicate_locations")


def test_a_block_list_names_only_manifest_blocks(make_delivery):
    """The dem table's block cell may list several blocks ("B1;B2", derived.dem_blocks): each is checked."""
    manifest = _with("dem", "tables/dem.csv")
    ok = open_delivery(
        make_delivery(
            "ok", manifest=manifest, extra={"tables/dem.csv": "dem_id,block\nD1,B1; B2\n"}
        )
    )
    assert ok.table("dem").df["block"].tolist() == ["B1; B2"]
    bad = open_delivery(
        make_delivery(
            "bad", manifest=manifest, extra={"tables/dem.csv": "dem_id,block\nD1,B1\nD2,B2;B7\n"}
        )
    )
    with pytest.raises(DeliveryError, match=r"tables/dem.csv: row 2: column 'block': block 'B7'"):
        bad.table("dem")


# --- R14 ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Bounded(ColumnSpec):
    """A column spec with the `min:`/`max:` keys of specs/delivery-tables.yaml (convention.ColumnSpec
    gains them on request, /tmp/team/requests-B2 R14)."""

    min: float | None = None
    max: float | None = None


_BOUNDED = TableSpec(
    "t",
    "image",
    "id",
    "",
    {
        "id": ColumnSpec("id", "text", None, True, ""),
        "rmse": _Bounded("rmse", "number", "m", False, "", min=0.0),
        "share": _Bounded("share", "number", "%", False, "", min=0.0, max=100.0),
    },
)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "id,rmse,share\nA,0.3,5\nB,-0.5,5\n",
            "t.csv: row 2: column 'rmse': -0.5 is below the minimum 0 of this column",
        ),
        (
            "id,rmse,share\nA,0,100.5\n",
            "t.csv: row 1: column 'share': 100.5 is above the maximum 100 of this column",
        ),
        (
            "id,rmse,share\nA,1,2\nB,2,-1e-9\n",
            "t.csv: row 2: column 'share': -1e-09 is below the minimum 0 of this column",
        ),
    ],
)
def test_number_outside_its_column_bounds_is_refused(text, message):
    with pytest.raises(DeliveryError) as err:
        parse_csv(text, _BOUNDED, file="t.csv")
    assert str(err.value) == message


def test_bounds_are_inclusive_and_blank_cells_unbounded():
    df = parse_csv("id,rmse,share\nA,0,0\nB,,100\nC,2.5,\n", _BOUNDED, file="t.csv")
    assert df["rmse"].tolist()[0] == 0.0 and np.isnan(df["rmse"].tolist()[1])
    assert df["share"].tolist()[:2] == [0.0, 100.0]
