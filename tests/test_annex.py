"""The tender annex rendered from a profile: Markdown, HTML and PDF/A-3b, read back."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pdfplumber
import pytest
from click.testing import CliRunner
from pypdf import PdfReader

from orthospec.cli.main import cli
from orthospec.errors import ReportError
from orthospec.profile.loader import load_profile
from orthospec.profile.models import Parameter, Requirement
from orthospec.reports.annex import annex_filename, render_annex, requirement_text

DATA = Path(__file__).resolve().parent / "data"

HOSTILE = """\
orthospec_profile: 1
id: hostile
version: 0.1.0
title: "Annex <script>alert(1)</script> | pipes"
source: {title: Test source}
parameters:
  tolerance_xy: {unit: m, value: 0.5, description: "Tolerance | with a pipe <b>bold</b>"}
rules:
  - id: H-1
    title: "Title with | pipe"
    clause: {document: DOC, section: "3.1"}
    quote: "Text with <img src=\\"http://127.0.0.1:9/x\\"> and | a pipe"
    scope: block
    measure: checkpoints.rmse_x
    requirement: {op: "<=", value: tolerance_xy, unit: m}
    consequence: reject_block
  - id: H-2
    title: Table rule
    clause: {document: DOC, table: "4", row: a}
    quote: From a table
    scope: image
    measure: images.roll
    requirement: {op: between, min: 0, max: 3, unit: deg}
    level: recommended
    consequence: warn
"""


@pytest.fixture(scope="module")
def mini_annex() -> dict[str, str | bytes]:
    prof = load_profile(DATA / "profiles" / "mini.yaml", check_measures=False)
    return {"profile": prof, **render_annex(prof, formats=["md", "html", "pdf"], day="2026-01-01")}


def test_markdown_lists_parameters_and_every_rule_with_clause_and_quote(mini_annex: dict) -> None:
    prof = mini_annex["profile"]
    md = mini_annex[annex_filename(prof, "md")]
    assert prof.sha256 in md
    for name, p in prof.parameters.items():
        assert f"`{name}`" in md and (p.unit or "") in md
    assert re.search(r"\| Max roll \(`max_roll`\) \| 3 \| deg \| standard \|", md)
    assert re.search(
        r"\| Tolerance xy \(`tolerance_xy`\) \| — \| m \| to be fixed in the ITT \(required\) \|",
        md,
    )
    for rule in prof.rules:
        assert f"`{rule.id}`" in md
        assert rule.clause.text() in md
        assert rule.quote in md
    # grouped like the source: §5.x before §6.x before §12.x
    heads = re.findall(r"^### 2\.\d+ (.+)$", md, flags=re.M)
    assert heads == [
        "JRC EUR 23638 EN — Section 5",
        "JRC EUR 23638 EN — Section 6",
        "JRC EUR 23638 EN — Section 12",
    ]
    assert "≤ 3 deg" in md and "reject item" in md


def test_pdf_annex_is_pdfa_with_resolved_profile_attached(mini_annex: dict) -> None:
    prof = mini_annex["profile"]
    pdf = mini_annex[annex_filename(prof, "pdf")]
    reader = PdfReader(io.BytesIO(pdf))
    att = {k: v[0] for k, v in reader.attachments.items()}
    assert att[f"{prof.id}-{prof.version}.json"].decode("utf-8") == prof.canonical_json()
    xmp = reader.trailer["/Root"]["/Metadata"].get_object().get_data().decode("utf-8")
    assert 'pdfaid:part="3"' in xmp and 'pdfaid:conformance="B"' in xmp
    with pdfplumber.open(io.BytesIO(pdf)) as doc:
        text = "\n".join(p.extract_text() or "" for p in doc.pages)
    for rule in prof.rules:
        assert rule.id in text
    assert "page 1 of" in text and prof.sha256 in text.replace(" ", "")
    again = render_annex(prof, formats=["pdf"], day="2026-01-01")[annex_filename(prof, "pdf")]
    assert again == pdf


def test_profile_text_is_escaped_in_html_and_markdown(tmp_path: Path) -> None:
    path = tmp_path / "hostile.yaml"
    path.write_text(HOSTILE, encoding="utf-8")
    prof = load_profile(path, check_measures=False)
    out = render_annex(prof, formats=["md", "html"], day="2026-01-01")
    html = out[annex_filename(prof, "html")]
    assert "<script>" not in html and "<img src=" not in html and "<b>bold</b>" not in html
    assert "&lt;script&gt;" in html
    md = out[annex_filename(prof, "md")]
    assert "<script>" not in md and "<img" not in md
    row = next(line for line in md.splitlines() if line.startswith("| `H-1`"))
    assert row.count(" | ") + 2 == 7  # six cells: the pipes inside texts are escaped
    assert "Title with \\| pipe" in row
    assert "## 2.2 DOC — Table 4" in md.replace("### ", "## ")


@pytest.mark.parametrize(
    ("req", "expected"),
    [
        (Requirement(op="<=", value="tol", unit="m"), "≤ 0.5 m"),
        # evaluated: 0.5 / 3, printed to 6 significant digits as the QCR prints the threshold it
        # applied (3 digits, "0.167 m", told bidders a looser threshold than the one checked)
        (Requirement(op="<=", value="tol / 3", unit="m"), "≤ 0.166667 m"),
        # 0.5 * 0.999 and 0.5 * 1.001: at 3 digits both sides read 0.5 m, a range of no width
        (
            Requirement(op="between", min="tol * 0.999", max="tol * 1.001", unit="m"),
            "between 0.4995 m (incl.) and 0.5005 m (incl.)",
        ),
        (Requirement(op=">=", value=20, unit="1"), "≥ 20"),
        (Requirement(op="<", value=2.5, unit="m"), "< 2.5 m"),
        (
            Requirement(op="between", min=0, max=3, unit="deg"),
            "between 0 deg (incl.) and 3 deg (incl.)",
        ),
        (Requirement(op="in", values=["a", "b"]), "one of a, b"),
        (Requirement(op="<=", value="free", unit="m"), "≤ the value fixed in the ITT"),
        (Requirement(op="<=", value="2 * tol"), "≤ 2 * tol"),
    ],
)
def test_requirement_text(req: Requirement, expected: str) -> None:
    params = {"tol": Parameter(unit="m", default=0.5), "free": Parameter(unit="m", required=True)}
    assert requirement_text(req, params) == expected


def test_spec_render_command_writes_requested_formats(tmp_path: Path) -> None:
    res = CliRunner().invoke(
        cli(),
        [
            "spec",
            "render",
            str(DATA / "profiles" / "mini.yaml"),
            "--format",
            "md,html",
            "--out",
            str(tmp_path),
            "--date",
            "2026-01-01",
        ],
    )
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "annex-mini-1.0.0.html",
        "annex-mini-1.0.0.md",
    ]
    assert "2026-01-01" in (tmp_path / "annex-mini-1.0.0.md").read_text(encoding="utf-8")
    bad = CliRunner().invoke(
        cli(), ["spec", "render", str(DATA / "profiles" / "mini.yaml"), "--format", "docx"]
    )
    assert bad.exit_code == 2 and "unknown format" in bad.output
    with pytest.raises(ReportError, match="unknown annex format"):
        render_annex(load_profile(DATA / "profiles" / "mini.yaml"), formats=["rtf"])


def test_spec_render_publishes_profile_with_unimplemented_measures(tmp_path: Path) -> None:
    path = tmp_path / "future.yaml"
    path.write_text(
        HOSTILE.replace("measure: images.roll", "measure: future.measure_x"), encoding="utf-8"
    )
    res = CliRunner().invoke(
        cli(),
        [
            "spec",
            "render",
            str(path),
            "--format",
            "md",
            "--out",
            str(tmp_path),
            "--date",
            "2026-01-01",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "warning:" in res.output and "future.measure_x" in res.output
    assert "`H-2`" in (tmp_path / "annex-hostile-0.1.0.md").read_text(encoding="utf-8")
    broken = tmp_path / "broken.yaml"
    broken.write_text(HOSTILE.replace("scope: block", "scope: nowhere"), encoding="utf-8")
    res = CliRunner().invoke(
        cli(), ["spec", "render", str(broken), "--format", "md", "--out", str(tmp_path)]
    )
    assert res.exit_code != 0 and not (tmp_path / "annex-hostile-0.1.0.html").exists()


def test_tender_annex_is_procurement_grade() -> None:
    """Issue 13 item 6: evaluated thresholds, sensor filter, prose conditions, plain notes, ITT changes."""
    from pathlib import Path

    from orthospec.profile.loader import load_profile

    prof = load_profile(
        Path(__file__).resolve().parents[1] / "examples" / "specs" / "tender-example.yaml"
    )
    out = render_annex(prof, formats=["md", "pdf"], day="2026-11-23")
    md = out[annex_filename(prof, "md")]
    with pdfplumber.open(io.BytesIO(out[annex_filename(prof, "pdf")])) as pdf:
        text = "\n".join(p.extract_text() or "" for p in pdf.pages)
    jrc = load_profile("jrc-v3")
    jrc_md = render_annex(jrc, formats=["md"], day="2026-11-23")[annex_filename(jrc, "md")]
    for body in (md, text, jrc_md):
        for word in ("seed", "Trap", "manifest.", "**"):
            assert word not in body, word
        # the rule authors' remarks on how the source was transcribed are not for bidders
        assert not re.search(r"\b(OCR|trap)\b", body), re.search(r".{60}\b(OCR|trap)\b.{20}", body)
    # the block tolerance of the ITT (tolerance_xy = 0.5 m) as a number with its unit
    rmsey = next(line for line in md.splitlines() if line.startswith("| `JRC-12.7-RMSEY`"))
    assert "| ≤ 0.5 m |" in rmsey
    # GCPs three times more precise than 0.5 m: 0.5 / 3 m, not a formula
    gcp = next(line for line in md.splitlines() if line.startswith("| `JRC-7.1-GCP-ACCURACY-3X`"))
    assert "0.166667 m" in gcp and "gcp_accuracy_factor" not in gcp
    # an aerial digital ITT: satellite and film rules are in Appendix A, not in the requirements
    body, appendix = md.split("## Appendix A.")
    sat = [
        r.id
        for r in prof.rules
        if r.when and "manifest.sensor.type == 'satellite'" in r.when and " or " not in r.when
    ]
    assert sat
    for rid in sat:
        assert f"`{rid}`" not in body and f"`{rid}`" in appendix
    # what the ITT changed is marked, and the tightened title does not keep the guideline's range
    cloud = next(line for line in md.splitlines() if line.startswith("| `JRC-6.3-CLOUD-COVER`"))
    assert "changed by the ITT" in cloud and "5-10 %" not in cloud and "≤ 5 %" in cloud
    assert "## Appendix C. Interpretation notes" in md
