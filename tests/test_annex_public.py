"""The annex is written for procurement (issue 26): no internal vocabulary in the annex of any shipped
profile, and nothing a public note says is filtered away.

Rule notes are split: ``note`` is public (the annex and `explain` print it), ``internal_note`` is for
the profile's maintainers (never printed); parameters likewise (``description`` / ``internal_note``).
Observation behind it: the old sentence filter dropped every sentence naming "orthospec", "seed" or
"issue N" (JRC-9.5's note lost the sentence saying what a disagreement does; JRC-6.3-NOISE lost the
definition of what is measured) while "red team R4...R16" (17 lines), "helper B", "the rule grammar
has no tangent" and "pyproj" reached the bidders.
"""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from orthospec.cli.main import cli
from orthospec.profile.loader import available, load_profile
from orthospec.reports.annex import annex_filename, plain_note, render_annex

#: words that belong to the tool's making, never to a contract document ("issue 3.0" of a source
#: document and the delivery's own delivery.yaml are the reader's words, not ours)
INTERNAL = re.compile(
    r"\bred[- ]?team\b|\bR\d{1,2}\b(?![-.]\d)|\bhelpers?\b|\bgrammar\b|\btangent\b|"
    r"\b(?:pyproj|rasterio|pint|numpy|pandas|scipy|scikit|shapely|pyogrio|GDAL|gdal\w*|weasyprint|pydantic|"
    r"jinja2?|sqlalchemy|dask|pyarrow|matplotlib)\b|"
    r"\bissues? \d+(?!\.\d)|\bseeds?\b|\bINTERFACES\b|\bmutation|\bxfail|\bTODO\b|\bFIXME\b|\bverbatim\b|\bOCR\b|"
    r"\bLaTeX\b|U\+[0-9A-F]{4}|\.py\b|(?<!delivery)\.ya?ml\b|\.txt\b|\b(?:specs|src|tests|scripts|benchmarks|docs)/|"
    r"\bevaluator\b|\bprovider\b|\bthe engine\b|\borthospec\b",
    re.I,
)
#: the annex's own sentences that name the tool (the template, not the profile)
BOILERPLATE = re.compile(r"\*Rendered by orthospec from profile [^*]*\*")
SHIPPED = sorted({pid for pid, _v, _t, _p in available()})


def _hits(text: str) -> list[str]:
    return [
        text[max(0, m.start() - 60) : m.end() + 30].replace("\n", " ")
        for m in INTERNAL.finditer(text)
    ]


@pytest.mark.parametrize("pid", SHIPPED)
def test_no_internal_vocabulary_in_the_annex_of_a_shipped_profile(pid: str) -> None:
    prof = load_profile(pid)
    md = BOILERPLATE.sub(
        "", render_annex(prof, formats=["md"], day="2026-01-01")[annex_filename(prof, "md")]
    )
    assert not _hits(md), "\n".join(_hits(md)[:20])


@pytest.mark.parametrize("pid", SHIPPED)
def test_explain_prints_no_internal_vocabulary(pid: str) -> None:
    prof = load_profile(pid)
    for r in prof.rules:
        if not r.note:
            continue
        out = CliRunner().invoke(cli(), ["explain", r.id, "--profile", pid]).output
        note = out.split("note:", 1)[1].split("\nevidence:", 1)[0] if "note:" in out else ""
        assert note.strip(), r.id
        assert not _hits(note), (r.id, _hits(note))


def test_a_public_note_reaches_the_annex_whole() -> None:
    text = (
        "Decision: the noise std of homogeneous areas (the local-standard-deviation estimator), scaled to "
        "8 bits. A disagreement beyond 1 cm is a finding for the checker, never a rejection."
    )
    assert plain_note(text) == text


@pytest.mark.parametrize(
    ("pid", "rid", "words"),
    [
        (
            "jrc-v3",
            "JRC-9.5-REPORTED-RMSE-X",
            "recomputes the block RMSE_x from the external check points",
        ),
        (
            "jrc-v3",
            "JRC-6.3-MISREGISTRATION",
            "largest shift between a band and the reference band",
        ),
        ("jrc-v3", "JRC-6.3-NOISE", "noise standard deviation of homogeneous areas"),
        ("jrc-v3", "JRC-12.5-DISTINCT-CHECKPOINTS", "reference position repeats another"),
        ("ceos-edge", "CEOS-3B-SNR", "SNR = DN difference"),
        ("usgs-insitu", "USGS-CE90-EMPIRICAL", "linear interpolation between order statistics"),
    ],
)
def test_the_annex_says_what_a_rule_measures(pid: str, rid: str, words: str) -> None:
    """What a rule measures stays in its public note (the old filter dropped it with the word 'seed')."""
    prof = load_profile(pid)
    note = plain_note(next(r for r in prof.rules if r.id == rid).note)
    assert words.lower() in note.lower(), note
    md = render_annex(prof, formats=["md"], day="2026-01-01")[annex_filename(prof, "md")]
    assert words.lower() in " ".join(md.split()).lower()
