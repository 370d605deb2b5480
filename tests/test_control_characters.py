"""Issue 28 item 7: control characters (ESC, VT, U+202E) in delivery or profile text are refused
where the text is read (exit 2 naming file and line), so none reaches qcr.csv, report.html or the
terminal. Tab, line feed and carriage return stay legal."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from orthospec.cli.main import main
from orthospec.controls import find_in_text, find_in_utf8
from orthospec.delivery.reader import open_delivery
from orthospec.errors import DeliveryError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deliveries" / "aerial-pass"


def _copy(tmp_path: Path) -> Path:
    d = tmp_path / "delivery"
    shutil.copytree(EXAMPLE, d)
    return d


def _replace(path: Path, old: str, new: str) -> int:
    """Replace the first ``old`` in the file; the 1-based line where it was."""
    text = path.read_text(encoding="utf-8")
    at = text.index(old)
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return text.count("\n", 0, at) + 1


@pytest.mark.parametrize("ch", ["\x1b", "\x0b", "\u202e", "\x85", "\u2066", "\x7f"])
def test_every_refused_character_is_found_in_text_and_in_utf8(ch: str) -> None:
    text = f"F01{ch}0101"
    assert find_in_text(text) == 3
    assert find_in_utf8(f"a,b\n{text},x\n".encode()) == (2, ch)


@pytest.mark.parametrize("ch", ["\t", "\n", "\r", "é", "\u200e", "ß", "\u2028"])
def test_ordinary_text_is_not_refused(ch: str) -> None:
    assert find_in_text(f"x{ch}y") is None
    assert find_in_utf8(f"x{ch}y".encode()) is None


@pytest.mark.parametrize("ch", ["\x1b[2J", "\x0b", "\u202e"])
def test_a_control_character_in_a_table_cell_refuses_the_delivery_naming_file_and_line(
        tmp_path: Path, ch: str) -> None:
    d = _copy(tmp_path)
    line = _replace(d / "tables" / "images.csv", "F01_0103", f"F01{ch}_0103")
    with pytest.raises(DeliveryError) as err:
        open_delivery(d).load_all_tables()
    msg = str(err.value)
    assert f"tables/images.csv:{line}: " in msg, msg
    assert "control character (U+" in msg


def test_the_command_exits_2_without_a_traceback_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _copy(tmp_path)
    _replace(d / "tables" / "images.csv", "F01_0103", "F01\x1b]0;owned\x07_0103")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        main(["check", str(d), "--profile", "jrc-v3", "--out", str(out), "--date", "2026-11-21"])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert "Traceback" not in err and "\x1b" not in err and "U+001B" in err, err
    assert not out.exists() or not any(out.iterdir())


def test_a_bidi_override_in_a_yaml_value_names_file_line_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _copy(tmp_path)
    manifest = d / "delivery.yaml"
    line = _replace(manifest, "id: D-2026-014", 'id: "D-2026\\u202e-014"')
    with pytest.raises(SystemExit) as exc:
        main(
            [
                "check",
                str(d),
                "--profile",
                "jrc-v3",
                "--out",
                str(tmp_path / "out"),
                "--date",
                "2026-11-21",
            ]
        )
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert f"delivery.yaml:{line}:" in err and "U+202E" in err, err
    assert "\u202e" not in err


def test_an_escape_in_a_profile_is_refused_at_spec_validate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    profile = tmp_path / "tender.yaml"
    profile.write_text(
        'id: tender-esc\nversion: "1"\nextends: jrc-v3\ntitle: "Lot 1 \\e[31m"\n', encoding="utf-8"
    )
    with pytest.raises(SystemExit) as exc:
        main(["spec", "validate", str(profile)])
    err = capsys.readouterr().err + capsys.readouterr().out
    assert exc.value.code == 2
    assert "tender.yaml:4:" in err and "U+001B" in err, err
