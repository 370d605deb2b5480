"""init --from end to end: the tiles-real example drafted and checked as it is, the draft the same
bytes on every run, nothing written into the source, every `missing` record naming its TODO line,
and the hostile inputs of issue 27 (each a line in INGEST.md or exit 2 naming the file)."""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from orthospec.qcr import all_records

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "deliveries" / "tiles-real"
CHECKER = ROOT / "examples" / "checker" / "tiles-real.yaml"


def run(*args: object) -> object:
    """The installed command, as a user runs it (exit codes and messages of cli/main.py)."""
    exe = Path(sys.executable).with_name("orthospec")
    r = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)
    return SimpleNamespace(exit_code=r.returncode, output=r.stdout + r.stderr)


def _snapshot(root: Path) -> dict[str, tuple[int, int, str]]:
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for n in filenames + dirnames:
            p = Path(dirpath) / n
            st = p.lstat()
            digest = (
                hashlib.sha256(p.read_bytes()).hexdigest()
                if p.is_file() and not p.is_symlink()
                else ""
            )
            out[p.relative_to(root).as_posix()] = (st.st_mtime_ns, st.st_size, digest)
    return out


def _tree(root: Path) -> dict[str, str]:
    """Every entry of a draft: file bytes' SHA-256, or a link's target."""
    out = {}
    for dirpath, _dirs, files in os.walk(root):
        for n in files:
            p = Path(dirpath) / n
            rel = p.relative_to(root).as_posix()
            out[rel] = (
                "-> " + os.readlink(p)
                if p.is_symlink()
                else hashlib.sha256(p.read_bytes()).hexdigest()
            )
    return out


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, object], int]:
    """The README's two commands: init --from the example, check the draft with the checker's file."""
    base = tmp_path_factory.mktemp("tiles")
    before = _snapshot(EXAMPLE)
    res = run("init", base / "draft", "--from", EXAMPLE)
    assert res.exit_code == 0, res.output  # type: ignore[attr-defined]
    res = run(
        "check",
        base / "draft",
        "--profile",
        "jrc-v3",
        "--checker",
        CHECKER,
        "--out",
        base / "report",
        "--date",
        "2026-05-20",
    )
    assert _snapshot(EXAMPLE) == before, "init or check wrote into the source"
    doc = json.loads((base / "report" / "qcr.json").read_text(encoding="utf-8"))
    return base / "draft", doc, res.exit_code  # type: ignore[attr-defined]


def test_the_draft_is_checked_as_it_is(checked: tuple[Path, dict[str, object], int]) -> None:
    """Zero lines written by hand between the two commands (the checker's file aside)."""
    draft, doc, code = checked
    assert (
        code == 1 and doc["verdict"] == "rejected"
    )  # as examples/deliveries/tiles-real/README.md says
    assert "**REJECTED** (exit 1)" in (EXAMPLE / "README.md").read_text(encoding="utf-8")
    m = (draft / "delivery.yaml").read_text(encoding="utf-8")
    assert (
        "type: satellite" in m
        and "LE07_L3_iso19139.xml" in m
        and "id: DE-L3-ORTHO-LS7-2026-01" in m
    )
    images = (draft / "tables" / "images.csv").read_text(encoding="utf-8").splitlines()
    assert len(images) == 17 and images[1].startswith(
        "LE07_L3_R1_C1,source/tiles/LE07_L3_R1_C1.tif,B1,"
    )


#: rules whose value the delivered pixels themselves cannot give in the example (nodata 0 hides DN 0): nothing
#: a user can fill, so their records name the "anything else" line and say why
PIXELS_CANNOT_TELL = {"JRC-6.3-SATURATION-LOW"}


def test_every_missing_record_names_its_todo_line(
    checked: tuple[Path, dict[str, object], int],
) -> None:
    draft, doc, _ = checked
    todo = (draft / "TODO.md").read_text(encoding="utf-8").splitlines()
    missing = [r for r in all_records(doc) if r["verdict"] == "missing"]
    assert len(missing) > 100
    other = next(i + 1 for i, t in enumerate(todo) if "anything else a record reports" in t)
    for r in missing:
        m = re.search(r"see TODO\.md line (\d+): ", r["message"] or "")
        assert m, (r["rule"], r["message"])
        line = int(m.group(1))
        if line == other:  # the catch-all: only a value the pixels themselves cannot give, said why
            assert r["rule"] in PIXELS_CANNOT_TELL, (r["rule"], r["message"])
            continue
        entry = todo[line - 1]
        assert entry.startswith("- [ ] ")
        listed = todo[line] if line < len(todo) else ""
        assert r["rule"] in listed, (r["rule"], entry)


def test_a_present_rule_failing_on_an_empty_field_names_it_too(
    checked: tuple[Path, dict[str, object], int],
) -> None:
    _, doc, _ = checked
    date = [r for r in all_records(doc) if r["rule"] == "JRC-2.4-QCR-DATE"]
    assert date and date[0]["verdict"] == "fail" and "TODO.md line" in date[0]["message"]


def test_the_draft_is_byte_identical_across_runs(tmp_path: Path) -> None:
    a, b = tmp_path / "a" / "draft", tmp_path / "b" / "draft"
    for d in (a, b):
        assert run("init", d, "--from", EXAMPLE).exit_code == 0  # type: ignore[attr-defined]
    ta, tb = _tree(a), _tree(b)
    assert ta == tb
    assert {
        "delivery.yaml",
        "TODO.md",
        "INGEST.md",
        "tables/images.csv",
        "tables/checkpoints.csv",
        "tables/gcps.csv",
        "ingest/rasters.csv",
        "ingest/evidence.csv",
        "ingest/points-mapping.yaml",
        "ingest/todo-rules.json",
    } <= set(ta)


def test_the_saved_mapping_reads_the_survey_again_without_questions(tmp_path: Path) -> None:
    first = tmp_path / "first"
    assert run("init", first, "--from", EXAMPLE).exit_code == 0  # type: ignore[attr-defined]
    second = tmp_path / "second"
    res = run(
        "init", second, "--from", EXAMPLE, "--mapping", first / "ingest" / "points-mapping.yaml"
    )
    assert res.exit_code == 0, res.output  # type: ignore[attr-defined]
    assert "layout from the mapping given" in (second / "INGEST.md").read_text(encoding="utf-8")
    assert (second / "tables/checkpoints.csv").read_bytes() == (
        first / "tables/checkpoints.csv"
    ).read_bytes()


# --------------------------------------------------------------------------- hostile input
@pytest.fixture()
def source(tmp_path: Path) -> Path:
    src = tmp_path / "disk"
    shutil.copytree(EXAMPLE, src)
    return src


def _fake_gdalinfo_free_corrupt(src: Path) -> None:
    tiles = src / "tiles"
    good = (tiles / "LE07_L3_R1_C1.tif").read_bytes()
    (tiles / "TRUNCATED.tif").write_bytes(good[: len(good) // 3])
    (tiles / "GARBAGE.tif").write_bytes(b"II*\x00" + os.urandom(300))
    (tiles / "EMPTY.tif").write_bytes(b"")
    import numpy as np
    import rasterio

    with rasterio.open(
        tiles / "NOGEO.tif", "w", driver="GTiff", width=8, height=8, count=1, dtype="uint8"
    ) as ds:
        ds.write(np.ones((1, 8, 8), dtype="uint8"))


def test_bad_rasters_are_listed_and_judged_never_fatal(source: Path, tmp_path: Path) -> None:
    _fake_gdalinfo_free_corrupt(source)
    draft = tmp_path / "draft"
    res = run("init", draft, "--from", source)
    assert res.exit_code == 0, res.output  # type: ignore[attr-defined]
    report = (draft / "INGEST.md").read_text(encoding="utf-8")
    for name in ("TRUNCATED", "GARBAGE", "EMPTY"):
        assert re.search(rf"not readable: `source/tiles/{name}\.tif`: .+", report), name
    assert "`source/tiles/NOGEO.tif`: no georeference" in report
    images = (draft / "tables/images.csv").read_text(encoding="utf-8")
    for name in ("TRUNCATED", "GARBAGE", "EMPTY", "NOGEO"):  # listed, so the check judges them
        assert f"source/tiles/{name}.tif" in images
    out = tmp_path / "report"
    res = run(
        "check",
        draft,
        "--profile",
        "jrc-v3",
        "--param",
        "tolerance_xy=450",
        "--param",
        "map_crs=EPSG:32618",
        "--out",
        out,
        "--format",
        "json",
    )
    assert res.exit_code == 1, res.output  # type: ignore[attr-defined]
    doc = json.loads((out / "qcr.json").read_text(encoding="utf-8"))
    readable = {
        r["item"]: r["verdict"] for r in all_records(doc) if r["rule"] == "JRC-9.2-T7-READABLE"
    }
    assert readable["GARBAGE"] == readable["TRUNCATED"] == readable["EMPTY"] == "fail"
    assert readable["LE07_L3_R1_C1"] == "pass"


def test_symlinks_out_of_the_source_and_fifos_are_not_read(source: Path, tmp_path: Path) -> None:
    secret = tmp_path / "secret.tif"
    shutil.copy(source / "tiles" / "LE07_L3_R1_C1.tif", secret)
    os.symlink(secret, source / "tiles" / "OUTSIDE.tif")
    os.symlink(tmp_path, source / "escape")
    os.mkfifo(source / "tiles" / "PIPE.tif")
    draft = tmp_path / "draft"
    res = run("init", draft, "--from", source)
    assert res.exit_code == 0, res.output  # type: ignore[attr-defined]
    report = (draft / "INGEST.md").read_text(encoding="utf-8")
    assert (
        "`source/tiles/OUTSIDE.tif`: symbolic link leading out of the source folder: not read"
        in report
    )
    assert "`source/escape`: symbolic link leading out of the source folder" in report
    assert "`source/tiles/PIPE.tif`: is a FIFO (named pipe): not read" in report
    assert not (draft / "source" / "tiles" / "OUTSIDE.tif").exists()
    assert "OUTSIDE" not in (draft / "tables/images.csv").read_text(encoding="utf-8")


def test_a_source_that_is_a_file_or_holds_the_draft_is_refused(
    source: Path, tmp_path: Path
) -> None:
    res = run("init", tmp_path / "d", "--from", source / "tiles" / "LE07_L3_R1_C1.tif")
    assert res.exit_code == 2 and "is a file, not a folder" in res.output  # type: ignore[attr-defined]
    res = run("init", source / "draft", "--from", source)
    assert res.exit_code == 2 and "would lie inside the source" in res.output  # type: ignore[attr-defined]
    assert not (source / "draft").exists()
    res = run("init", tmp_path / "d", "--from", tmp_path / "nowhere")
    assert res.exit_code == 2 and "not found" in res.output  # type: ignore[attr-defined]
    assert "Traceback" not in res.output  # type: ignore[attr-defined]


def test_an_undecidable_survey_stops_with_its_columns_and_leaves_nothing(
    source: Path, tmp_path: Path
) -> None:
    (source / "survey" / "messung.csv").write_text(
        "Nr;E;N\nA;150000,5;2700000,5\nB;160000,5;2710000,5\n", encoding="utf-8"
    )
    res = run("init", tmp_path / "d", "--from", source)
    out = res.output  # type: ignore[attr-defined]
    assert (
        res.exit_code == 2
        and "source/survey/messung.csv" in out
        and "orthospec_points_mapping: 1" in out
    )  # type: ignore[attr-defined]
    assert "Traceback" not in out and not (tmp_path / "d").exists()
    assert not [
        p for p in tmp_path.iterdir() if p.name.startswith(".d.")
    ]  # no temporary folder left
    # the user fills the proposal: roles for the ?, the table; the unit is asked, never defaulted
    mapping = out[out.index("orthospec_points_mapping: 1") :]
    assert "decimal: ','" in mapping and "unit: '?'" in mapping
    for role, col in (("point_id", "Nr"), ("x", "E"), ("y", "N")):
        mapping = mapping.replace(f"?: '{col}'", f"{role}: '{col}'")
    mapping = mapping.replace("table: checkpoints", "table: gcps")
    (source / "survey" / "Passpunkte.csv").unlink()  # one GCP file per draft
    (tmp_path / "m.yaml").write_text(mapping, encoding="utf-8")
    res = run("init", tmp_path / "d", "--from", source, "--mapping", tmp_path / "m.yaml")
    assert res.exit_code == 2 and "the mapping's unit '?' is not m, ft or usft" in res.output  # type: ignore[attr-defined]
    (tmp_path / "m.yaml").write_text(mapping.replace("unit: '?'", "unit: m"), encoding="utf-8")
    res = run("init", tmp_path / "d", "--from", source, "--mapping", tmp_path / "m.yaml")
    assert res.exit_code == 0, res.output  # type: ignore[attr-defined]
    gcps = (tmp_path / "d" / "tables" / "gcps.csv").read_text(encoding="utf-8")
    assert gcps == "point_id,block,x,y\nA,B1,150000.5,2700000.5\nB,B1,160000.5,2710000.5\n"


def test_the_sensor_type_is_never_guessed(source: Path, tmp_path: Path) -> None:
    shutil.rmtree(source / "metadata")
    res = run("init", tmp_path / "d", "--from", source)
    assert res.exit_code == 2 and "--sensor" in res.output  # type: ignore[attr-defined]
    res = run("init", tmp_path / "d", "--from", source, "--sensor", "aerial", "--id", "D-1")
    assert res.exit_code == 0, res.output  # type: ignore[attr-defined]
    m = (tmp_path / "d" / "delivery.yaml").read_text(encoding="utf-8")
    assert "type: aerial  # --sensor" in m and "id: D-1  # --id" in m and "digital:" not in m


def test_without_outlines_blocks_stay_empty_and_the_points_wait(
    source: Path, tmp_path: Path
) -> None:
    (source / "index" / "blocks.geojson").unlink()
    draft = tmp_path / "d"
    assert run("init", draft, "--from", source).exit_code == 0  # type: ignore[attr-defined]
    m = (draft / "delivery.yaml").read_text(encoding="utf-8")
    assert "blocks:" not in m and "checkpoints:" not in m.split("tables:")[1].splitlines()[0]
    assert (draft / "ingest" / "checkpoints.csv").is_file()
    assert ",source/tiles/LE07_L3_R1_C1.tif,," in (draft / "tables/images.csv").read_text(
        encoding="utf-8"
    )
    todo = (draft / "TODO.md").read_text(encoding="utf-8")
    assert "- [ ] blocks (" in todo and "table `checkpoints`" in todo
    res = run(
        "check",
        draft,
        "--profile",
        "jrc-v3",
        "--param",
        "tolerance_xy=450",
        "--param",
        "map_crs=EPSG:32618",
        "--out",
        tmp_path / "r",
        "--format",
        "json",
    )
    assert res.exit_code == 1, res.output  # type: ignore[attr-defined]


# --------------------------------------------------------------------------- containment at check time
@pytest.fixture()
def draft(source: Path, tmp_path: Path) -> Path:
    d = tmp_path / "draft"
    assert run("init", d, "--from", source).exit_code == 0  # type: ignore[attr-defined]
    return d


def _check(draft: Path, tmp_path: Path) -> object:
    return run(
        "check",
        draft,
        "--profile",
        "jrc-v3",
        "--param",
        "tolerance_xy=450",
        "--param",
        "map_crs=EPSG:32618",
        "--out",
        tmp_path / "r",
        "--format",
        "json",
    )


def test_a_link_repointed_out_of_the_source_is_refused(draft: Path, tmp_path: Path) -> None:
    outside = tmp_path / "elsewhere.tif"
    outside.write_bytes(b"secret")
    link = draft / "source" / "tiles" / "LE07_L3_R1_C1.tif"
    link.unlink()
    os.symlink(outside, link)
    res = _check(draft, tmp_path)
    assert res.exit_code == 2  # type: ignore[attr-defined]
    assert "source/tiles/LE07_L3_R1_C1.tif" in res.output and "leading out" in res.output  # type: ignore[attr-defined]


def test_a_link_outside_the_links_folder_is_refused(
    draft: Path, tmp_path: Path, source: Path
) -> None:
    os.symlink(source / "survey" / "Passpunkte.csv", draft / "tables" / "extra.csv")
    res = _check(draft, tmp_path)
    assert res.exit_code == 2 and "tables/extra.csv" in res.output  # type: ignore[attr-defined]


@pytest.mark.parametrize("new", ["/", ".", "source", "nowhere"])
def test_a_draft_source_that_is_no_separate_folder_is_refused(
    draft: Path, tmp_path: Path, new: str
) -> None:
    m = draft / "delivery.yaml"
    text = m.read_text(encoding="utf-8")
    m.write_text(re.sub(r"source: [^,}]+", f"source: {new}", text), encoding="utf-8")
    res = _check(draft, tmp_path)
    assert res.exit_code == 2 and "draft.source" in res.output, res.output  # type: ignore[attr-defined]


def test_a_damaged_todo_map_stops_the_check(draft: Path, tmp_path: Path) -> None:
    (draft / "ingest" / "todo-rules.json").write_text("{not json", encoding="utf-8")
    res = _check(draft, tmp_path)
    assert res.exit_code == 2 and "todo-rules.json" in res.output  # type: ignore[attr-defined]


def test_mixed_crss_pixel_sizes_and_overlapping_tiles_are_reported(
    source: Path, tmp_path: Path
) -> None:
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin

    tiles = source / "tiles"
    with rasterio.open(tiles / "LE07_L3_R1_C1.tif") as ds:
        left, top = ds.bounds.left, ds.bounds.top
    profile = {"driver": "GTiff", "width": 16, "height": 16, "count": 1, "dtype": "uint8"}
    # 150 m pixels over the corner of R1_C1: another pixel size, overlapping a tile
    with rasterio.open(
        tiles / "EXTRA_150.tif",
        "w",
        crs="EPSG:32618",
        transform=from_origin(left + 600, top - 600, 150, 150),
        **profile,
    ) as ds:
        ds.write(np.ones((1, 16, 16), dtype="uint8"))
    with rasterio.open(
        tiles / "EXTRA_19N.tif",
        "w",
        crs="EPSG:32619",
        transform=from_origin(200000, 2700000, 300, 300),
        **profile,
    ) as ds:
        ds.write(np.ones((1, 16, 16), dtype="uint8"))
    draft = tmp_path / "draft"
    res = run("init", draft, "--from", source, "--workers", 1)
    # the GCP file states no unit: with one CRS it is the CRS's; with two, it is asked for
    assert res.exit_code == 2 and "source/survey/Passpunkte.csv: no unit stated" in res.output  # type: ignore[attr-defined]
    assert "the images do not share one CRS" in res.output and "unit: '?'" in res.output  # type: ignore[attr-defined]
    (source / "survey" / "Passpunkte.csv").unlink()
    res = run("init", draft, "--from", source, "--workers", 1)
    assert res.exit_code == 0, res.output  # type: ignore[attr-defined]
    report = (draft / "INGEST.md").read_text(encoding="utf-8")
    assert "- **Mixed CRSs**: EPSG:32618 (17 images), EPSG:32619 (1 images)" in report
    # the Landsat tiles' pixels are not square (gdalinfo: 300.037926675 x -300.04178273)
    assert (
        "- **Mixed pixel sizes**: 150 x 150 metre (1 images), 300 x 300 metre (1 images), "
        "300.037926675 x 300.04178273 metre (16 images)"
    ) in report
    assert "footprints compared in EPSG:32618, the CRS most images use" in report
    # 16 x 150 m = 2400 m square from 600 m inside R1_C1 (38 400 m wide): 2400 x 2400 m over R1_C1 only
    assert (
        "- **Overlapping images**: 1 pairs, e.g. `source/tiles/EXTRA_150.tif` / "
        "`source/tiles/LE07_L3_R1_C1.tif` (5760000 sq. units)"
    ) in report
    images = (draft / "tables/images.csv").read_text(encoding="utf-8")
    assert (
        "EXTRA_150,source/tiles/EXTRA_150.tif,B1,150,,PAN\n" in images
    )  # no NBITS tag: bit depth not stated
    # x = 200 km in zone 19N is x ~ 809 km in zone 18N, east of the outlines: in no block
    # (compared as raw numbers it would fall in B1)
    assert "EXTRA_19N,source/tiles/EXTRA_19N.tif,,300,,PAN\n" in images
