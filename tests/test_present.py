"""One presentation vocabulary (issue 28 item 3): one formatter set, one clause citation, reports that
draw what was judged.

Why: a value or a citation spelled differently in two outputs makes a reader ask which one the
verdict used; a report figure recomputed from the points can disagree with the measured value the
rule judged. Expected strings come from the profile's YAML and from the format specifications
(Python's ``g``/``f`` formats), not from orthospec's own output.
"""

from __future__ import annotations

import ast
import csv
import io
import json
import math
import re
from pathlib import Path
from typing import Any

import pdfplumber
import pytest
import yaml
from click.testing import CliRunner
from tests.checking import CHECKERS, EXAMPLES, ROOT

from orthospec import present
from orthospec.cli.main import cli
from orthospec.present import (
    NO_VALUE,
    cite,
    fmt_fixed,
    fmt_measured,
    fmt_number,
    fmt_quantity,
    fmt_value,
)
from orthospec.profile.loader import load_profile
from orthospec.qcr import all_records
from orthospec.reports import html

SRC = ROOT / "src" / "orthospec"
JRC = yaml.safe_load((ROOT / "specs" / "jrc-v3.yaml").read_text(encoding="utf-8"))
JRC_RULES = {r["id"]: r for r in JRC["rules"]}


# --- the formatters -----------------------------------------------------------------------------


def test_no_value_has_one_spelling() -> None:
    for x in (None, float("nan")):
        assert fmt_value(x) == NO_VALUE
        assert fmt_fixed(x) == NO_VALUE
        assert fmt_number(x) == NO_VALUE
        assert fmt_quantity(x, "m") == NO_VALUE  # no unit after a missing value
    assert fmt_measured(None) == fmt_measured({}) == NO_VALUE


def test_values_print_as_the_formats_say() -> None:
    assert fmt_value(0.123456789) == "0.123457"  # 6 significant digits
    assert fmt_value(2.0) == "2"
    assert fmt_value(1 / 3, 10) == "0.3333333333"
    assert fmt_value(True) == "true" and fmt_value(False) == "false"  # as a profile writes them
    assert fmt_value([0.5, True, "a"]) == "0.5, true, a"
    assert fmt_fixed(0.5, 3) == "0.500" and fmt_fixed("text") == "text"
    assert fmt_number(0.64123) == "0.641" and fmt_number(1234.7) == "1235" and fmt_number(7) == "7"
    assert fmt_quantity(0.641, "m") == "0.641 m" and fmt_quantity(3, "1") == "3"
    assert fmt_measured({"value": 12.5, "unit": "%"}) == "12.5 %"
    assert fmt_value(math.inf) == "inf"


# --- the citation ------------------------------------------------------------------------------

RULE = "JRC-12.4-T12-CHECKPOINTS-PRESENT"  # §12.4, Table 12, row 'Check points'


def _yaml_clause(rule: str) -> dict[str, Any]:
    return JRC_RULES[rule]["clause"]


def test_citation_styles_of_a_profile_clause() -> None:
    c = _yaml_clause(RULE)
    text = f"{c['document']}, §{c['section']}, Table {c['table']}, row '{c['row']}'"
    columns = f"{c['document']}, {c['section']}, {c['table']}, {c['row']}"
    assert cite(c) == text and cite(c, "columns") == columns
    assert cite(c, "section") == f"§{c['section']}"
    assert cite(c, "ref") == f"§{c['section']} T{c['table']}"
    clause = next(r for r in load_profile("jrc-v3").rules if r.id == RULE).clause
    assert clause.text() == cite(clause) == text  # the model and a qcr.json dict cite alike
    assert clause.ref() == cite(clause, "ref")
    assert cite(None) == "" and cite("as worded") == "as worded"


#: formatters of something that is not a value or a citation (row ranges of the evidence)
NOT_VALUES = {"fmt_rows"}
PRESENT_NAMES = set(present.__all__)


def _own_formatters(path: Path) -> list[str]:
    """Functions named like a value formatter or a citation that do not format through
    orthospec.present (a thin wrapper that calls it is how a module keeps its cell conventions)."""
    formatter = re.compile(r"^_?(fmt|fmt_\w+|format_value|clause_text|_?clause|cite)$")
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, ast.FunctionDef) or not formatter.match(node.name):
            continue
        used = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}
        if node.name not in NOT_VALUES and not used & PRESENT_NAMES:
            out.append(node.name)
    return out


def test_no_second_formatter_or_citation_creeps_back() -> None:
    """Value formatters and clause citations live in orthospec/present.py only: a function named
    like one elsewhere that does not call it, or a citation spelled by hand (``§{`` in an
    f-string), fails here."""
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        if path.name in (
            "present.py",
            "cmd_measure_edge.py",
        ):  # edge: its owner moves it (issue 31)
            continue
        rel = path.relative_to(SRC)
        offenders += [f"{rel}: def {n}" for n in _own_formatters(path)]
        text = path.read_text(encoding="utf-8")
        offenders += [f"{rel}: {m.group(0)}" for m in re.finditer(r"f[\"'][^\"'\n]*§\{", text)]
    assert offenders == []


def test_the_guard_sees_a_second_formatter(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text('def _fmt(v):\n    return "—" if v is None else f"{v:.3f}"\n', encoding="utf-8")
    assert _own_formatters(bad) == ["_fmt"]
    bad.write_text("def _fmt(v):\n    return fmt_fixed(v, 3)\n", encoding="utf-8")
    assert _own_formatters(bad) == []


# --- one delivery, every output -----------------------------------------------------------------


@pytest.fixture(scope="module")
def aerial_fail(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """`orthospec check examples/deliveries/aerial-fail` with every text output, read back."""
    out = tmp_path_factory.mktemp("present") / "out"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(EXAMPLES / "aerial-fail"),
            "--profile",
            "jrc-v3",
            "--checker",
            str(CHECKERS / "aerial-fail"),
            "--date",
            "2026-11-21",
            "--out",
            str(out),
            "--format",
            "terminal,json,csv,junit,html,pdf",
        ],
        terminal_width=400,
    )
    assert res.exit_code == 1, res.output
    with pdfplumber.open(out / "report.pdf") as pdf:
        pdf_text = "\n".join(p.extract_text() or "" for p in pdf.pages)
    return {
        "terminal": res.output,
        "doc": json.loads((out / "qcr.json").read_text(encoding="utf-8")),
        "csv": list(csv.DictReader(io.StringIO((out / "qcr.csv").read_text(encoding="utf-8")))),
        "html": (out / "report.html").read_text(encoding="utf-8"),
        "pdf": " ".join(pdf_text.split()),
    }


@pytest.mark.parametrize("rule", ["JRC-12.4-T12-MIN-CHECKPOINTS", "JRC-12.5-QUADRANTS"])
def test_every_output_cites_a_rule_alike(aerial_fail: dict[str, Any], rule: str) -> None:
    """Both rules find a problem in aerial-fail (block B03): qcr.json, qcr.csv, the HTML and the
    PDF cite each as the profile's clause says, row included, and never shorter."""
    c = _yaml_clause(rule)
    parts = [c["document"], f"§{c['section']}"]
    parts += [f"Table {c['table']}"] if c.get("table") else []
    short = ", ".join(parts)
    parts += [f"row '{c['row']}'"] if c.get("row") else []
    text = ", ".join(parts)
    doc = aerial_fail["doc"]
    assert next(r for r in doc["rules"] if r["rule"] == rule)["clause"] == text
    col = ", ".join(str(c[k]) for k in ("document", "section", "table", "row") if c.get(k))
    assert {r["clause"] for r in aerial_fail["csv"] if r["rule"] == rule} == {col}
    page = html.markupsafe.escape(text)
    assert page in aerial_fail["html"]
    assert text in aerial_fail["pdf"].replace("’", "'")
    if short != text:  # a citation without its row is a second spelling
        assert f"({html.markupsafe.escape(short)})" not in aerial_fail["html"]


def test_report_draws_the_judged_quadrant_shares(aerial_fail: dict[str, Any]) -> None:
    """The HTML quadrant figure of every block shows the shares the provider recorded, whose
    smallest is the value the rule judged (measured in %)."""
    doc = aerial_fail["doc"]
    judged = {
        r["item"]: r["measured"]["value"]
        for r in all_records(doc)
        if r["rule"] == "JRC-12.5-QUADRANTS"
    }
    for bid, b in doc["details"]["checkpoints"].items():
        q = b["quadrants"]
        assert sum(q["counts"].values()) > 0
        assert min(q["shares"].values()) * 100 == pytest.approx(judged[bid], rel=1e-6)
        svg = next(f for f in html._block_figures(b, bid) if f["kind"] == "dist")["svg"]
        for quad, share in q["shares"].items():
            assert f">{quad} {share:.0%}</text>" in svg


def test_report_never_recomputes_the_distribution(aerial_fail: dict[str, Any]) -> None:
    """Planted shares in qcr.json are what the figure prints (a recomputation from the points
    would print the points' shares); without recorded shares no distribution figure is drawn."""
    b = json.loads(json.dumps(aerial_fail["doc"]["details"]["checkpoints"]["B02"]))
    b["quadrants"]["shares"] = {"NE": 0.61, "NW": 0.13, "SW": 0.17, "SE": 0.09}
    svg = next(f for f in html._block_figures(b, "B02") if f["kind"] == "dist")["svg"]
    assert ">NE 61%</text>" in svg and ">SE 9%</text>" in svg
    del b["quadrants"]
    assert [f["kind"] for f in html._block_figures(b, "B02") if f["kind"] == "dist"] == []
