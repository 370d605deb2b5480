"""Closed vocabularies of the columns rules branch on (issue 25 item 4, observation "Method as free text").

A `when` such as ``scenes.correction_method == 'rpc'`` used to match the cell exactly: ``RPC`` or
``rpc_refined`` on a 1-GCP scene turned every Table 9 GCP rule not applicable and the delivery was
ACCEPTED. Now the reader normalises a cell to its column's vocabulary (specs/delivery-tables.yaml
``values:``) or refuses the delivery naming file, row and column; an empty cell leaves the rule
``missing``; a profile comparing the column with a word outside the vocabulary is undecidable.
Edits are made on copies of the shipped examples (the checker pins only checkpoints.csv).
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

import pytest
import yaml
from tests.checking import (
    CHECKERS,
    DATE,
    EXAMPLES,
    ROOT,
    check_with,
    read_table,
    records,
    write_table,
)
from tests.checking import copy_example as _copy

from orthospec.delivery import vocabulary
from orthospec.delivery.reader import open_delivery
from orthospec.errors import DeliveryError

SPECS = ROOT / "specs"


def _set(d: Path, table: str, item: str, **cells: str) -> None:
    header, rows = read_table(d, table)
    id_col = header[0]
    hit = [r for r in rows if r[id_col] == item]
    assert hit, item
    for r in hit:
        r.update(cells)
    write_table(d, table, header, rows)


def _verdicts(doc: dict[str, Any], rule: str) -> dict[str, str]:
    return {r["item"]: r["verdict"] for r in records(doc) if r["rule"] == rule}


# --- the vocabulary itself ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("table", "column", "cell", "expected"),
    [
        ("scenes", "correction_method", "RPC", "rpc"),
        ("scenes", "correction_method", " rpc-block ", "rpc_block"),
        ("scenes", "correction_method", "RPC Block", "rpc_block"),
        ("scenes", "correction_method", "Polynomial", "poly"),
        ("scenes", "correction_method", "physical model", "ortho"),
        ("scenes", "correction_method", "rpc_refined", None),
        ("scenes", "correction_method", "rpc2", None),
        ("scenes", "resampling_method", "Cubic Convolution", "cubic"),
        ("scenes", "resampling_method", "nearest-neighbour", "nearest"),
        ("scenes", "resampling_method", "lanczos", None),
        ("images", "resampling", "BILINEAR", "bilinear"),
        ("cameras", "calibration_type", "In Situ", "in-situ"),
        ("cameras", "calibration_type", "insitu", "in-situ"),
        ("aerotriangulation", "configuration", "DGPS/INS", "dgps_ins"),
        ("aerotriangulation", "tie_point_mode", "Auto", "automatic"),
        ("scenes", "resolution_class", "vhr", "VHR"),
        ("gcps", "source_type", "Topographic map", "map"),
        ("gcps", "source_type", "GNSS RTK", "survey"),
    ],
)
def test_cells_are_read_in_the_columns_vocabulary(
    table: str, column: str, cell: str, expected: str | None
) -> None:
    voc = vocabulary.of(table, column)
    assert voc is not None
    assert voc.normalise(cell) == expected


def _profile_rules(doc: Any) -> list[dict[str, Any]]:
    """A profile's rules; other YAML in specs/ (inspection.yaml maps rules to grid classes) has none."""
    rules = doc.get("rules") if isinstance(doc, dict) else None
    return rules if isinstance(rules, list) else []


def test_every_literal_a_shipped_rule_compares_a_column_with_is_in_its_vocabulary() -> None:
    """The other side of the vocabulary: each word a shipped `when` or `in` requirement compares a
    vocabulary column with is one of its values (else the rule could never match a normalised cell)."""
    seen = 0
    for path in sorted(SPECS.glob("*.yaml")):
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        for r in _profile_rules(doc):
            req = r.get("requirement") or {}
            values = req.get("values") or [] if req.get("op") == "in" else []
            problems = vocabulary.literal_problems(
                r.get("when") or "", extra=[(r["measure"], v) for v in values]
            )
            assert not problems, (path.name, r["id"], problems)
            seen += sum(
                vocabulary.of_measure(n) is not None
                for n, _ in vocabulary.compared_literals(r.get("when") or "")
            )
    assert seen >= 15  # the Table 4/5/9 and §7.1 branches are among them


def test_every_column_a_shipped_when_compares_with_a_word_is_closed() -> None:
    """Issue 25 item 4: every table column a rule branches on has a closed vocabulary."""
    tables = yaml.safe_load((SPECS / "delivery-tables.yaml").read_text(encoding="utf-8"))["tables"]
    open_columns = set()
    for path in sorted(SPECS.glob("*.yaml")):
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        for r in _profile_rules(doc):
            for name, _ in vocabulary.compared_literals(r.get("when") or ""):
                t, _, col = name.partition(".")
                if t in tables and col in tables[t]["columns"] and vocabulary.of(t, col) is None:
                    open_columns.add(name)
            req = r.get("requirement") or {}
            t, _, col = r["measure"].partition(".")
            if (
                req.get("op") == "in"
                and t in tables
                and col in tables[t]["columns"]
                and vocabulary.of(t, col) is None
            ):
                open_columns.add(r["measure"])
    assert not open_columns


def test_literal_problems_name_the_word_and_the_values() -> None:
    got = vocabulary.literal_problems(
        "manifest.sensor.type == 'satellite' and scenes.correction_method == 'RPC'"
    )
    assert got == [
        "scenes.correction_method is compared with 'RPC', which is not one of its values "
        "(poly, ortho, rpc, rpc_block, rpc_from_gcp) (write 'rpc')"
    ]
    assert vocabulary.literal_problems("'rpc_block' == scenes.correction_method") == []
    assert ast.parse("1", mode="eval")  # the helper never evaluates anything


# --- the reader ------------------------------------------------------------------------------------


def test_a_spelling_of_a_known_method_is_normalised_when_the_table_is_read(tmp_path: Path) -> None:
    d = _copy("satellite-pass", tmp_path)
    _set(d, "scenes", "S02_SC1", correction_method="RPC")
    _set(
        d, "scenes", "S01_SC2", correction_method="RPC-Block", resampling_method="Cubic convolution"
    )
    t = open_delivery(d).table("scenes")
    got = dict(zip(t.df["image_id"], t.df["correction_method"], strict=True))
    assert got["S02_SC1"] == "rpc" and got["S01_SC2"] == "rpc_block"
    assert set(t.df["resampling_method"]) == {"cubic"}


def test_an_unknown_method_refuses_the_delivery_naming_file_row_and_column(tmp_path: Path) -> None:
    d = _copy("satellite-pass", tmp_path)
    _set(d, "scenes", "S02_SC1", correction_method="rpc_refined")
    _, rows = read_table(d, "scenes")
    row = 1 + [r["image_id"] for r in rows].index("S02_SC1")
    with pytest.raises(DeliveryError) as err:
        open_delivery(d).load_all_tables()
    msg = str(err.value)
    assert f"tables/scenes.csv: row {row}: column 'correction_method'" in msg, msg
    assert (
        "'rpc_refined' is not an allowed value; allowed: poly, ortho, rpc, rpc_block, rpc_from_gcp"
        in msg
    )


def test_an_unknown_method_exits_2_from_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from orthospec.cli.main import main

    d = _copy("satellite-pass", tmp_path)
    _set(d, "scenes", "S02_SC1", correction_method="rpc_refined")
    with pytest.raises(SystemExit) as exc:
        main(
            [
                "check",
                str(d),
                "--profile",
                "jrc-v3",
                "--checker",
                str(CHECKERS / "satellite-pass"),
                "--out",
                str(tmp_path / "out"),
            ]
        )
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert (
        "correction_method" in err and "allowed: poly, ortho, rpc, rpc_block, rpc_from_gcp" in err
    )
    assert "Traceback" not in err and not (tmp_path / "out").exists()


def test_a_huge_unknown_cell_is_shown_shortened(tmp_path: Path) -> None:
    d = _copy("satellite-pass", tmp_path)
    _set(d, "scenes", "S02_SC1", resampling_method="x" * 5000)
    with pytest.raises(DeliveryError) as err:
        open_delivery(d).load_all_tables()
    assert len(str(err.value)) < 400


# --- the rules ------------------------------------------------------------------------------------


def test_an_empty_method_leaves_the_gcp_minimum_missing_never_not_applicable(
    tmp_path: Path,
) -> None:
    """An unknown method must leave the minimum undecided (issue 25), whatever the GCP count."""
    d = _copy("satellite-pass", tmp_path)
    _set(d, "scenes", "S02_SC1", correction_method="")
    doc = check_with(d, "jrc-v3", checker=CHECKERS / "satellite-pass", date=DATE).document
    for rule in ("JRC-T9-GCP-VHR-RPC", "JRC-T9-GCP-VHR-PHYSICAL"):
        assert _verdicts(doc, rule)["S02_SC1"] == "missing", (rule, _verdicts(doc, rule))
    # the HR/MR/LR polynomial minimum is decided whatever the method: the scene is VHR
    assert _verdicts(doc, "JRC-T9-GCP-POLY")["S02_SC1"] == "not_applicable"
    assert doc["verdict"] != "accepted"


def test_a_profile_comparing_with_a_word_outside_the_vocabulary_is_missing(tmp_path: Path) -> None:
    """A tender rule written ``correction_method == 'RPC'`` could never match a normalised cell: it is
    `missing` with the reason, not silently not applicable everywhere."""
    tender = tmp_path / "tender.yaml"
    tender.write_text(
        yaml.safe_dump(
            {
                "orthospec_profile": 1,
                "id": "tender-vocab",
                "version": "1.0.0",
                "title": "t",
                "source": {"title": "ITT", "identifier": "ITT-V"},
                "extends": {"id": "jrc-v3", "version": "3.0.0"},
                "rules": [
                    {
                        "id": "ITT-1-RPC-GCPS",
                        "title": "RPC scenes on at least 3 GCPs",
                        "clause": {"document": "ITT-V", "section": "1"},
                        "quote": "RPC scenes use 3 GCPs.",
                        "scope": "image",
                        "when": "scenes.correction_method == 'RPC'",
                        "measure": "scenes.gcp_count",
                        "requirement": {"op": ">=", "value": 3, "unit": "1"},
                        "level": "mandatory",
                        "consequence": "reject_item",
                    }
                ],
            }
        ),
        encoding="utf-8",
    )
    doc = check_with(
        EXAMPLES / "satellite-pass", tender, checker=CHECKERS / "satellite-pass", date=DATE
    ).document
    got = [r for r in records(doc) if r["rule"] == "ITT-1-RPC-GCPS"]
    assert got and {r["verdict"] for r in got} == {"missing"}
    assert "compared with 'RPC', which is not one of its values" in got[0]["message"]
