import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from orthospec.cli.main import cli, main
from orthospec.provenance import sha256_file
from orthospec.qcr import all_records

CHECKER = """\
orthospec_checker: 1
checker: {name: A. Checker (fictional), role: external QC}
delivery: {id: D1}
parameters: {tolerance_xy: {value: 0.5, unit: m}}
manual_checks:
  - {check: R-VIS, item: "*", date: 2026-01-01, verdict: pass, note: visual check done}
waivers:
  - {rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}
"""


def run(*args):
    return CliRunner().invoke(cli(), list(map(str, args)))


def _checker(tmp_path):
    """The checker's own file (outside the delivery): the manual R-VIS verdict and the R-ROLL waiver
    the delivery only requests (docs/CHECKER.md)."""
    path = tmp_path / "checker.yaml"
    path.write_text(CHECKER, encoding="utf-8")
    return path


def test_sample_is_reproducible_and_rounds_differ(make_delivery, mini_profile, tmp_path):
    rows = "\n".join(f"I{i},f{i}.tif,B{i % 2 + 1},0.5,1000,30,{i * 100},{(i % 5) * 100}"
                     for i in range(40))
    root = make_delivery(
        images="image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n" + rows + "\n"
    )
    a, b, c = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    for out, rnd in ((a, 0), (b, 0), (c, 1)):
        res = run(
            "sample",
            root,
            "-p",
            mini_profile,
            "--seed",
            11,
            "--round",
            rnd,
            "--fraction",
            0.1,
            "--out",
            out,
        )
        assert res.exit_code == 0, res.output
    assert sha256_file(a) == sha256_file(b)
    assert a.read_text() != c.read_text()
    assert "selected 4 of 40 images" in res.output


def test_check_with_sample_only_judges_sampled_images(make_delivery, mini_profile, tmp_path):
    root = make_delivery()
    sample = tmp_path / "s.csv"
    sample.write_text("item,scope,reason,seed,round\nI1,image,random,1,0\nI3,image,random,1,0\n")
    res = run(
        "check",
        root,
        "-p",
        mini_profile,
        "--sample",
        sample,
        "--out",
        tmp_path / "o",
        "--date",
        "2026-01-01",
        "--format",
        "json",
        "--checker",
        _checker(tmp_path),
    )
    doc = json.loads((tmp_path / "o" / "qcr.json").read_text())
    fh = {r["item"]: r for r in all_records(doc) if r["rule"] == "R-FH"}
    assert fh["I2"]["verdict"] == "not_applicable"
    assert "not in the external QC sample" in fh["I2"]["message"]
    share = next(r for r in all_records(doc) if r["rule"] == "R-ROLLUP")
    assert share["measured"]["value"] == 0.0  # I2 (the failing one) was not sampled
    assert res.exit_code == 0


def test_bad_sample_table(make_delivery, mini_profile, tmp_path):
    sample = tmp_path / "s.csv"
    sample.write_text("item,scope\nI1,galaxy\n")
    res = run(
        "check", make_delivery(), "-p", mini_profile, "--sample", sample, "--out", tmp_path / "o"
    )
    assert res.exit_code != 0


def test_tightened_ledger_state_draws_a_larger_sample_with_the_suspects(
    make_delivery, mini_profile, tmp_path
):
    rows = "\n".join(
        f"I{i},f{i}.tif,B1,{5 if i == 7 else 0.5},1000,30,{i * 100},{(i % 5) * 100}"
        for i in range(40)
    )
    root = make_delivery(
        images="image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n" + rows + "\n"
    )
    ledger = tmp_path / "ledger.sqlite"
    res = run(
        "check",
        root,
        "-p",
        mini_profile,
        "--out",
        tmp_path / "o",
        "--ledger",
        ledger,
        "--date",
        "2026-01-01",
        "--checker",
        _checker(tmp_path),
    )
    # 1 failing image in 40 (2.5 %) is within the §12.3 5 % rule: accepted, but its family turns tightened
    assert res.exit_code == 0, res.output
    normal = run(
        "sample",
        root,
        "-p",
        mini_profile,
        "--seed",
        3,
        "--fraction",
        0.1,
        "--out",
        tmp_path / "n.csv",
    )
    tight = run(
        "sample",
        root,
        "-p",
        mini_profile,
        "--seed",
        3,
        "--fraction",
        0.1,
        "--ledger",
        ledger,
        "--out",
        tmp_path / "t.csv",
    )
    assert "audit level normal" in normal.output
    assert "audit level tightened" in tight.output, tight.output
    n_ids = (tmp_path / "n.csv").read_text().splitlines()[1:]
    t_ids = (tmp_path / "t.csv").read_text().splitlines()[1:]
    assert len(t_ids) > len(n_ids)
    assert any(line.startswith("I7,") for line in t_ids)


REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"


def _real_rgb() -> Path:
    path = REAL / "RGB.byte.tif"
    if not path.exists():
        pytest.skip(f"real test image {path.name} not found in {REAL} (shared data absent)")
    return path


def test_sample_places_images_by_their_footprint(make_delivery, mini_profile, tmp_path):
    """Without exposure columns the images are placed at their footprint's centre (read through
    raster/roi.py): a real GeoTIFF three times gives a sample of them."""
    rgb = _real_rgb()
    root = make_delivery()
    (root / "images").mkdir()
    for i in (1, 2, 3):
        (root / "images" / f"i{i}.tif").write_bytes(rgb.read_bytes())
    res = run(
        "sample",
        root,
        "-p",
        mini_profile,
        "--seed",
        3,
        "--fraction",
        0.5,
        "--out",
        tmp_path / "s.csv",
    )
    assert res.exit_code == 0, res.output
    assert "selected 2 of 3 images" in res.output


def test_sample_refuses_an_unreadable_image_naming_it(
    make_delivery, mini_profile, tmp_path, capsys
):
    """Issue 15 item 2: an unreadable image was placed at (0, 0) silently, which moves the
    systematic part of the sample. Now: exit 2, the file and its row in images.csv named."""
    data = _real_rgb().read_bytes()
    root = make_delivery()
    (root / "images").mkdir()
    for i in (1, 3):
        (root / "images" / f"i{i}.tif").write_bytes(data)
    (root / "images" / "i2.tif").write_bytes(data[: len(data) // 2])  # truncated: the IFD is lost
    with pytest.raises(SystemExit) as exc:  # the executable's error boundary: error line, exit 2
        main(
            [
                "sample",
                str(root),
                "-p",
                str(mini_profile),
                "--seed",
                "3",
                "--out",
                str(tmp_path / "s.csv"),
            ]
        )
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert err.startswith(
        "error: tables/images.csv: row 2: image I2 cannot be placed for the sample"
    )
    assert "images/i2.tif: not a readable raster" in err
    assert "Traceback" not in err and not (tmp_path / "s.csv").exists()
