"""Hostile ids in a delivery reach qcr.csv, junit.xml and the terminal harmlessly (issue 17 "Outputs").

OWASP CSV injection guidance: a cell starting with = + - @ tab or CR is prefixed with a single quote.
"""

from __future__ import annotations

import csv
import io
import xml.dom.minidom
from pathlib import Path

from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.qcr import csv_safe

# Control characters (BEL, ESC ...) in an id are refused where the table is read (exit 2, issue 28:
# tests/test_control_characters.py); the formula-like ids below are legal text and must reach the outputs harmless.
HOSTILE = ['=HYPERLINK("http://evil.example/x","click")', "+cmd|' /C calc'!A0", "@SUM(1+1)", "-2+3"]


def test_csv_safe_prefixes_formulas_only() -> None:
    assert csv_safe("=1+1") == "'=1+1"
    assert csv_safe("\tx") == "'\tx" and csv_safe("\rx") == "'\nx"  # a CR also becomes a quoted LF
    assert csv_safe("-0.25") == "'-0.25"  # text that a spreadsheet would evaluate
    assert csv_safe(-0.25) == -0.25  # a number stays a number
    assert csv_safe("B02") == "B02"


def test_hostile_ids_are_neutralised_in_csv_junit_and_terminal(
    make_delivery, mini_profile, tmp_path: Path
) -> None:
    rows = "\n".join(
        f'"{i.replace(chr(34), chr(34) * 2)}",f{n}.tif,B1,{9 if "SUM" in i else 0.5},1000,30'
        for n, i in enumerate(HOSTILE)
    )  # the @SUM id fails roll: the terminal shows it
    root = make_delivery(
        "h", images="image_id,file,block,roll,flying_height,std_dn\n" + rows + "\n"
    )
    out = tmp_path / "out"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(root),
            "-p",
            str(mini_profile),
            "--out",
            str(out),
            "--date",
            "2026-01-01",
            "--format",
            "terminal,json,csv,junit",
            "--param",
            "tolerance_xy=0.5m",
        ],
    )
    assert res.exit_code in (0, 1), res.output + repr(res.exception)
    cells = [
        c
        for row in csv.reader(io.StringIO((out / "qcr.csv").read_text(encoding="utf-8")))
        for c in row
    ]
    items = [c for c in cells if "HYPERLINK" in c or "SUM(" in c or "cmd|" in c]
    assert items, "the hostile ids reached the CSV"
    for c in cells:
        assert not c.startswith(("=", "+", "-", "@", "\t", "\r")), c
    junit = (out / "junit.xml").read_bytes()
    xml.dom.minidom.parseString(junit)  # well-formed with the formula-like ids
    assert "@SUM(1+1)" in res.output.replace("\n", "")  # shown as text


def test_a_carriage_return_in_a_csv_cell_cannot_split_the_row() -> None:
    """csv.writer with lineterminator "\\n" leaves a lone CR unquoted; a spreadsheet (and Python's
    csv.reader) would then see the row broken there. csv_safe turns it into a LF, which is quoted:
    the row reads back whole, as the 3 cells written."""
    import csv
    import io

    from orthospec.qcr import _csv_cells, csv_safe

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(
        [csv_safe("B01\rFAKE,pass"), csv_safe("\r=1+1"), "ok"]
    )
    assert list(csv.reader(io.StringIO(buf.getvalue()))) == [["B01\nFAKE,pass", "'\n=1+1", "ok"]]
    # the per-block writer's column path gives the same cells as csv.writer
    assert _csv_cells(["B01\rFAKE,pass", "plain"]) == ['"B01\nFAKE,pass"', "plain"]
