"""`orthospec report QCR_JSON --format gpkg` (issue 30): the findings GeoPackage re-rendered from
qcr.json alone holds the same layers as the one `check --format gpkg` wrote, but for the seamlines
(read from the delivery, not carried by qcr.json)."""

from __future__ import annotations

import math
from pathlib import Path

import pyogrio
from click.testing import CliRunner
from tests.conftest import ROOT

from orthospec.cli.main import cli


def _layer(path: Path, name: str) -> tuple[list[object], list[list[object]]]:
    meta, _fids, geom, fields = pyogrio.raw.read(path, layer=name)
    cols = [
        [None if isinstance(v, float) and math.isnan(v) else v for v in f.tolist()] for f in fields
    ]
    return ([] if geom is None else list(geom)), [list(meta["fields"]), *cols]


def test_report_renders_the_findings_gpkg_from_qcr_json(tmp_path: Path) -> None:
    out = tmp_path / "check"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(ROOT / "examples/deliveries/aerial-fail"),
            "--profile",
            "jrc-v3",
            "--checker",
            str(ROOT / "examples/checker/aerial-fail"),
            "--format",
            "json,gpkg",
            "--out",
            str(out),
            "--date",
            "2026-11-21",
        ],
    )
    assert res.exit_code == 1, res.output
    again = tmp_path / "report"
    res = CliRunner().invoke(
        cli(), ["report", str(out / "qcr.json"), "--format", "gpkg", "--out", str(again)]
    )
    assert res.exit_code == 0, res.output
    assert "findings.gpkg" in res.output and not (again / "report.html").exists()
    names = [n for n, _ in pyogrio.list_layers(out / "findings.gpkg")]
    assert names == [n for n, _ in pyogrio.list_layers(again / "findings.gpkg")]
    assert "images" in names and "checkpoints" in names
    for name in names:
        if name == "seamlines":
            continue
        assert _layer(out / "findings.gpkg", name) == _layer(again / "findings.gpkg", name), name
    images, _ = _layer(again / "findings.gpkg", "images")
    assert any(g is not None for g in images)  # footprints from qcr.json's details
