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


@pytest.mark.parametrize(
    "images, message",
    [
        ("image_id,file\nI1,a.tif\n", "missing required column(s) block"),
        ("image_id,file,block,colour\nI1,a.tif,B1,red\n", "unexpected column(s) colour"),
        (
            "image_id,file,block,roll\nI1,a.tif,B1,abc\n",
            "row 1: column 'roll': expected a number, got 'abc'",
        ),
        (
            "image_id,file,block,roll\nI1,a.tif,B1,1\nI2,b.tif,B1,NaN\n",
            "row 2: column 'roll': expected a finite",
        ),
        ("image_id,file,block,roll\nI1,a.tif,B1,inf\n", "expected a finite number"),
        ("image_id,file,block\nI1,a.tif,B1\nI1,b.tif,B1\n", "duplicate id 'I1' in rows 1, 2"),
        ("image_id,file,block\nI1,a.tif\n", "row 1: has 2 fields, the header has 3"),
        ("image_id,file,block,exposure_time\nI1,a.tif,B1,yesterday\n", "expected a datetime"),
        ("image_id,file,block\n,a.tif,B1\n", "row 1: column 'image_id': required value is empty"),
        ("", "empty table"),
    ],
)
def test_bad_tables_name_file_row_and_column(make_delivery, images, message):
    d = open_delivery(make_delivery(images=images))
    with pytest.raises(DeliveryError) as err:
        d.table("images")
    assert "tables/images.csv" in str(err.value)
    assert message in str(err.value)


def test_missing_column_message_lists_expected_columns(make_delivery):
    d = open_delivery(make_delivery(images="image_id,file\nI1,a.tif\n"))
    with pytest.raises(
        DeliveryError, match="Expected columns for table 'images': required image_id, file, block"
    ):
        d.table("images")


@pytest.mark.parametrize(
    "manifest, message",
    [
        ("orthospec_delivery: 1\nid: x\n", "project: Field required"),
        ("orthospec_delivery: 2\n", "orthospec_delivery"),
        ("- a list\n", "must be a YAML mapping"),
        ("id: [unclosed\n", "invalid YAML"),
    ],
)
def test_bad_manifest(make_delivery, manifest, message):
    root = make_delivery(manifest=manifest)
    with pytest.raises(DeliveryError, match=message.replace("(", r"\(")):
        open_delivery(root)


def test_manifest_error_has_line_numbers(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(
        manifest=MANIFEST.replace("sensor: {type: aerial", "sensor: {type: balloon")
    )
    with pytest.raises(DeliveryError, match=r"delivery.yaml:6:\d+: sensor.type"):
        open_delivery(root)


def test_unknown_table_and_missing_file(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(
        manifest=MANIFEST.replace("images: tables/images.csv", "pictures: tables/images.csv")
    )
    with pytest.raises(DeliveryError, match="unknown table 'pictures'; known tables:"):
        open_delivery(root)
    root2 = make_delivery("d2", images=None)
    with pytest.raises(DeliveryError, match="table 'images' file not found: tables/images.csv"):
        open_delivery(root2).table("images")


def test_paths_cannot_escape_the_delivery(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(manifest=MANIFEST.replace("tables/images.csv", "../../etc/passwd"))
    with pytest.raises(
        DeliveryError, match=r"delivery.yaml:10: tables.images '../../etc/passwd' contains '..'"
    ):
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


# --------------------------------------------------------------------------- containment (issue 17)


@pytest.mark.parametrize(
    "rel, why",
    [
        ("/etc/passwd", "absolute path"),
        ("images/../../x.tif", "contains '..'"),
        ("/vsicurl/http://example.com/x.tif", "GDAL virtual file system"),
        ("http://example.com/x.tif", "URL"),
        ("C:\\data\\x.tif", "URL or a drive-letter"),
        ("images/a\x07.tif", "control characters"),
        ("", "is empty"),
    ],
)
def test_contained_refuses_paths_that_leave_the_delivery(tmp_path, rel, why):
    from orthospec.delivery.reader import contained

    with pytest.raises(
        DeliveryError, match=r"tables/images.csv: row 4: column 'file': path .*" + why
    ):
        contained(tmp_path, rel, what="path", file="tables/images.csv", row=4, field="file")


def test_contained_follows_links_but_only_inside(tmp_path):
    import os

    from orthospec.delivery.reader import contained

    root = tmp_path / "d"
    (root / "images").mkdir(parents=True)
    (root / "images" / "a.tif").write_bytes(b"II*\x00")
    (root / "images" / "alias.tif").symlink_to("a.tif")
    (tmp_path / "outside.tif").write_bytes(b"secret")
    (root / "images" / "out.tif").symlink_to(tmp_path / "outside.tif")
    (root / "linked").symlink_to(tmp_path)
    os.mkfifo(root / "images" / "pipe.tif")
    assert contained(root, "images/alias.tif") == root / "images" / "alias.tif"
    assert contained(root, "images\\a.tif") == root / "images" / "a.tif"  # Windows separators
    assert (
        contained(root, "images/missing.tif") == root / "images" / "missing.tif"
    )  # reported later
    for rel, why in [
        ("images/out.tif", "symbolic link leading out"),
        ("linked/outside.tif", "out of"),
        ("images/pipe.tif", "FIFO"),
    ]:
        with pytest.raises(DeliveryError, match=why):
            contained(root, rel)


def test_check_tree_refuses_outward_links_and_fifos(tmp_path):
    import os

    from orthospec.delivery.reader import check_tree

    root = tmp_path / "d"
    (root / "docs").mkdir(parents=True)
    (root / "docs" / "a.md").write_text("a")
    (root / "docs" / "b.md").symlink_to("a.md")
    assert check_tree(root) == ["docs/a.md"]
    (root / "docs" / "c.md").symlink_to("/etc/hostname")
    with pytest.raises(DeliveryError, match=r"^docs/c.md: is a symbolic link leading out"):
        check_tree(root)
    (root / "docs" / "c.md").unlink()
    os.mkfifo(root / "docs" / "p")
    with pytest.raises(DeliveryError, match=r"^docs/p: is a FIFO"):
        check_tree(root)


def test_open_delivery_refuses_a_document_linked_outside(make_delivery, tmp_path):
    (tmp_path / "secret.txt").write_text("secret")
    root = make_delivery(manifest=MANIFEST_WITH_DOC)
    (root / "documents").mkdir()
    (root / "documents" / "qcr.md").symlink_to(tmp_path / "secret.txt")
    with pytest.raises(
        DeliveryError,
        match=r"delivery.yaml:\d+: documents.internal_qcr 'documents/qcr.md' "
        r"is \(or passes through\) a symbolic link",
    ):
        open_delivery(root)


def test_file_column_outside_is_refused_with_row(make_delivery):
    images = "image_id,file,block\nI1,images/a.tif,B1\nI2,/vsicurl/http://x/y.tif,B1\n"
    d = open_delivery(make_delivery(images=images))
    with pytest.raises(
        DeliveryError,
        match=r"tables/images.csv: row 2: column 'file': path "
        r"'/vsicurl/http://x/y.tif' is a GDAL virtual",
    ):
        d.load_all_tables()


MANIFEST_WITH_DOC = None  # set below from conftest's manifest


def _manifest_with_doc() -> str:
    from tests.conftest import MANIFEST

    return MANIFEST + "documents: {internal_qcr: documents/qcr.md}\n"


MANIFEST_WITH_DOC = _manifest_with_doc()


# --------------------------------------------------------------------------- bounded tables


@pytest.mark.parametrize(
    "text, limits, message",
    [
        (
            b"a,b\n1," + b"x" * 200 + b"\n",
            {"cell_bytes": 100},
            "row 1: a cell longer than 100 bytes",
        ),
        (
            b"a,b\n1,2\n3," + b"x" * 50 + b"," * 30 + b"\n",
            {"columns": 20},
            r"row 2: \d+\+ fields on one line exceed the limit of 20",
        ),
        (
            b"a," + b",".join(b"c%d" % i for i in range(30)) + b"\n",
            {"columns": 20},
            r"tables/t.csv:1: \d+\+ fields",
        ),
        (b'"image\nid",file\n1,2\n', {}, "tables/t.csv:1: the header row has an unclosed quote"),
    ],
)
def test_csv_bounds_before_parsing(text, limits, message):
    import io

    from orthospec.delivery.reader import Limits, check_csv_bounds

    with pytest.raises(DeliveryError, match=message):
        check_csv_bounds(io.BytesIO(text), file="tables/t.csv", limits=Limits(**limits), chunk=7)


def test_csv_bounds_accept_a_normal_table_across_chunks():
    import io

    from orthospec.delivery.reader import Limits, check_csv_bounds

    text = IMAGES.encode() * 50
    check_csv_bounds(
        io.BytesIO(text), file="t.csv", limits=Limits(cell_bytes=40, columns=6), chunk=5
    )


def test_table_size_limit_from_the_environment(make_delivery, monkeypatch):
    monkeypatch.setenv("ORTHOSPEC_MAX_TABLE_BYTES", "50")
    d = open_delivery(make_delivery())
    with pytest.raises(
        DeliveryError, match=r"tables/images.csv: table of \d+ bytes exceeds the limit of 50"
    ):
        d.table("images")


def test_a_128_kib_cell_is_just_text(make_delivery):
    images = "image_id,file,block,tags\nI1,a.tif,B1," + "c" * 2**17 + "\n"
    d = open_delivery(make_delivery(images=images))
    assert len(d.table("images").df["tags"][0]) == 2**17


def test_manifest_impossible_date_names_line(make_delivery):
    from tests.conftest import MANIFEST

    root = make_delivery(manifest=MANIFEST + "dates: {delivered: 2026-02-30}\n")
    with pytest.raises(
        DeliveryError, match=r"delivery.yaml:\d+:\d+: invalid value '2026-02-30': day is out"
    ):
        open_delivery(root)


def test_manifest_alias_bomb_is_refused_fast(make_delivery):
    import time

    from tests.conftest import MANIFEST

    bomb = "bomb:\n  l0: &l0 [lol]\n" + "".join(
        f"  l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]\n" for i in range(1, 10)
    )
    root = make_delivery(manifest=MANIFEST + bomb)
    t0 = time.perf_counter()
    with pytest.raises(
        DeliveryError, match=r"aliases \(\*name\) expand the document to [\d,]+ nodes"
    ):
        open_delivery(root)
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize(
    "text, message",
    [
        ("a: &a [*a]\n", "f.yaml:1:4: a recursive alias"),
        ("x: " + "[" * 250 + "]" * 250 + "\n", "nested more than 200 levels"),
        ("k: 1" + "0" * 5000 + "\n", "f.yaml:1:4: invalid value"),
        ("a: 1\nb: [1, 2\n", "f.yaml:3:1: invalid YAML"),
    ],
)
def test_yaml_limits_and_positions(text, message):
    from orthospec.yamlio import YamlError, load_text

    with pytest.raises(YamlError, match=message):
        load_text(text, "f.yaml")


def test_yaml_file_size_limit(tmp_path):
    from orthospec.yamlio import YamlError, YamlLimits, load_file

    f = tmp_path / "p.yaml"
    f.write_text("notes: '" + "a" * 1000 + "'\n")
    with pytest.raises(YamlError, match=r"p.yaml: 1,010 bytes exceed the limit of 100"):
        load_file(f, display="p.yaml", limits=YamlLimits(bytes=100))


def test_cr_only_and_crlf_tables_read_like_lf(make_delivery):
    """Old Mac (CR) and Windows (CRLF) line ends: the same rows, and the bounds count lines once."""
    import io

    from orthospec.delivery.reader import Limits, check_csv_bounds

    for sep in ("\r", "\r\n"):
        d = open_delivery(make_delivery(f"d{len(sep)}", images=IMAGES.replace("\n", sep)))
        assert d.table("images").df["roll"].tolist() == [0.5, 2.5, 4.0]
    wide = ("a,b\r\n1,2\r\n3," + "," * 30 + "\r\n").encode()
    with pytest.raises(DeliveryError, match=r"row 2: \d+\+ fields"):
        check_csv_bounds(io.BytesIO(wide), file="t.csv", limits=Limits(columns=20), chunk=4)


def test_yaml_error_carries_file_line_column_and_deep_flow_is_refused_fast():
    import time

    from orthospec.yamlio import YamlError, load_text

    with pytest.raises(YamlError) as info:
        load_text("a: 1\nb: [1, 2\n", "dir/p.yaml")
    assert (info.value.file, info.value.line, info.value.column) == ("dir/p.yaml", 3, 1)
    t0 = time.perf_counter()
    with pytest.raises(YamlError, match="p.yaml:1: nested more than 200 levels deep"):
        load_text("x: " + "[" * 20000 + "]" * 20000, "p.yaml")
    assert time.perf_counter() - t0 < 1.0
