import json

import pytest
from click.testing import CliRunner
from tests.conftest import MANIFEST

from orthospec.cli.main import cli
from orthospec.provenance import sha256_file


def run(*args):
    return CliRunner().invoke(cli(), list(map(str, args)), catch_exceptions=False)


def run_main(args, capsys):
    """Through the real entry point (error mapping, exit codes) rather than click alone."""
    from orthospec.cli.main import main

    with pytest.raises(SystemExit) as exc:
        main(list(map(str, args)))
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


def test_rejected_delivery_exits_1_and_writes_outputs(make_delivery, mini_profile, tmp_path, capsys):
    out = tmp_path / "out"
    code, stdout, _ = run_main(["check", make_delivery(), "-p", mini_profile, "--out", out,
                                "--date", "2026-01-01"], capsys)
    assert code == 1
    assert "REJECTED" in stdout and "R-ROLLUP" in stdout
    assert "rules, 11 records" in stdout
    doc = json.loads((out / "qcr.json").read_text())
    assert doc["verdict"] == "rejected"
    assert (out / "qcr.csv").read_text().startswith("rule,clause,scope,item")
    junit = (out / "junit.xml").read_text()
    assert '<testsuite name="R-ROLLUP"' in junit and "<failure" in junit


def test_accepted_delivery_exits_0(make_delivery, mini_profile, tmp_path, capsys):
    images = "image_id,file,block,roll,flying_height,std_dn\nI1,a.tif,B1,0.5,1000,30\n"
    code, stdout, _ = run_main(["check", make_delivery(images=images), "-p", mini_profile,
                                "--out", tmp_path / "o", "--date", "2026-01-01"], capsys)
    assert code == 0 and "ACCEPTED" in stdout


def test_byte_identical_json_with_same_date(make_delivery, mini_profile, tmp_path, capsys):
    root = make_delivery()
    for o in ("a", "b"):
        run_main(["check", root, "-p", mini_profile, "--out", tmp_path / o, "--date", "2026-02-03",
                  "--format", "json"], capsys)
    assert sha256_file(tmp_path / "a" / "qcr.json") == sha256_file(tmp_path / "b" / "qcr.json")


@pytest.mark.parametrize("mutate, message", [
    (lambda m: m.replace("sensor: {type: aerial", "sensor: {type: zeppelin"), "delivery.yaml:6"),
    (lambda m: m.replace("images: tables/images.csv", "images: tables/nope.csv"), "file not found: tables/nope.csv"),
])
def test_bad_input_exit_2_no_traceback_no_outputs(make_delivery, mini_profile, tmp_path, capsys, mutate, message):
    out = tmp_path / "out"
    code, stdout, err = run_main(["check", make_delivery(manifest=mutate(MANIFEST)), "-p", mini_profile,
                                  "--out", out], capsys)
    assert code == 2
    assert message in err and err.startswith("error: ")
    assert "Traceback" not in err + stdout
    assert not out.exists()


def test_bad_csv_value_exit_2(make_delivery, mini_profile, tmp_path, capsys):
    images = "image_id,file,block,roll\nI1,a.tif,B1,1.5\nI2,b.tif,B1,x\n"
    code, _, err = run_main(["check", make_delivery(images=images), "-p", mini_profile, "--out", tmp_path / "o"],
                            capsys)
    assert code == 2
    assert "tables/images.csv: row 2: column 'roll': expected a number, got 'x'" in err


def test_unknown_profile_lists_available(make_delivery, capsys):
    code, _, err = run_main(["check", make_delivery(), "-p", "nope"], capsys)
    assert code == 2 and "unknown profile 'nope'; available:" in err


def test_unknown_format_is_a_usage_error(make_delivery, mini_profile, capsys):
    code, _, err = run_main(["check", make_delivery(), "-p", mini_profile, "--format", "docx"], capsys)
    assert code == 2 and "unknown format(s) docx" in err


def test_delivery_is_not_modified(make_delivery, mini_profile, tmp_path, capsys):
    root = make_delivery()
    before = {p.relative_to(root): sha256_file(p) for p in root.rglob("*") if p.is_file()}
    run_main(["check", root, "-p", mini_profile, "--out", tmp_path / "o"], capsys)
    after = {p.relative_to(root): sha256_file(p) for p in root.rglob("*") if p.is_file()}
    assert before == after


def test_terminal_caps_items_but_json_lists_all(make_delivery, mini_profile, tmp_path, capsys):
    rows = "\n".join(f"I{i},f{i}.tif,B1,5,1000,30" for i in range(30))
    _, stdout, _ = run_main(["check", make_delivery(images="image_id,file,block,roll,flying_height,std_dn\n"
                                                                + rows + "\n"), "-p", mini_profile,
                                "--out", tmp_path / "o", "--max-items", "3"], capsys)
    assert "I0, I1, I2 … (+26 more)" in stdout  # I3 is waived; natural order
    doc = json.loads((tmp_path / "o" / "qcr.json").read_text())
    roll = next(r for r in doc["rules"] if r["rule"] == "R-ROLL")
    assert len(roll["offending"]) == 29


def test_every_command_has_help():
    group = cli()

    def walk(cmd, path):
        yield path, cmd
        for name, sub in getattr(cmd, "commands", {}).items():
            yield from walk(sub, [*path, name])

    for path, cmd in walk(group, []):
        assert (cmd.help or "").strip(), f"orthospec {' '.join(path)} has no help text"
        assert run(*path, "--help").exit_code == 0


def test_outputs_are_ordinary_files(make_delivery, mini_profile, tmp_path, capsys):
    import os
    import stat

    run_main(["check", make_delivery(), "-p", mini_profile, "--out", tmp_path / "o", "--format", "json"], capsys)
    mode = stat.S_IMODE((tmp_path / "o" / "qcr.json").stat().st_mode)
    mask = os.umask(0)
    os.umask(mask)
    assert mode == 0o666 & ~mask
    assert not list((tmp_path / "o").glob(".*.tmp"))  # no temp file left behind
