import pytest
from tests.conftest import IMAGES

from orthospec.delivery.reader import open_delivery
from orthospec.errors import DeliveryError
from orthospec.provenance import sha256_file


def test_opens_and_types_tables(make_delivery):
    d = open_delivery(make_delivery())
    t = d.table("images")
    assert t.df["roll"].tolist() == [0.5, 2.5, 4.0]
    assert t.df["_row"].tolist() == [1, 2, 3]
    assert t.units["flying_height"] == "m"
    assert t.sha256 == sha256_file(d.root / "tables" / "images.csv")
    assert d.gsd_m == 0.25
    assert d.block_ids == ["B1", "B2"]


@pytest.mark.parametrize("images, message", [
    ("image_id,file\nI1,a.tif\n", "missing required column(s) block"),
    ("image_id,file,block,colour\nI1,a.tif,B1,red\n", "unexpected column(s) colour"),
    ("image_id,file,block,roll\nI1,a.tif,B1,abc\n", "row 1: column 'roll': expected a number, got 'abc'"),
    ("image_id,file,block,roll\nI1,a.tif,B1,1\nI2,b.tif,B1,NaN\n", "row 2: column 'roll': expected a finite"),
    ("image_id,file,block,roll\nI1,a.tif,B1,inf\n", "expected a finite number"),
    ("image_id,file,block\nI1,a.tif,B1\nI1,b.tif,B1\n", "duplicate id 'I1' in rows 1, 2"),
    ("image_id,file,block\nI1,a.tif\n", "row 1: has 2 fields, the header has 3"),
    ("image_id,file,block,exposure_time\nI1,a.tif,B1,yesterday\n", "expected a datetime"),
    ("image_id,file,block\n,a.tif,B1\n", "row 1: column 'image_id': required value is empty"),
    ("", "empty table"),
])
def test_bad_tables_name_file_row_and_column(make_delivery, images, message):
    d = open_delivery(make_delivery(images=images))
    with pytest.raises(DeliveryError) as err:
        d.table("images")
    assert "tables/images.csv" in str(err.value)
    assert message in str(err.value)


def test_missing_column_message_lists_expected_columns(make_delivery):
    d = open_delivery(make_delivery(images="image_id,file\nI1,a.tif\n"))
    with pytest.raises(DeliveryError, match="Expected columns for table 'images': required image_id, file, block"):
        d.table("images")


@pytest.mark.parametrize("manifest, message", [
    ("orthospec_delivery: 1\nid: x\n", "project: Field required"),
    ("orthospec_delivery: 2\n", "orthospec_delivery"),
    ("- a list\n", "must be a YAML mapping"),
    ("id: [unclosed\n", "invalid YAML"),
])
def test_bad_manifest(make_delivery, manifest, message):
    root = make_delivery(manifest=manifest)
    with pytest.raises(DeliveryError, match=message.replace("(", r"\(")):
        open_delivery(root)


def test_manifest_error_has_line_numbers(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(manifest=MANIFEST.replace("sensor: {type: aerial", "sensor: {type: balloon"))
    with pytest.raises(DeliveryError, match=r"delivery.yaml:6:\d+: sensor.type"):
        open_delivery(root)


def test_unknown_table_and_missing_file(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(manifest=MANIFEST.replace("images: tables/images.csv", "pictures: tables/images.csv"))
    with pytest.raises(DeliveryError, match="unknown table 'pictures'; known tables:"):
        open_delivery(root)
    root2 = make_delivery("d2", images=None)
    with pytest.raises(DeliveryError, match="table 'images' file not found: tables/images.csv"):
        open_delivery(root2).table("images")


def test_paths_cannot_escape_the_delivery(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(manifest=MANIFEST.replace("tables/images.csv", "../../etc/passwd"))
    with pytest.raises(DeliveryError, match=r"delivery.yaml:10: tables.images '../../etc/passwd' contains '..'"):
        open_delivery(root)


def test_not_a_delivery(tmp_path):
    with pytest.raises(DeliveryError, match="no delivery.yaml"):
        open_delivery(tmp_path)
    with pytest.raises(DeliveryError, match="not found"):
        open_delivery(tmp_path / "nope")


def test_reading_never_modifies_the_delivery(make_delivery):
    root = make_delivery()
    before = {p: sha256_file(p) for p in root.rglob("*") if p.is_file()}
    d = open_delivery(root)
    d.load_all_tables()
    _ = d.files
    after = {p: sha256_file(p) for p in root.rglob("*") if p.is_file()}
    assert before == after
    assert IMAGES  # fixture text used above


def test_misspelt_manifest_key_gets_a_suggestion(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(manifest=MANIFEST.replace("contractor:", "contracter:"))
    with pytest.raises(DeliveryError, match="did you mean 'contractor'"):
        open_delivery(root)
