"""The findings layers feed the GeoPackage, the HTML map and the PDF's static map alike (issue 30
items 2 and 4), and delivery text reaches all of them escaped."""

from __future__ import annotations

import io
import json
import re
from collections import Counter
from pathlib import Path
from typing import Any

import pdfplumber
import pytest
import yaml
from click.testing import CliRunner
from tests.conftest import ROOT
from tests.test_gpkg import layer, run

from orthospec.cli.main import cli
from orthospec.findings import build_layers, to_gpkg
from orthospec.findings.layers import nice_scale
from orthospec.reports.fetcher import data_uri
from orthospec.reports.html import ReportOptions, render_html
from orthospec.reports.interactive import MAP_LAYERS, map_html

LAYER_OF = re.compile(r'<g class="layer" data-layer="([a-z_]+)">(.*?)</g>', re.S)


def drawn_counts(html: str) -> dict[str, Counter[str]]:
    """Verdicts of the features each layer of the map draws, read from the SVG markup."""
    svg = html[html.index('<svg xmlns="http://www.w3.org/2000/svg" class="findings-map"'):]
    svg = svg[: svg.index("</svg>")]
    return {
        name: Counter(re.findall(r'data-verdict="([^"]*)"', body))
        for name, body in LAYER_OF.findall(svg)
    }


@pytest.fixture(scope="module")
def aerial_fail(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("layers") / "out"
    run(out, "json,gpkg,html,pdf")
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    return {"out": out, "doc": doc}


def test_static_pdf_map_html_map_and_gpkg_agree(aerial_fail: dict[str, Any]) -> None:
    out, doc = aerial_fail["out"], aerial_fail["doc"]
    static = render_html(doc, ReportOptions(bounded=True), figure=data_uri, pdf=True)
    interactive = (out / "report.html").read_text(encoding="utf-8")
    assert (
        "<script>" not in static[static.index('id="findings-map"') : static.index("</svg>")]
    )  # static in the PDF
    pdf_map, html_map = drawn_counts(static), drawn_counts(interactive)
    assert pdf_map == html_map
    for name in MAP_LAYERS:
        geoms, cols = layer(out / "findings.gpkg", name)
        want = Counter(
            "" if v is None else str(v)
            for g, v in zip(geoms, cols["verdict"], strict=True)
            if g is not None
        )
        assert pdf_map[name] == want, name
    assert sum(pdf_map["blocks"].values()) == 3 and pdf_map["blocks"]["fail"] == 3
    with pdfplumber.open(io.BytesIO((out / "report.pdf").read_bytes())) as pdf:
        text = "\n".join(p.extract_text() or "" for p in pdf.pages)
    assert "Map of the findings" in text and "Residual vectors are drawn" in text


def test_footprints_travel_in_qcr_json(aerial_fail: dict[str, Any], tmp_path: Path) -> None:
    """The map re-renders from qcr.json alone: the footprints the check read are details.footprints."""
    import rasterio

    doc = aerial_fail["doc"]
    feet = doc["details"]["footprints"]
    with rasterio.open(ROOT / "examples/deliveries/aerial-fail/images/F01_0101.tif") as ds:
        assert feet["F01_0101"] == pytest.approx(list(ds.bounds))
    assert "F03_0202" not in feet  # listed, not delivered
    html = render_html(doc, ReportOptions(), figure=data_uri)
    assert drawn_counts(html) == drawn_counts(
        (aerial_fail["out"] / "report.html").read_text(encoding="utf-8")
    )
    run(tmp_path / "json", "json")  # no map asked for: no header read, no footprints
    plain = json.loads((tmp_path / "json" / "qcr.json").read_text(encoding="utf-8"))
    assert "footprints" not in plain["details"]
    counts = drawn_counts(render_html(plain, ReportOptions(), figure=data_uri))
    assert sum(counts["blocks"].values()) == 3 and sum(counts["checkpoints"].values()) == 64
    assert not counts["images"]


def test_nice_scale() -> None:
    assert [nice_scale(v) for v in (531.0, 199.0, 1.0, 0.07)] == [500.0, 100.0, 1.0, 0.05]


HOSTILE_BLOCK = 'B1"><script>alert("b")</script>'
HOSTILE_POINT = "P'\"<img src=x onerror=alert(1)>"
QUOTED_BLOCK = '"' + HOSTILE_BLOCK.replace('"', '""') + '"'


def _hostile_delivery(root: Path) -> Path:
    from tests.test_reports import PROFILE, write_delivery

    write_delivery(root)
    m = yaml.safe_load((root / "delivery.yaml").read_text(encoding="utf-8"))
    m["blocks"][0]["id"] = HOSTILE_BLOCK
    m["blocks"][0]["polygon"] = [
        [499000, 5399000],
        [506000, 5399000],
        [506000, 5406000],
        [499000, 5406000],
    ]
    (root / "delivery.yaml").write_text(yaml.safe_dump(m, sort_keys=False), encoding="utf-8")
    for name in ("checkpoints.csv", "gcps.csv", "images.csv"):
        p = root / "tables" / name
        lines = p.read_text(encoding="utf-8").splitlines()
        lines = [
            lines[0],
            *(re.sub(r"(?<=,)B1(?=,|$)", lambda _m: QUOTED_BLOCK, ln) for ln in lines[1:]),
        ]
        if name == "checkpoints.csv":
            lines[1] = (
                '"' + HOSTILE_POINT.replace('"', '""') + '"' + lines[1][lines[1].index(",") :]
            )
        p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    (root.parent / "profile.yaml").write_text(PROFILE, encoding="utf-8")
    return root


def test_hostile_ids_reach_gpkg_as_data_and_html_escaped(tmp_path: Path) -> None:
    d = _hostile_delivery(tmp_path / "d")
    out = tmp_path / "out"
    res = CliRunner().invoke(
        cli(),
        [
            "check",
            str(d),
            "--profile",
            str(tmp_path / "profile.yaml"),
            "--out",
            str(out),
            "--date",
            "2026-01-01",
            "--format",
            "json,gpkg,html",
            "--param",
            "tolerance_xy=0.5m",
        ],
    )
    assert res.exit_code in (0, 1), res.output + repr(res.exception)
    _, blocks = layer(out / "findings.gpkg", "blocks")
    assert HOSTILE_BLOCK in list(blocks["id"])  # the GeoPackage holds the id as data, verbatim
    _, pts = layer(out / "findings.gpkg", "checkpoints")
    assert HOSTILE_POINT in list(pts["point_id"]) and HOSTILE_BLOCK in list(pts["block"])
    html = (out / "report.html").read_text(encoding="utf-8")
    start = html.index('id="findings-map"')
    map_part = html[start : html.index("</div>", html.index('id="findings-data"'))]
    assert "<script>alert" not in html and "<img src=x" not in html
    assert "&lt;script&gt;alert(&#34;b&#34;)&lt;/script&gt;" in map_part  # the SVG titles
    island = html[html.index('id="findings-data">') + len('id="findings-data">') :]
    island = island[: island.index("</script>")]
    assert "<" not in island and "\\u003cscript\\u003e" in island
    assert HOSTILE_BLOCK in [
        f["id"] for f in json.loads(island).values()
    ]  # the click shows the id as text


def test_bidi_override_is_shown_never_obeyed(aerial_fail: dict[str, Any], tmp_path: Path) -> None:
    """A hand-edited qcr.json (the delivery's readers refuse U+202E) still cannot reorder the map."""
    doc = json.loads(json.dumps(aerial_fail["doc"]))
    pts = doc["details"]["checkpoints"]["B01"]["points"]["data"]["point_id"]
    pts[0] = "\u202eevil"
    html = map_html(build_layers(doc), interactive=True)
    assert "\u202e" not in html and "[U+202E]evil" in html
    gpkg = tmp_path / "f.gpkg"
    gpkg.write_bytes(to_gpkg(doc))
    _, cols = layer(gpkg, "checkpoints")
    assert "[U+202E]evil" in list(cols["point_id"]) and not any(
        "\u202e" in str(v) for v in cols["point_id"]
    )


def test_seamlines_carry_the_verdict_of_their_image(
    aerial_fail: dict[str, Any], tmp_path: Path
) -> None:
    import shapely

    from orthospec.findings import DeliveryGeometry
    from orthospec.qcr import all_records

    doc = aerial_fail["doc"]
    scopes = {r["rule"]: r["scope"] for r in doc["rules"]}
    severity = ("error", "fail", "missing", "warn", "waived", "pass", "not_applicable")
    verdicts = [
        r["verdict"]
        for r in all_records(doc)
        if scopes[r["rule"]] == "image" and r["item"] == "F01_0101"
    ]
    geometry = DeliveryGeometry(
        seamlines=[
            (shapely.box(506000, 5412000, 506100, 5412100), "F01_0101"),
            (shapely.box(506100, 5412000, 506200, 5412100), None),
        ],
        seamlines_file="vectors/seamlines.gpkg",
    )
    gpkg = tmp_path / "s.gpkg"
    gpkg.write_bytes(to_gpkg(doc, geometry))
    geoms, cols = layer(gpkg, "seamlines")
    assert list(cols["image_id"]) == ["F01_0101", None]
    assert cols["verdict"][0] == min(verdicts, key=severity.index) and cols["verdict"][1] is None
    assert geoms[0].equals(shapely.box(506000, 5412000, 506100, 5412100))
    assert drawn_counts(map_html(build_layers(doc, geometry), interactive=False))[
        "seamlines"
    ] == Counter({cols["verdict"][0]: 1, "": 1})  # not judged
