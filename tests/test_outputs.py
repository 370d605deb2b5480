"""orthospec/outputs.py: the one atomic writer (issue 28 item 1)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from orthospec import outputs, qcr
from orthospec.raster import checkpoints


def test_one_writer_reexported() -> None:
    assert qcr.atomic_write is outputs.atomic_write
    assert not hasattr(checkpoints, "_atomic")


def test_atomic_write_replaces_with_ordinary_mode(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "qcr.json"
    outputs.atomic_write(target, "old")
    outputs.atomic_write(target, b"new \xc3\xa9")
    assert target.read_bytes() == b"new \xc3\xa9"
    assert stat.S_IMODE(target.stat().st_mode) == outputs.file_mode()
    assert sorted(p.name for p in target.parent.iterdir()) == ["qcr.json"]


def test_atomic_path_error_leaves_target_and_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "hand.csv"
    target.write_text("kept")
    with pytest.raises(KeyboardInterrupt), outputs.atomic_path(target, ".csv") as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".csv"
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert target.read_text() == "kept"
    assert os.listdir(tmp_path) == ["hand.csv"]


def test_atomic_write_failure_keeps_target(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "qcr.csv"
    target.write_text("kept")

    def boom(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(outputs.os, "fsync", boom)
    with pytest.raises(OSError, match="No space"):
        outputs.atomic_write(target, "new")
    assert target.read_text() == "kept"
    assert os.listdir(tmp_path) == ["qcr.csv"]
