"""The checker's file (`check --checker FILE`, docs/CHECKER.md): strict, located, outside the delivery.

Real YAML files on disk read by the real loader; the messages must name file:line:col (exit 2
through the CLI's OrthospecError mapping), and the published schema must be the model's.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest
from tests.checking import MINI_CHECKER, write_checker

from orthospec.delivery.checker import checker_schema, load_checker
from orthospec.errors import OrthospecError

ROOT = Path(__file__).resolve().parents[1]


def test_a_valid_checker_file_loads_with_its_lines_and_hash(tmp_path: Path) -> None:
    path = write_checker(tmp_path)
    chk = load_checker(path, delivery_root=tmp_path / "d")
    assert chk.who() == "Eva External (external QC, Paying Agency)"
    assert [m.check for m in chk.model.manual_checks] == ["R-VIS"]
    assert (
        chk.lines[("manual_checks", 0)] == 6 and chk.lines[("waivers", 0)] == 8
    )  # MINI_CHECKER's lines
    ev = chk.evidence("waivers", 0)
    assert ev.file == "checker:checker.yaml" and ev.path == "waivers[0] (line 8)"
    assert chk.model.delivery.id == "D1" and chk.at("delivery", "id") == f"{path}:3"
    assert chk.sha256 == hashlib.sha256(MINI_CHECKER.encode()).hexdigest()


@pytest.mark.parametrize(
    "text, where, what",
    [
        (MINI_CHECKER.replace("verdict: pass", "verdict: ok"), ":6:", "verdict"),
        (MINI_CHECKER.replace("approver: Chief", "approver: ''"), ":8:", "approver"),
        (
            MINI_CHECKER.replace("orthospec_checker: 1", "orthospec_checker: 2"),
            ":1:",
            "orthospec_checker",
        ),
        (MINI_CHECKER.replace("checker: {name", "checkr: {name"), ":2:", "checkr"),
        (MINI_CHECKER.replace("date: 2026-01-02", "date: 2026-02-30"), ":6:", "invalid value|date"),
        (
            MINI_CHECKER.replace("delivery: {id: D1}\n", ""),
            "",
            "delivery",
        ),  # required: what was signed
        (
            MINI_CHECKER.replace("{id: D1}", "{id: D1, manifest_sha256: abc}"),
            ":3:",
            "manifest_sha256",
        ),
        (
            MINI_CHECKER.replace("{id: D1}", "{id: D1, files: {tables/manual.csv: 12}}"),
            ":3:",
            "files",
        ),
        ("[1, 2]\n", ":1:1:", "mapping"),
        ("a: [\n", ":", "invalid YAML"),
    ],
)
def test_a_bad_checker_file_names_file_line_and_column(
    tmp_path: Path, text: str, where: str, what: str
) -> None:
    path = write_checker(tmp_path, text)
    with pytest.raises(OrthospecError, match=what) as exc:
        load_checker(path, delivery_root=tmp_path / "d")
    assert str(path) in str(exc.value) and where in str(exc.value)


def test_the_same_check_and_item_twice_is_refused(tmp_path: Path) -> None:
    text = MINI_CHECKER.replace(
        "waivers:\n", "  - {check: R-VIS, item: '*', date: 2026-01-03, verdict: fail}\nwaivers:\n"
    )
    with pytest.raises(
        OrthospecError, match=r"checker.yaml:7: manual_checks: R-VIS item '\*' is given twice"
    ):
        load_checker(write_checker(tmp_path, text))


def test_a_missing_checker_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(OrthospecError, match="file not found"):
        load_checker(tmp_path / "nope.yaml")


def test_the_published_schema_is_the_models() -> None:
    committed = json.loads(
        (ROOT / "specs" / "schema" / "checker.schema.json").read_text(encoding="utf-8")
    )
    assert committed == json.loads(json.dumps(checker_schema()))
    assert committed["properties"]["manual_checks"]["items"]["$ref"].endswith("CheckerManualCheck")


def _cli_check(
    root: Path, profile: Path, checker: Path, out: Path, *extra: str
) -> subprocess.CompletedProcess[str]:
    """`orthospec check ROOT --profile P --checker C --out O ...` as a user runs it (a new process)."""
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "orthospec.cli.main",
            "check",
            str(root),
            "--profile",
            str(profile),
            "--checker",
            str(checker),
            "--out",
            str(out),
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_check_with_a_checker_file_inside_the_delivery_exits_2(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    """`orthospec check D --checker D/x.yaml`: exit 2, a one-line message, no traceback, nothing written."""
    root = make_delivery()
    inside = write_checker(root, name="my-own-verdicts.yaml")
    out = tmp_path / "out"
    proc = _cli_check(root, mini_profile, inside, out)
    assert proc.returncode == 2, proc.stderr
    assert "inside the delivery" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()
    ok = _cli_check(
        root, mini_profile, write_checker(tmp_path), out, "--date", "2026-01-01", "--format", "json"
    )
    assert ok.returncode in (0, 1), ok.stderr
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    assert doc["checker"]["name"] == "Eva External" and doc["checker"]["file"] == "checker.yaml"


# --- the checker file is bound to what it signed (red team R5) -----------------------


def _bind(root: Path, text: str, tmp_path: Path):
    from orthospec.delivery.reader import open_delivery

    return load_checker(write_checker(tmp_path, text), delivery=open_delivery(root))


def test_a_checker_file_for_another_delivery_is_refused(make_delivery, tmp_path: Path) -> None:
    root = make_delivery()  # tests/conftest.py MANIFEST: id D1
    assert _bind(root, MINI_CHECKER, tmp_path).model.delivery.id == "D1"
    with pytest.raises(OrthospecError) as exc:
        _bind(root, MINI_CHECKER.replace("{id: D1}", "{id: D-2026-014}"), tmp_path)
    msg = str(exc.value)
    assert f"{tmp_path / 'checker.yaml'}:3 is for delivery D-2026-014; this delivery is D1" in msg
    assert "the checker's verdicts were given on other content" in msg


def test_a_checker_file_pinning_another_manifest_is_refused(make_delivery, tmp_path: Path) -> None:
    root = make_delivery()
    real = hashlib.sha256((root / "delivery.yaml").read_bytes()).hexdigest()
    ok = MINI_CHECKER.replace("{id: D1}", f"{{id: D1, manifest_sha256: {real.upper()}}}")
    assert (
        _bind(root, ok, tmp_path).model.delivery.manifest_sha256 == real.upper()
    )  # case is no difference
    other = "0" * 64
    with pytest.raises(
        OrthospecError,
        match=f"checker.yaml:3 pins delivery.yaml sha256 {other}, the "
        f"delivery's is {real}: the checker's verdicts were given on other",
    ):
        _bind(
            root,
            MINI_CHECKER.replace("{id: D1}", f"{{id: D1, manifest_sha256: '{other}'}}"),
            tmp_path,
        )


def test_a_pinned_file_changed_after_signing_is_refused(make_delivery, tmp_path: Path) -> None:
    """R5: the checker signed the check points' independent source; the table is then edited."""
    root = make_delivery()
    table = root / "tables" / "manual.csv"
    signed = hashlib.sha256(table.read_bytes()).hexdigest()
    text = MINI_CHECKER.replace(
        "delivery: {id: D1}\n", f"delivery:\n  id: D1\n  files:\n    tables/manual.csv: {signed}\n"
    )
    assert _bind(root, text, tmp_path).model.delivery.files == {"tables/manual.csv": signed}
    table.write_text(
        table.read_text(encoding="utf-8") + "R-X,*,Joe,2026-01-01,pass\n", encoding="utf-8"
    )
    now = hashlib.sha256(table.read_bytes()).hexdigest()
    with pytest.raises(OrthospecError) as exc:
        _bind(root, text, tmp_path)
    assert (
        f"checker.yaml:6 pins tables/manual.csv sha256 {signed}, the delivery's is {now}: the checker's "
        "verdicts were given on other content"
    ) in str(exc.value)
    table.unlink()
    with pytest.raises(
        OrthospecError, match="checker.yaml:6 pins tables/manual.csv, which the delivery does not"
    ):
        _bind(root, text, tmp_path)
    with pytest.raises(OrthospecError, match=r"checker.yaml:6: .*\.\./outside"):
        _bind(root, text.replace("tables/manual.csv", "../outside"), tmp_path)


def test_check_refuses_a_checker_file_for_other_content_with_exit_2(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    """Through `orthospec check`: exit 2, one message naming the checker file, nothing written."""
    root = make_delivery()
    other = write_checker(tmp_path, MINI_CHECKER.replace("{id: D1}", "{id: D2}"), "other.yaml")
    out = tmp_path / "out"
    proc = _cli_check(root, mini_profile, other, out)
    assert proc.returncode == 2, proc.stderr
    assert (
        "other.yaml:3 is for delivery D2; this delivery is D1" in proc.stderr
        and "Traceback" not in proc.stderr
    )
    assert not out.exists()


def test_the_example_checker_files_pin_the_check_points(tmp_path: Path) -> None:
    """examples/generate.py signs each example's tables/checkpoints.csv, the contractor's internal-QC
    table the checker read (JRC §12.5), with the role the delivery gives it (issue 29 item 4)."""
    for name in ("aerial-pass", "aerial-fail", "satellite-pass", "satellite-fail"):
        chk = load_checker(ROOT / "examples" / "checker" / name)
        table = ROOT / "examples" / "deliveries" / name / "tables" / "checkpoints.csv"
        ((rel, pin),) = chk.model.delivery.files.items()
        assert rel == "tables/checkpoints.csv" and not isinstance(pin, str)
        assert (pin.sha256, pin.role) == (
            hashlib.sha256(table.read_bytes()).hexdigest(),
            "tables.checkpoints",
        )
        assert (
            chk.model.delivery.manifest_sha256 is None
        )  # the README's redelivery edits delivery.yaml


# --- block outlines and area of interest in force (red team R13/R17) ------------------------------

#: two touching 1 km squares (x 0..1000 and 1000..2000) and an area of interest over both
OUTLINES = """\
blocks:
  - id: B1
    polygon: [[0, 0], [1000, 0], [1000, 1000], [0, 1000]]
  - id: B2
    polygon: [[1000, 0], [2000, 0], [2000, 1000], [1000, 1000]]
area_of_interest: [[0, 0], [2000, 0], [2000, 1000], [0, 1000]]
"""


def test_the_checker_states_block_outlines_and_an_area_of_interest(tmp_path: Path) -> None:
    chk = load_checker(
        write_checker(tmp_path, MINI_CHECKER + OUTLINES), delivery_root=tmp_path / "d"
    )
    assert [b.id for b in chk.model.blocks] == ["B1", "B2"]
    assert chk.model.blocks[1].polygon[0] == (1000.0, 0.0)
    assert len(chk.model.area_of_interest or []) == 4
    assert chk.evidence("blocks", 1).path == "blocks[1] (line 12)"  # MINI_CHECKER has 8 lines


@pytest.mark.parametrize(
    "change, where, what",
    [
        # a bow tie: B2's two top vertices swapped, its edges cross
        (
            (
                "[[1000, 0], [2000, 0], [2000, 1000], [1000, 1000]]",
                "[[1000, 0], [2000, 0], [1000, 1000], [2000, 1000]]",
            ),
            ":13",
            r"blocks\[1\] \(B2\): the polygon is not a valid block outline \(Self-intersection",
        ),
        # B2 starts 10 m inside B1: 10 m x 1000 m shared
        (
            (
                "[[1000, 0], [2000, 0], [2000, 1000], [1000, 1000]]",
                "[[990, 0], [2000, 0], [2000, 1000], [990, 1000]]",
            ),
            ":13",
            r"blocks\[1\] \(B2\): the polygon overlaps the outline of block B1 \(blocks\[0\]\) over an area of 10000",
        ),
        (("id: B2", "id: B1"), ":12", r"blocks\[1\]: block B1 is given twice"),
        (
            ("[2000, 0], [2000, 1000], [1000", "[2000, 0, 5], [2000, 1000], [1000"),
            ":13",
            "at most 2 items",
        ),
        (
            ("[2000, 0], [2000, 1000], [1000", "[2000, .inf], [2000, 1000], [1000"),
            ":13",
            "finite number",
        ),
        (
            ("[2000, 0], [2000, 1000], [1000", "[2000, east], [2000, 1000], [1000"),
            ":13",
            "valid number",
        ),
        (
            ("[[1000, 0], [2000, 0], [2000, 1000], [1000, 1000]]", "[[1000, 0], [2000, 0]]"),
            ":13",
            "at least 3 items",
        ),
        (
            (
                "area_of_interest: [[0, 0], [2000, 0], [2000, 1000], [0, 1000]]",
                "area_of_interest: [[0, 0], [2000, 1000], [2000, 0], [0, 1000]]",
            ),
            ":14",
            r"area_of_interest is not a valid outline \(Self-intersection",
        ),
        (
            ("id: B2\n", "id: B2\n    method: aerotriangulation\n"),
            ":13",
            "method",
        ),  # the outline only, closed
    ],
)
def test_a_bad_outline_in_the_checker_file_is_refused_naming_file_and_line(
    tmp_path: Path, change: tuple[str, str], where: str, what: str
) -> None:
    assert change[0] in OUTLINES
    path = write_checker(tmp_path, MINI_CHECKER + OUTLINES.replace(*change))
    with pytest.raises(OrthospecError, match=what) as exc:
        load_checker(path, delivery_root=tmp_path / "d")
    assert f"{path}{where}" in str(exc.value)
