"""`orthospec measure accuracy` through CliRunner: JSON keys, units, blunders, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.measures.accuracy import accuracy_stats

US_FT = 1200 / 3937


def _write(tmp_path, text, name="points.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return str(p)


def _run(*args):
    return CliRunner().invoke(cli(), ["measure", "accuracy", *args])


def _coords_csv(n=20, unit_col=None, seed=0):
    rng = np.random.default_rng(seed)
    ref = rng.uniform(0, 1000, (n, 2))
    d = rng.normal(0, 0.3, (n, 2))
    dz = rng.normal(0, 0.5, n)
    lines = ["id,x,y,z,x_ref,y_ref,z_ref" + (",unit" if unit_col else "")]
    for i in range(n):
        row = [f"P{i}", ref[i, 0] + d[i, 0], ref[i, 1] + d[i, 1], 100 + dz[i], ref[i, 0],
               ref[i, 1], 100.0]
        lines.append(",".join(str(v) for v in row) + (f",{unit_col}" if unit_col else ""))
    return "\n".join(lines) + "\n", d, dz


def test_json_output_matches_library(tmp_path):
    text, d, dz = _coords_csv()
    res = _run(_write(tmp_path, text), "--json", "--gsd", "0.25")
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    ref = accuracy_stats(d[:, 0], d[:, 1], dz)
    for key in ("n", "mean_x", "mean_y", "mean_z", "std_x", "std_y", "std_z", "rmse_x", "rmse_y",
                "rmse_z", "rmse_r", "nssda_horizontal_95", "nssda_vertical_95", "ce90", "ce95",
                "bias_ratio", "bias_negligible", "ce90_empirical", "ce95_empirical",
                "max_abs_dx", "max_abs_dy", "max_dr"):
        assert out[key] == pytest.approx(getattr(ref, key), rel=1e-6), key
    assert out["units"] == "m" and out["blunders"]["basis"] == "calculated"
    assert len(out["blunders"]["decisions"]) == 20
    assert out["in_gsd"]["rmse_x"] == pytest.approx(ref.rmse_x / 0.25, rel=1e-6)


def test_deltas_layout_without_z_gives_null_axes(tmp_path):
    path = _write(tmp_path, "id,dx,dy\nA,0.1,0.2\nB,-0.1,0.0\nC,0.3,-0.2\n")
    out = json.loads(_run(path, "--json").stdout)
    assert out["layout"] == "deltas"
    assert out["mean_z"] is None and out["rmse_z"] is None and out["nssda_vertical_95"] is None
    assert out["rmse_x"] == pytest.approx(np.sqrt((0.01 + 0.01 + 0.09) / 3))


@pytest.mark.parametrize(("unit", "factor"), [("ft", 0.3048), ("usft", US_FT)])
def test_feet_converted_to_metres(tmp_path, unit, factor):
    text = "id,dx,dy\nA,1.0,2.0\nB,-1.0,-2.0\n"
    via_option = json.loads(_run(_write(tmp_path, text), "--json", "--units", unit).stdout)
    col = f"id,dx,dy,unit\nA,1.0,2.0,{unit}\nB,-1.0,-2.0,{unit}\n"
    via_column = json.loads(_run(_write(tmp_path, col, "c.csv"), "--json").stdout)
    for out in (via_option, via_column):
        assert out["rmse_x"] == pytest.approx(factor, rel=1e-9)  # JSON keeps 10 digits
        assert out["rmse_y"] == pytest.approx(2 * factor, rel=1e-9)
        assert out["source_units"] == unit and out["units"] == "m"


def test_blunder_exclusion_from_csv(tmp_path):
    lines = ["id,dx,dy,excluded,exclusion_reason"]
    rng = np.random.default_rng(2)
    for i in range(20):
        dx = 5.0 if i == 4 else rng.normal(0, 0.2)
        just = "survey mark destroyed" if i == 4 else ""
        flag = "true" if i in (4, 9) else "false"
        lines.append(f"P{i},{dx},{rng.normal(0, 0.2)},{flag},{just}")
    out = json.loads(_run(_write(tmp_path, "\n".join(lines) + "\n"), "--json").stdout)
    assert out["blunders"]["excluded"] == ["P4"]
    assert out["blunders"]["errors"] == ["P9"]  # within tolerance: never excluded
    assert out["after_exclusions"]["n"] == 19
    assert out["n"] == 20


def test_table_output(tmp_path):
    text, _, _ = _coords_csv()
    res = _run(_write(tmp_path, text), "--gsd", "0.25")
    assert res.exit_code == 0
    assert "rmse_x" in res.stdout and "GSD units" in res.stdout and "Blunders" in res.stdout


@pytest.mark.parametrize(
    ("text", "args", "match"),
    [
        ("id,x,y\nA,1,2\nB,1,2\n", [], "missing column.*x_ref.*expected"),
        ("id,dx,dy\nA,1,2\nB,abc,2\n", [], "row 2.*'dx'.*number"),
        ("id,dx,dy\nA,1,2\nB,inf,2\n", [], "row 2.*finite"),
        ("id,dx,dy\nA,1,2\nA,1,3\n", [], "row 2.*duplicate point id 'A'"),
        ("id,dx,dy\nA,1,2\n", [], "at least 2"),
        ("id,dx,dy,unit\nA,1,2,m\nB,1,3,ft\n", [], "mixed units"),
        ("id,dx,dy,unit\nA,1,2,m\nB,1,3,m\n", ["--units", "ft"], "unit column says m"),
        ("id,dx,dy\nA,1,2\nB,2,3\n", ["--blunder-basis", "target"], "target RMSE"),
        ("id,dx,dy,dz\nA,1,2,\nB,2,3,1\n", [], "row 1.*'dz'.*partly"),
        ("id,dx,dy,dx\nA,1,2,1\nB,2,3,1\n", [], "duplicate column.*dx"),
        ("id,dx,dy,excluded\nA,1,2,maybe\nB,2,3,no\n", [], "row 1.*excluded.*true/false"),
    ],
)
def test_bad_input_exit_2_without_traceback(tmp_path, text, args, match):
    import re

    res = _run(_write(tmp_path, text), *args)
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("error: ")
    assert re.search(match, res.stderr), res.stderr
    assert "Traceback" not in res.output


def test_missing_file_exit_2(tmp_path):
    res = _run(str(tmp_path / "nope.csv"))
    assert res.exit_code == 2 and "not found" in res.stderr and "Traceback" not in res.output


def test_nearest_rank_percentile_option(tmp_path):
    rows = "\n".join(f"P{i},{i + 1},0" for i in range(10))
    path = _write(tmp_path, "id,dx,dy\n" + rows + "\n")
    lin = json.loads(_run(path, "--json").stdout)
    nr = json.loads(_run(path, "--json", "--percentile", "nearest-rank").stdout)
    assert lin["ce90_empirical"] == pytest.approx(9.1) and nr["ce90_empirical"] == 9.0
    assert nr["percentile_method"] == "nearest-rank"


def test_help_text():
    res = CliRunner().invoke(cli(), ["measure", "accuracy", "--help"])
    assert res.exit_code == 0 and "--blunder-basis" in res.output and "x_ref" in res.output


def test_reads_a_delivery_checkpoints_table_per_block() -> None:
    """A check point table of the convention (extra columns image_id, source, the checker's provenance
    columns ...) is accepted, per block; the RMSE of each block recomputed here with numpy from
    x - x_ref (points excluded or not: all kept). Here the checker's measurements of aerial-fail."""
    import csv as _csv
    import json as _json
    from pathlib import Path as _Path

    import numpy as _np
    from click.testing import CliRunner as _Runner

    from orthospec.cli.main import cli as _cli

    path = (
        _Path(__file__).resolve().parents[1]
        / "examples"
        / "checker"
        / "aerial-fail"
        / "tables"
        / "checkpoints.csv"
    )
    res = _Runner().invoke(_cli(), ["measure", "accuracy", str(path), "--json"])
    assert res.exit_code == 0, res.output
    out = _json.loads(res.stdout)
    assert "image_id" in out["ignored_columns"]
    rows = list(_csv.DictReader(path.open(encoding="utf-8")))
    for block in {r["block"] for r in rows}:
        sub = [r for r in rows if r["block"] == block]
        dy = _np.array([float(r["y"]) - float(r["y_ref"]) for r in sub])
        assert out["blocks"][block]["n"] == len(sub)
        assert abs(out["blocks"][block]["rmse_y"] - float(_np.sqrt(_np.mean(dy**2)))) < 1e-6
    assert round(out["blocks"]["B02"]["rmse_y"], 3) == 0.641  # the example's documented failure
