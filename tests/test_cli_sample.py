import json

from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.provenance import sha256_file


def run(*args):
    return CliRunner().invoke(cli(), list(map(str, args)))


def test_sample_is_reproducible_and_rounds_differ(make_delivery, mini_profile, tmp_path):
    rows = "\n".join(f"I{i},f{i}.tif,B{i % 2 + 1},0.5,1000,30,{i * 100},{(i % 5) * 100}"
                     for i in range(40))
    root = make_delivery(images="image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n" + rows + "\n")
    a, b, c = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    for out, rnd in ((a, 0), (b, 0), (c, 1)):
        res = run("sample", root, "-p", mini_profile, "--seed", 11, "--round", rnd, "--fraction", 0.1, "--out", out)
        assert res.exit_code == 0, res.output
    assert sha256_file(a) == sha256_file(b)
    assert a.read_text() != c.read_text()
    assert "selected 4 of 40 images" in res.output


def test_check_with_sample_only_judges_sampled_images(make_delivery, mini_profile, tmp_path):
    root = make_delivery()
    sample = tmp_path / "s.csv"
    sample.write_text("item,scope,reason,seed,round\nI1,image,random,1,0\nI3,image,random,1,0\n")
    res = run("check", root, "-p", mini_profile, "--sample", sample, "--out", tmp_path / "o",
              "--date", "2026-01-01", "--format", "json")
    doc = json.loads((tmp_path / "o" / "qcr.json").read_text())
    fh = {r["item"]: r for r in doc["records"] if r["rule"] == "R-FH"}
    assert fh["I2"]["verdict"] == "not_applicable"
    assert "not in the external QC sample" in fh["I2"]["message"]
    share = next(r for r in doc["records"] if r["rule"] == "R-ROLLUP")
    assert share["measured"]["value"] == 0.0  # I2 (the failing one) was not sampled
    assert res.exit_code == 0


def test_bad_sample_table(make_delivery, mini_profile, tmp_path):
    sample = tmp_path / "s.csv"
    sample.write_text("item,scope\nI1,galaxy\n")
    res = run("check", make_delivery(), "-p", mini_profile, "--sample", sample, "--out", tmp_path / "o")
    assert res.exit_code != 0
