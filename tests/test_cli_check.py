import json
from html import unescape

import pytest
from click.testing import CliRunner
from tests.checking import write_checker
from tests.conftest import MANIFEST

from orthospec.cli.main import cli
from orthospec.provenance import sha256_file
from orthospec.qcr import all_records

#: the ITT tolerance the mini profile requires: the manifest's declared value is the contractor's
#: evidence, never the value in force (docs/CHECKER.md), so a check states it as the checker would
ITT = ["--param", "tolerance_xy=0.5m"]


def _with_itt(args):
    args = list(map(str, args))
    if args[:1] == ["check"] and "--param" not in args and "--checker" not in args:
        args += ITT
        if "jrc-v3" in args:
            args += ["--param", "map_crs=EPSG:25832"]  # the ITT's map projection (red team R16)
    return args


def run(*args):
    return CliRunner().invoke(cli(), _with_itt(args), catch_exceptions=False)


def run_main(args, capsys):
    """Through the real entry point (error mapping, exit codes) rather than click alone."""
    from orthospec.cli.main import main

    with pytest.raises(SystemExit) as exc:
        main(_with_itt(args))
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


def test_rejected_delivery_exits_1_and_writes_outputs(
    make_delivery, mini_profile, tmp_path, capsys
):
    out = tmp_path / "out"
    code, stdout, _ = run_main(
        ["check", make_delivery(), "-p", mini_profile, "--out", out, "--date", "2026-01-01"], capsys
    )
    assert code == 1
    assert "REJECTED" in stdout and "R-ROLLUP" in stdout
    # 11 profile records (R-ROLLUP, R-VIS: 1 each; R-CV, R-FH, R-ROLL: 3 images each) + the built-in
    # ORTHOSPEC-ITT-DECLARED record of tolerance_xy (given with --param)
    assert "rules, 12 records" in stdout
    doc = json.loads((out / "qcr.json").read_text())
    assert doc["verdict"] == "rejected"
    assert (out / "qcr.csv").read_text().startswith("rule,clause,scope,item")
    junit = (out / "junit.xml").read_text()
    assert '<testsuite name="R-ROLLUP"' in junit and "<failure" in junit


def test_accepted_delivery_exits_0(make_delivery, mini_profile, tmp_path, capsys):
    images = "image_id,file,block,roll,flying_height,std_dn\nI1,a.tif,B1,0.5,1000,30\n"
    code, stdout, _ = run_main(
        [
            "check",
            make_delivery(images=images),
            "-p",
            mini_profile,
            "--checker",
            write_checker(tmp_path),
            "--out",
            tmp_path / "o",
            "--date",
            "2026-01-01",
        ],
        capsys,
    )
    assert code == 0 and "ACCEPTED" in stdout


def test_byte_identical_json_with_same_date(make_delivery, mini_profile, tmp_path, capsys):
    root = make_delivery()
    for o in ("a", "b"):
        run_main(
            [
                "check",
                root,
                "-p",
                mini_profile,
                "--out",
                tmp_path / o,
                "--date",
                "2026-02-03",
                "--format",
                "json",
            ],
            capsys,
        )
    assert sha256_file(tmp_path / "a" / "qcr.json") == sha256_file(tmp_path / "b" / "qcr.json")


@pytest.mark.parametrize(
    "mutate, message",
    [
        (
            lambda m: m.replace("sensor: {type: aerial", "sensor: {type: zeppelin"),
            "delivery.yaml:6",
        ),
        (
            lambda m: m.replace("images: tables/images.csv", "images: tables/nope.csv"),
            "file not found: tables/nope.csv",
        ),
    ],
)
def test_bad_input_exit_2_no_traceback_no_outputs(
    make_delivery, mini_profile, tmp_path, capsys, mutate, message
):
    out = tmp_path / "out"
    code, stdout, err = run_main(
        ["check", make_delivery(manifest=mutate(MANIFEST)), "-p", mini_profile, "--out", out],
        capsys,
    )
    assert code == 2
    assert message in err and err.startswith("error: ")
    assert "Traceback" not in err + stdout
    assert not out.exists()


def test_bad_csv_value_exit_2(make_delivery, mini_profile, tmp_path, capsys):
    images = "image_id,file,block,roll\nI1,a.tif,B1,1.5\nI2,b.tif,B1,x\n"
    code, _, err = run_main(
        ["check", make_delivery(images=images), "-p", mini_profile, "--out", tmp_path / "o"], capsys
    )
    assert code == 2
    assert "tables/images.csv: row 2: column 'roll': expected a number, got 'x'" in err


def test_unknown_profile_lists_available(make_delivery, capsys):
    code, _, err = run_main(["check", make_delivery(), "-p", "nope"], capsys)
    assert code == 2 and "unknown profile 'nope'; available:" in err


def test_unknown_format_is_a_usage_error(make_delivery, mini_profile, capsys):
    code, _, err = run_main(
        ["check", make_delivery(), "-p", mini_profile, "--format", "docx"], capsys
    )
    assert code == 2 and "unknown format(s) docx" in err


def test_delivery_is_not_modified(make_delivery, mini_profile, tmp_path, capsys):
    root = make_delivery()
    before = {p.relative_to(root): sha256_file(p) for p in root.rglob("*") if p.is_file()}
    run_main(["check", root, "-p", mini_profile, "--out", tmp_path / "o"], capsys)
    after = {p.relative_to(root): sha256_file(p) for p in root.rglob("*") if p.is_file()}
    assert before == after


def test_terminal_caps_items_but_json_lists_all(make_delivery, mini_profile, tmp_path, capsys):
    rows = "\n".join(f"I{i},f{i}.tif,B1,5,1000,30" for i in range(30))
    _, stdout, _ = run_main(
        [
            "check",
            make_delivery(images="image_id,file,block,roll,flying_height,std_dn\n" + rows + "\n"),
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o",
            "--max-items",
            "3",
            "--checker",
            write_checker(tmp_path),
        ],
        capsys,
    )
    assert "I0, I1, I2 … (+26 more)" in stdout  # I3 is waived by the checker; natural order
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

    run_main(
        ["check", make_delivery(), "-p", mini_profile, "--out", tmp_path / "o", "--format", "json"],
        capsys,
    )
    mode = stat.S_IMODE((tmp_path / "o" / "qcr.json").stat().st_mode)
    mask = os.umask(0)
    os.umask(mask)
    assert mode == 0o666 & ~mask
    assert not list((tmp_path / "o").glob(".*.tmp"))  # no temp file left behind


# --------------------------------------------------------------------------- outputs (issue 17)


def test_out_inside_the_delivery_is_refused_before_the_check(make_delivery, mini_profile, capsys):
    root = make_delivery()
    before = sorted(p.relative_to(root).as_posix() for p in root.rglob("*"))
    code, _, err = run_main(["check", root, "-p", mini_profile, "--out", root / "qc"], capsys)
    assert code == 2 and "--out" in err and "never writes into a delivery" in err
    assert sorted(p.relative_to(root).as_posix() for p in root.rglob("*")) == before


@pytest.mark.parametrize("workers, ok", [("0", False), ("-3", False), ("1", True)])
def test_workers_must_be_positive(make_delivery, mini_profile, tmp_path, capsys, workers, ok):
    code, _, err = run_main(
        [
            "check",
            make_delivery(),
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o",
            "--workers",
            workers,
        ],
        capsys,
    )
    assert (code != 2) is ok, err
    if not ok:
        assert "--workers" in err


def test_workers_are_capped_to_the_cores():
    import os

    from orthospec.cli.cmd_check import _workers

    assert _workers(10_000) == (os.cpu_count() or 1) and _workers(None) is None and _workers(1) == 1


def test_outputs_are_all_or_nothing(tmp_path):
    from orthospec.api import write_outputs
    from orthospec.errors import OrthospecError

    out = tmp_path / "out"
    (out / "junit.xml").mkdir(parents=True)
    (out / "qcr.json").write_text("old")
    with pytest.raises(
        OrthospecError, match="junit.xml exists and is not a regular file; no output written"
    ):
        write_outputs(out, {"qcr.json": "new", "qcr.csv": "new", "junit.xml": "new"})
    assert sorted(p.name for p in out.iterdir()) == ["junit.xml", "qcr.json"]
    assert (out / "qcr.json").read_text() == "old"
    assert write_outputs(out / "fresh", {"a.txt": "1", "b.bin": b"\x00"}) == ["a.txt", "b.bin"]
    assert (out / "fresh" / "b.bin").read_bytes() == b"\x00" and len(
        list((out / "fresh").iterdir())
    ) == 2


WRITE_PAST_A_SIZE_LIMIT = """
import resource, signal, sys
from pathlib import Path
from orthospec.api import write_outputs
from orthospec.errors import OrthospecError
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past RLIMIT_FSIZE fails with EFBIG instead
resource.setrlimit(resource.RLIMIT_FSIZE, (1 << 20, 1 << 20))
out = Path(sys.argv[1])
(out / "qcr.json").write_text("old")
big = ("x" * 1000 + "\\n" for _ in range(5000))  # 5 MB, in pieces, past the 1 MB limit
try:
    write_outputs(out, {"qcr.json": "new", "qcr.csv": big, "junit.xml": "new"})
except OrthospecError as exc:
    print(exc)
"""


def test_a_write_that_fails_in_the_writer_thread_names_its_output_and_leaves_nothing(tmp_path):
    """A real write error (a file-size limit: EFBIG), raised in the thread that writes while the
    next piece is rendered: the message names the output being written, and the folder is as
    it was (the all-or-nothing promise of write_outputs)."""
    import subprocess
    import sys

    out = tmp_path / "out"
    out.mkdir()
    run = subprocess.run(
        [sys.executable, "-c", WRITE_PAST_A_SIZE_LIMIT, str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("cannot write qcr.csv to ") and "no output written" in run.stdout
    assert sorted(p.name for p in out.iterdir()) == ["qcr.json"]
    assert (out / "qcr.json").read_text() == "old"


@pytest.mark.parametrize(
    "text, expected",
    [
        ("D-2026-014", "D-2026-014"),
        ("../../../escaped", "escaped"),
        ("/tmp/x/delivery", "tmp_x_delivery"),
        ("..", "delivery"),
        ("", "delivery"),
        ("a b/c", "a_b_c"),
    ],
)
def test_default_output_folder_is_one_safe_segment(text, expected):
    from orthospec.api import default_output_dir, safe_segment

    assert safe_segment(text) == expected
    assert default_output_dir(text).parts == ("reports", expected)


def test_junit_directory_in_out_exits_2_and_writes_nothing(
    make_delivery, mini_profile, tmp_path, capsys
):
    out = tmp_path / "out"
    (out / "junit.xml").mkdir(parents=True)
    code, _, err = run_main(["check", make_delivery(), "-p", mini_profile, "--out", out], capsys)
    assert code == 2 and "junit.xml" in err and "internal error" not in err
    assert [p.name for p in out.iterdir()] == ["junit.xml"]


def test_a_bad_ledger_fails_before_the_check_writes_anything(
    make_delivery, mini_profile, tmp_path, capsys
):
    bad = tmp_path / "ledger.sqlite"
    bad.write_bytes(b"not a database " * 100)
    code, _, err = run_main(
        ["check", make_delivery(), "-p", mini_profile, "--out", tmp_path / "o", "--ledger", bad],
        capsys,
    )
    assert code == 2 and "ledger" in err
    assert not (tmp_path / "o").exists()


def test_a_ledger_inside_the_delivery_is_refused(make_delivery, mini_profile, tmp_path, capsys):
    root = make_delivery()
    code, _, err = run_main(
        [
            "check",
            root,
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o",
            "--ledger",
            root / "ledger.sqlite",
        ],
        capsys,
    )
    assert code == 2 and "--ledger" in err and not (root / "ledger.sqlite").exists()
    assert not (tmp_path / "o").exists()


def test_cwd_inside_the_delivery_without_out_is_refused(
    make_delivery, mini_profile, capsys, monkeypatch
):
    root = make_delivery()
    monkeypatch.chdir(root)
    code, _, err = run_main(["check", ".", "-p", mini_profile], capsys)
    assert code == 2 and "default output folder" in err and not (root / "reports").exists()


def test_ledger_head_is_recorded_in_the_qcr(make_delivery, mini_profile, tmp_path, capsys):
    led = tmp_path / "ledger.sqlite"
    args = ["check", make_delivery(), "-p", mini_profile, "--ledger", led, "--date", "2026-01-01"]
    run_main([*args, "--out", tmp_path / "o1"], capsys)
    first = json.loads((tmp_path / "o1" / "qcr.json").read_text())["ledger_head"]
    run_main([*args, "--out", tmp_path / "o2"], capsys)
    second = json.loads((tmp_path / "o2" / "qcr.json").read_text())["ledger_head"]
    assert first["seq"] + 1 == second["seq"] and first["hash"] != second["hash"]


def test_qcr_json_does_not_depend_on_the_working_folder(tmp_path, monkeypatch, capsys):
    """Issue 17: qcr.json embedded the delivery path as typed and absolute paths in messages.
    The same delivery checked from two working folders (relative and absolute path), with an
    unreadable image so that a raster error message is recorded, gives the same bytes."""
    import shutil
    from pathlib import Path

    src = Path(__file__).resolve().parents[1] / "examples" / "deliveries" / "aerial-pass"
    d = tmp_path / "x" / "lot"
    shutil.copytree(src, d)
    img = sorted((d / "images").glob("*.tif"))[0]
    img.write_bytes(img.read_bytes()[:2000])  # truncated: not a readable raster
    outs = []
    for cwd, target in ((tmp_path, "x/lot"), (img.parent, str(d))):
        monkeypatch.chdir(cwd)
        out = tmp_path / f"out{len(outs)}"
        code, _, _ = run_main(
            [
                "check",
                target,
                "-p",
                "jrc-v3",
                "--out",
                out,
                "--format",
                "json",
                "--date",
                "2026-11-21",
            ],
            capsys,
        )
        assert code in (0, 1, 3)
        outs.append((out / "qcr.json").read_bytes())
    assert outs[0] == outs[1]
    text = outs[0].decode("utf-8")
    doc = json.loads(text)
    assert img.stem in doc["rollup"]["rejected"]["image"]  # the unreadable image itself is rejected
    assert str(tmp_path) not in text
    assert f"images/{img.name}" in text  # the error names the file relative to the delivery


def test_without_a_checker_manual_rules_are_missing_and_the_contractors_waiver_is_a_request(
    make_delivery, mini_profile, tmp_path, capsys
):
    """docs/CHECKER.md: the delivery's manual_checks and waivers never decide a verdict."""
    images = "image_id,file,block,roll,flying_height,std_dn\nI1,a.tif,B1,0.5,1000,30\nI3,c.tif,B2,4,1100,20\n"
    root = make_delivery(images=images)
    code, _, _ = run_main(
        [
            "check",
            root,
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o",
            "--date",
            "2026-01-01",
            "--format",
            "json",
        ],
        capsys,
    )
    doc = json.loads((tmp_path / "o" / "qcr.json").read_text())
    got = {(r["rule"], r["item"]): r for r in all_records(doc)}
    assert code == 1 and doc["checker"] is None
    assert got[("R-VIS", "D1")]["verdict"] == "missing"
    assert got[("R-ROLL", "I3")]["verdict"] == "fail" and got[("R-ROLL", "I3")]["waiver_requested"]
    code, _, _ = run_main(
        [
            "check",
            root,
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o2",
            "--date",
            "2026-01-01",
            "--format",
            "json",
            "--checker",
            write_checker(tmp_path),
        ],
        capsys,
    )
    doc = json.loads((tmp_path / "o2" / "qcr.json").read_text())
    got = {(r["rule"], r["item"]): r for r in all_records(doc)}
    assert code == 0 and doc["checker"]["name"] == "Eva External"
    assert (
        got[("R-VIS", "D1")]["verdict"] == "pass" and got[("R-ROLL", "I3")]["verdict"] == "waived"
    )


def test_a_checker_file_inside_the_delivery_is_refused(
    make_delivery, mini_profile, tmp_path, capsys
):
    root = make_delivery()
    code, _, err = run_main(
        [
            "check",
            root,
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o",
            "--checker",
            write_checker(root),
        ],
        capsys,
    )
    assert code == 2 and "checker.yaml" in err and not (tmp_path / "o").exists()


def test_check_options_are_typed(make_delivery, mini_profile):
    from orthospec.api import CheckOptions, check
    from orthospec.errors import OrthospecError

    with pytest.raises(OrthospecError, match="fail_on"):
        CheckOptions(fail_on="fial")
    with pytest.raises(OrthospecError, match="workers"):
        CheckOptions(workers=0)
    with pytest.raises(OrthospecError, match="unknown check option.*wokers"):
        CheckOptions.of({"wokers": 2})
    opts = CheckOptions.of({"workers": 1, "fail_on": "warn"})
    assert opts == CheckOptions(workers=1, fail_on="warn")
    # fail_on=warn makes the recommended R-FH warning blocking, through the options object alone
    doc = check(
        make_delivery(), mini_profile, options=opts, date="2026-01-01", params=["tolerance_xy=0.5m"]
    ).document
    assert doc["fail_on"] == "warn"


def test_scheduler_without_dask_exits_2_before_checking(make_delivery, mini_profile, tmp_path):
    """A missing optional extra is a clear exit 2 up front, not an error record per image."""
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['distributed'] = None; sys.modules['dask'] = None; "
        "from orthospec.cli.main import main; main(sys.argv[1:])"
    )
    res = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "check",
            str(make_delivery()),
            "-p",
            str(mini_profile),
            "--out",
            str(tmp_path / "o"),
            "--scheduler",
            "tcp://127.0.0.1:1",
        ],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 2, res.stderr
    assert "orthospec[dask]" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "o").exists()


def test_an_unknown_format_is_refused(make_delivery, mini_profile, tmp_path, capsys):
    code, _, err = run_main(
        [
            "check",
            make_delivery(),
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o",
            "--format",
            "json,yaml-ish",
        ],
        capsys,
    )
    assert code == 2 and "yaml-ish" in err and not (tmp_path / "o").exists()


def test_unsigned_manual_checks_are_named_on_the_terminal_and_page_1(
    make_delivery, mini_profile, tmp_path, capsys
):
    """mini.yaml has one manual rule (R-VIS, delivery scope): without the checker's file it has no verdict."""
    root = make_delivery()
    note = "1 manual check has no verdict from the checker: give the checker's file with --checker FILE"
    _, stdout, _ = run_main(
        ["check", root, "-p", mini_profile, "--out", tmp_path / "o", "--format", "terminal,html"],
        capsys,
    )
    assert note in " ".join(stdout.split())
    html = unescape((tmp_path / "o" / "report.html").read_text(encoding="utf-8"))
    assert note in html and html.index(note) < html.index("Findings, most consequential first")
    _, stdout, _ = run_main(
        [
            "check",
            root,
            "-p",
            mini_profile,
            "--out",
            tmp_path / "o2",
            "--format",
            "terminal,html",
            "--checker",
            write_checker(tmp_path),
        ],
        capsys,
    )
    assert "no verdict from the checker" not in stdout
    assert "no verdict from the checker" not in (tmp_path / "o2" / "report.html").read_text(
        encoding="utf-8"
    )


def test_a_stream_failing_while_written_leaves_nothing(tmp_path):
    from orthospec.api import write_outputs
    from orthospec.errors import OrthospecError

    def broken():
        yield "{\n"
        raise OrthospecError("plugin format failed half way")

    out = tmp_path / "new" / "out"
    with pytest.raises(OrthospecError, match="half way"):
        write_outputs(out, {"qcr.csv": "a,b\n", "qcr.json": broken()})
    assert not (tmp_path / "new").exists()
    (tmp_path / "kept").mkdir()
    (tmp_path / "kept" / "qcr.json").write_text("old")
    with pytest.raises(OrthospecError):
        write_outputs(tmp_path / "kept", {"qcr.json": broken()})
    assert [p.name for p in (tmp_path / "kept").iterdir()] == ["qcr.json"]
    assert (tmp_path / "kept" / "qcr.json").read_text() == "old"
