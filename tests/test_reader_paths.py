"""Paths in a table's ``file`` column are vetted in bulk when they are plain relative paths
(issue 14: a national images table has tens of thousands); every other one still goes through
delivery.reader.contained, and the first refused one is named by its row."""

from __future__ import annotations

import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.conftest import MANIFEST

from orthospec.delivery import paths, reader
from orthospec.errors import DeliveryError


@settings(max_examples=3000, deadline=None)
@given(st.text(alphabet="ab_.-/\\: \x00\u00e9C", max_size=12))
def test_every_plain_path_is_one_contained_accepts(path):
    if re.fullmatch(paths._PLAIN_PATH, path):
        assert paths._lexical(path)[0] is not None, path


@pytest.mark.parametrize(
    "path", ["images/a.tif", "a_b-c.d/e.tif", "_x/1.tif", "tiles/2026/b01/t.tif"]
)
def test_plain_paths_match(path):
    assert re.fullmatch(paths._PLAIN_PATH, path)


@pytest.mark.parametrize(
    "path",
    [
        "../x.tif",
        "./x.tif",
        "/etc/passwd",
        "C:x.tif",
        "a//b.tif",
        "a/../b",
        "/vsicurl/http://h/x.tif",
        "a\\b.tif",
        "é.tif",
        "",
    ],
)
def test_other_paths_are_checked_one_by_one(path):
    assert not re.fullmatch(paths._PLAIN_PATH, path)


def test_first_refused_path_among_many_plain_ones_is_named_by_row(make_delivery):
    rows = "".join(f"I{i},images/i{i}.tif,B1,0.5,1000,30\n" for i in range(1, 2000))
    text = (
        "image_id,file,block,roll,flying_height,std_dn\n"
        + rows
        + "I9999,../outside.tif,B1,0.5,1,1\n"
        + "I10000,/etc/passwd,B1,0.5,1,1\n"
    )
    d = reader.open_delivery(
        make_delivery("paths", manifest=MANIFEST, extra={"tables/images.csv": text})
    )
    with pytest.raises(
        DeliveryError,
        match=r"tables/images.csv: row 2000: column 'file': path '../outside.tif' "
        r"contains '..'",
    ):
        d.table("images")
