"""init --from, surveys: each spreadsheet layout read into the convention's columns, values as the
file states them; what cannot be decided is refused with the columns and the mapping to write.

Every file here is written by the test (CSV text, openpyxl for XLSX, the OpenDocument and Office
Open XML packages by hand where a feature needs it: stored formula results, ODS), so the expected
values are the ones written.
"""

from __future__ import annotations

import csv
import io
import zipfile
from pathlib import Path

import pytest

from orthospec.errors import DeliveryError
from orthospec.ingest import points as P

FOOT = [("T1", (1000.0, 5000.0, 2000.0, 6000.0))]


def _ctx(**kw: object) -> P.Context:
    base: dict[str, object] = {"footprints": FOOT, "crs_unit": "m", "crs_name": "EPSG:25832"}
    base.update(kw)
    return P.Context(**base)  # type: ignore[arg-type]


def _rows(pr: P.PointsRead) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(pr.csv_text)))


def _write(tmp: Path, name: str, text: str, encoding: str = "utf-8") -> Path:
    p = tmp / name
    p.write_bytes(text.encode(encoding))
    return p


def test_english_csv_with_image_and_reference_columns(tmp_path: Path) -> None:
    p = _write(
        tmp_path,
        "checkpoints.csv",
        "Point ID,Easting image (m),Northing image (m),Easting ref (m),"
        "Northing ref (m),Block\nC1,1100.50,5100.25,1100.40,5100.30,B1\nC2,1200.00,5200.00,1200.10,"
        "5199.90,B1\n",
    )
    pr = P.read_points(p, "checkpoints.csv", _ctx())
    assert pr.layout.table == "checkpoints" and pr.layout.unit == "m" and pr.layout.decimal == "."
    assert _rows(pr)[0] == {
        "point_id": "C1",
        "block": "B1",
        "x": "1100.50",
        "y": "5100.25",
        "x_ref": "1100.40",
        "y_ref": "5100.30",
        "image_id": "T1",
    }


def test_semicolon_csv_with_decimal_commas_and_windows_1252(tmp_path: Path) -> None:
    """Today's pain (the issue): a ';' file with decimal commas. Read, and said so."""
    text = (
        "Punkt;Rechtswert Bild;Hochwert Bild;Rechtswert Soll;Hochwert Soll;Höhe Soll;Los\n"
        "K1;1100,5;5100,25;1100,4;5100,3;312,45;B1\nK2;1200;5200;1200,1;5199,9;310,9;B1\n"
    )
    p = _write(tmp_path, "Kontrollpunkte.csv", text, encoding="cp1252")
    pr = P.read_points(p, "Kontrollpunkte.csv", _ctx())
    rows = _rows(pr)
    assert rows[0]["x"] == "1100.5" and rows[0]["y_ref"] == "5100.3" and rows[1]["z_ref"] == "310.9"
    assert rows[0]["block"] == "B1"
    said = " ".join(pr.notes)
    assert "semicolons" in said and "decimal comma" in said and "Windows-1252" in said
    assert "the axis unit of the images' CRS" in said  # no unit in the header


def test_xlsx_with_numbers_title_row_and_two_header_rows(tmp_path: Path) -> None:
    from openpyxl import Workbook

    wb = Workbook()
    ws = wb.active
    ws.append(["Check points, lot 7"])
    ws.append(["Point", "Ortho", None, "GNSS", None, None])
    ws.append([None, "E", "N", "E", "N", "H"])
    ws.append(["P1", 1500.25, 5500.75, 1500.0, 5500.5, 250.125])
    ws.append(["P2", 1600, 5600, 1600.5, 5599.5, 251])
    ws.merge_cells("B2:C2")
    ws.merge_cells("D2:F2")
    ws.append([])  # a trailing empty row
    p = tmp_path / "checkpoints_lot7.xlsx"
    wb.save(p)
    with pytest.raises(
        P.Ambiguous, match="no unit stated"
    ):  # no unit, and no image to take one from
        P.read_points(p, p.name, _ctx(crs_unit=None, footprints=[]))
    pr = P.read_points(p, p.name, _ctx())
    assert "the axis unit of the images' CRS EPSG:25832" in " ".join(pr.notes)
    assert pr.layout.roles == {
        "point_id": "Point",
        "x": "Ortho E",
        "y": "Ortho N",
        "x_ref": "GNSS E",
        "y_ref": "GNSS N",
        "z_ref": "GNSS H",
    }
    rows = _rows(pr)
    assert [r["x"] for r in rows] == ["1500.25", "1600"] and rows[0]["z_ref"] == "250.125"
    assert pr.rows == 2


def test_the_example_spreadsheet(tmp_path: Path) -> None:
    """examples/deliveries/tiles-real: German headers over two rows, merged group cells, coordinates as
    text with decimal commas; the values are the generator's (written with 2 and 3 decimals)."""
    from openpyxl import load_workbook

    p = (
        Path(__file__).resolve().parents[1]
        / "examples/deliveries/tiles-real/survey/Kontrollpunkte_Los3.xlsx"
    )
    pr = P.read_points(p, "Kontrollpunkte_Los3.xlsx", _ctx(crs_unit=None, footprints=[]))
    sheet = load_workbook(p).active
    first = [c.value for c in sheet[4]]
    row = _rows(pr)[0]
    assert row["point_id"] == first[0]
    assert (row["x"], row["y"], row["x_ref"], row["y_ref"]) == tuple(
        v.replace(",", ".") for v in first[1:5]
    )
    assert pr.rows == sheet.max_row - 3 == 40 and pr.layout.unit == "m"


def _xlsx_by_hand(path: Path, rows: list[str]) -> None:
    """A minimal Office Open XML workbook; each row is the inner XML of a <row>."""
    ct = (
        '<?xml version="1.0"?><Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
        '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
        '<Default Extension="xml" ContentType="application/xml"/>'
        '<Override PartName="/xl/workbook.xml" ContentType="application/vnd.openxmlformats-officedocument.'
        'spreadsheetml.sheet.main+xml"/><Override PartName="/xl/worksheets/sheet1.xml" ContentType="application/'
        'vnd.openxmlformats-officedocument.spreadsheetml.worksheet+xml"/></Types>'
    )
    rels = (
        '<?xml version="1.0"?><Relationships xmlns="http://schemas.openxmlformats.org/package/2006/'
        'relationships"><Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/'
        'relationships/officeDocument" Target="xl/workbook.xml"/></Relationships>'
    )
    wb = (
        '<?xml version="1.0"?><workbook xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main" '
        'xmlns:r="http://schemas.openxmlformats.org/officeDocument/2006/relationships"><sheets>'
        '<sheet name="S" sheetId="1" r:id="rId1"/></sheets></workbook>'
    )
    wbrels = (
        '<?xml version="1.0"?><Relationships xmlns="http://schemas.openxmlformats.org/package/2006/'
        'relationships"><Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/'
        'relationships/worksheet" Target="worksheets/sheet1.xml"/></Relationships>'
    )
    body = "".join(f'<row r="{i + 1}">{r}</row>' for i, r in enumerate(rows))
    sheet = (
        '<?xml version="1.0"?><worksheet xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main">'
        f"<sheetData>{body}</sheetData></worksheet>"
    )
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("[Content_Types].xml", ct)
        z.writestr("_rels/.rels", rels)
        z.writestr("xl/workbook.xml", wb)
        z.writestr("xl/_rels/workbook.xml.rels", wbrels)
        z.writestr("xl/worksheets/sheet1.xml", sheet)


def _s(ref: str, text: str) -> str:
    return f'<c r="{ref}" t="inlineStr"><is><t>{text}</t></is></c>'


HEAD = "".join(
    _s(f"{c}1", t) for c, t in zip("ABCDE", ("id", "x_img", "y_img", "x_ref", "y_ref"), strict=True)
)


def test_formulas_give_their_stored_results_never_evaluated(tmp_path: Path) -> None:
    p = tmp_path / "checkpoints.xlsx"
    _xlsx_by_hand(
        p,
        [
            HEAD,
            _s("A2", "C1") + '<c r="B2"><v>1100</v></c><c r="C2"><v>5100</v></c>'
            '<c r="D2"><f>B2-0.25</f><v>1099.75</v></c><c r="E2"><f>WEBSERVICE("http://127.0.0.1:9/")</f>'
            "<v>5100.5</v></c>",
        ],
    )
    row = _rows(P.read_points(p, p.name, _ctx()))[0]
    assert (row["x_ref"], row["y_ref"]) == ("1099.75", "5100.5")


def test_a_formula_without_a_stored_result_is_refused_naming_the_cell(tmp_path: Path) -> None:
    p = tmp_path / "checkpoints.xlsx"
    _xlsx_by_hand(
        p,
        [
            HEAD,
            _s("A2", "C1") + '<c r="B2"><v>1100</v></c><c r="C2"><v>5100</v></c>'
            '<c r="D2"><f>B2-0.25</f></c><c r="E2"><v>5100.5</v></c>',
            _s("A3", "C2") + '<c r="B3"><v>1200</v></c><c r="C3"><v>5200</v></c>'
            '<c r="D3"><v>1200</v></c><c r="E3"><v>5200</v></c>',
        ],
    )
    with pytest.raises(DeliveryError, match=r"checkpoints.xlsx: row 2.*column D 'x_ref'.*formula"):
        P.read_points(p, p.name, _ctx())


def test_merged_cells_over_data_rows_are_refused(tmp_path: Path) -> None:
    from openpyxl import Workbook

    wb = Workbook()
    ws = wb.active
    ws.append(["Point", "E img", "N img", "E ref", "N ref", "Block"])
    ws.append(["P1", 1500, 5500, 1500.1, 5500.1, "B1"])
    ws.append(["P2", 1600, 5600, 1600.1, 5600.1, None])
    ws.merge_cells("F2:F3")
    p = tmp_path / "checkpoints.xlsx"
    wb.save(p)
    with pytest.raises(DeliveryError, match="merged cells over data rows 2-3"):
        P.read_points(p, p.name, _ctx())


def test_ods(tmp_path: Path) -> None:
    def cell(v: object) -> str:
        if isinstance(v, str):
            return f'<table:table-cell office:value-type="string"><text:p>{v}</text:p></table:table-cell>'
        return f'<table:table-cell office:value-type="float" office:value="{v}"><text:p>{v}</text:p></table:table-cell>'

    rows = [
        ["Pkt", "E", "N", "H", "Genauigkeit"],
        ["G1", 1100.5, 5100.25, 300.0, 0.02],
        ["G2", 1200.0, 5200.0, 301.5, 0.02],
    ]
    body = "".join(
        "<table:table-row>" + "".join(cell(v) for v in r) + "</table:table-row>" for r in rows
    )
    content = (
        '<?xml version="1.0" encoding="UTF-8"?><office:document-content '
        'xmlns:office="urn:oasis:names:tc:opendocument:xmlns:office:1.0" '
        'xmlns:table="urn:oasis:names:tc:opendocument:xmlns:table:1.0" '
        'xmlns:text="urn:oasis:names:tc:opendocument:xmlns:text:1.0" office:version="1.2"><office:body>'
        f'<office:spreadsheet><table:table table:name="GCP">{body}</table:table></office:spreadsheet>'
        "</office:body></office:document-content>"
    )
    manifest = (
        '<?xml version="1.0" encoding="UTF-8"?><manifest:manifest xmlns:manifest="urn:oasis:names:tc:'
        'opendocument:xmlns:manifest:1.0" manifest:version="1.2"><manifest:file-entry manifest:full-path="/" '
        'manifest:media-type="application/vnd.oasis.opendocument.spreadsheet"/><manifest:file-entry '
        'manifest:full-path="content.xml" manifest:media-type="text/xml"/></manifest:manifest>'
    )
    p = tmp_path / "Passpunkte.ods"
    with zipfile.ZipFile(p, "w") as z:
        z.writestr(zipfile.ZipInfo("mimetype"), "application/vnd.oasis.opendocument.spreadsheet")
        z.writestr("META-INF/manifest.xml", manifest)
        z.writestr("content.xml", content)
    pr = P.read_points(p, p.name, _ctx(outlines={}))
    assert pr.layout.table == "gcps"
    assert _rows(pr)[0] == {
        "point_id": "G1",
        "block": "",
        "x": "1100.5",
        "y": "5100.25",
        "z": "300",
        "precision_xy": "0.02",
    }


def test_bare_x_y_decided_by_the_images_and_said(tmp_path: Path) -> None:
    """German surveys write X for the northing: the order that puts the points on the images wins."""
    text = "Nr,Y Bild,X Bild,Y Soll,X Soll\nA,1100,5100,1100.2,5100.1\nB,1900,5900,1900.1,5899.9\n"
    pr = P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())
    assert _rows(pr)[0]["x"] == "1100" and _rows(pr)[0]["y"] == "5100"
    assert any("X/Y read as northing/easting" in n for n in pr.notes)


def test_bare_x_y_without_images_is_refused_with_the_mapping_to_write(tmp_path: Path) -> None:
    text = "Nr,X Bild,Y Bild,X Soll,Y Soll\nA,1100,5100,1100.2,5100.1\nB,1900,5900,1900.1,5899.9\n"
    with pytest.raises(P.Ambiguous) as err:
        P.read_points(
            _write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx(footprints=[])
        )
    msg = str(err.value)
    assert "checkpoints.csv" in msg and "do not say which is the easting" in msg
    assert (
        "B 'X Bild' (number" in msg
        and "orthospec_points_mapping: 1" in msg
        and "--mapping FILE" in msg
    )


def test_one_unqualified_coordinate_set_is_refused(tmp_path: Path) -> None:
    text = "id;E;N;H\nA;1100,5;5100,5;10\nB;1200,5;5200,5;11\n"
    with pytest.raises(P.Ambiguous, match="telling image .* from reference"):
        P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())


def test_mixed_decimal_marks_and_mixed_units_are_refused(tmp_path: Path) -> None:
    text = "id;E img;N img;E ref;N ref\nA;1100,5;5100.5;1100;5100\nB;1200;5200;1200;5200\n"
    with pytest.raises(P.Ambiguous, match="decimal comma .* and a decimal point"):
        P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())
    text = "id,E img [m],N img [m],E ref [ft],N ref [ft]\nA,1100,5100,1100,5100\nB,1200,5200,1200,5200\n"
    with pytest.raises(P.Ambiguous, match="different units"):
        P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())


def test_no_unit_and_points_off_the_images_is_refused(tmp_path: Path) -> None:
    text = "id,E img,N img,E ref,N ref\nA,9100,9100,9100,9100\nB,9200,9200,9200,9200\n"
    with pytest.raises(P.Ambiguous, match="no unit stated"):
        P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())


def test_a_saved_mapping_reads_a_second_file_without_questions(tmp_path: Path) -> None:
    """The undecidable layout named once (the proposal, filled in) reads every file of that layout."""
    text = "Nr,X Bild,Y Bild,X Soll,Y Soll\nA,1100,5100,1100.2,5100.1\nB,1900,5900,1900.1,5899.9\n"
    p = _write(tmp_path, "survey.csv", text)
    layout = {
        "match": ["Nr", "X Bild", "Y Bild", "X Soll", "Y Soll"],
        "table": "checkpoints",
        "columns": {
            "point_id": "Nr",
            "x": "Y Bild",
            "y": "X Bild",
            "x_ref": "Y Soll",
            "y_ref": "X Soll",
        },
        "unit": "m",
        "decimal": ".",
    }
    pr = P.read_points(p, "survey.csv", _ctx(footprints=[], layouts=[layout]))
    assert _rows(pr)[0]["x"] == "5100" and pr.layout.unit == "m"
    second = _write(tmp_path, "survey2.csv", text.replace("A,", "Z,"))
    assert (
        _rows(P.read_points(second, "survey2.csv", _ctx(footprints=[], layouts=[layout])))[0][
            "point_id"
        ]
        == "Z"
    )
    saved = pr.layout.to_mapping(["survey.csv"])
    assert saved["match"] == layout["match"] and saved["columns"] == layout["columns"]


def test_blocks_by_location_and_points_outside_every_outline(tmp_path: Path) -> None:
    import shapely

    outlines = {"W": shapely.box(1000, 5000, 1500, 6000), "E": shapely.box(1500, 5000, 2000, 6000)}
    text = (
        "id,E img,N img,E ref,N ref\nA,1100,5100,1100.1,5100.1\nB,1900,5900,1900.1,5899.9\n"
        "C,2500,5500,2500,5500\n"
    )
    pr = P.read_points(
        _write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx(outlines=outlines)
    )
    assert [(r["point_id"], r["block"]) for r in _rows(pr)] == [("A", "W"), ("B", "E")]
    assert pr.outside == ["C"]
    assert [r["image_id"] for r in _rows(pr)] == ["T1", "T1"]  # both on the one footprint
    assert (
        "image_id: the image whose footprint holds the point (2 points); 1 on no image"
        in "\n".join(pr.notes)
    )


def test_a_stated_block_the_location_contradicts_is_overruled_and_said(tmp_path: Path) -> None:
    import shapely

    outlines = {"W": shapely.box(1000, 5000, 1500, 6000), "E": shapely.box(1500, 5000, 2000, 6000)}
    text = "id,Block,E img,N img,E ref,N ref\nA,W,1100,5100,1100,5100\nB,W,1900,5900,1900,5900\n"
    pr = P.read_points(
        _write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx(outlines=outlines)
    )
    assert [(r["point_id"], r["block"]) for r in _rows(pr)] == [("A", "W"), ("B", "E")]
    assert any(
        n.startswith(
            "block stated in the file differs from the outline the point lies in (1; the location "
            "decides): B (W -> E)"
        )
        for n in pr.notes
    ), pr.notes


def test_duplicate_ids_and_bad_numbers_name_the_row(tmp_path: Path) -> None:
    text = "id,E img,N img,E ref,N ref\nA,1100,5100,1100,5100\nA,1200,5200,1200,5200\n"
    with pytest.raises(DeliveryError, match=r"row 3.*'A' also on row 2"):
        P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())
    text = (
        "id,E img,N img,E ref,N ref\n"
        + "".join(f"P{i},1100,5100,1100,5100\n" for i in range(8))
        + "B,1200,5200,12OO,5200\n"
    )  # a letter O typed for a zero, on row 10
    with pytest.raises(DeliveryError, match=r"row 10.*column D 'E ref'.*'12OO' is not a number"):
        P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())


def test_row_limit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ORTHOSPEC_MAX_SHEET_ROWS", "50")
    text = "id,E img,N img,E ref,N ref\n" + "".join(
        f"P{i},1100,5100,1100,5100\n" for i in range(60)
    )
    with pytest.raises(DeliveryError, match="more than ORTHOSPEC_MAX_SHEET_ROWS"):
        P.read_points(_write(tmp_path, "checkpoints.csv", text), "checkpoints.csv", _ctx())


@pytest.mark.slow
def test_a_million_rows_in_bounded_memory(tmp_path: Path) -> None:
    """10^6 survey rows (hostile, or a national file) stream through in chunks."""
    import subprocess
    import sys

    p = tmp_path / "checkpoints.csv"
    with p.open("w") as fh:
        fh.write("id,E img,N img,E ref,N ref\n")
        for i in range(1_000_000):
            fh.write(
                f"P{i},{1000 + i % 1000}.5,{5000 + i % 997}.25,{1000 + i % 1000}.4,{5000 + i % 997}.3\n"
            )
    # VmHWM: this process's own peak RSS (ru_maxrss would carry over the forking pytest worker's,
    # which Linux keeps across fork + exec)
    code = (
        "import re; from pathlib import Path; from orthospec.ingest import points as P;"
        f"pr=P.read_points(Path({str(p)!r}),'checkpoints.csv',P.Context(footprints=[('T',(0.,0.,1e9,1e9))],"
        "crs_unit='m')); print(pr.rows, re.search(r'VmHWM:\\s+(\\d+) kB', open('/proc/self/status').read())[1])"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split()
    assert int(out[0]) == 1_000_000
    assert int(out[1]) < 500 * 1024, f"peak {int(out[1]) / 1024:.0f} MB"
