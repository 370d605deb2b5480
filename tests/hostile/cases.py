"""The hostile corpus of issue 17 (containment, read-only, bounds, outputs, messages).

Each case builds its input from a small copy of ``examples/deliveries/aerial-pass`` inside a
world folder and says what the run must do:

``exit2``   the run is refused: exit 2 and a message naming the file (``names``);
``record``  the run goes on and the offending item gets an ``error`` record naming it (or the
            whole run is refused with exit 2 naming it);
``clean``   any verdict (0, 1) or a refusal (2), but nothing else is allowed (the tree checks).

Every case is also checked by the test for: no traceback, no "internal error", the delivery
tree unchanged, no marker (content or SHA-256) in any output, and the time/memory budget.
"""

from __future__ import annotations

import os
import sqlite3
import textwrap
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .harness import copy_example

MARKER_TEXT = "ORTHOSPEC-HOSTILE-MARKER-7f3a9c1e"
PROFILE = "jrc-v3"
MINI_PROFILE = Path(__file__).resolve().parents[1] / "data" / "profiles" / "mini.yaml"
MINI = str(MINI_PROFILE)


@dataclass
class World:
    """Folders of one case: ``work`` (the cwd), ``work/delivery``, ``outside`` (markers), ``out``."""

    base: Path
    work: Path = field(init=False)
    delivery: Path = field(init=False)
    outside: Path = field(init=False)
    out: Path = field(init=False)

    def __post_init__(self) -> None:
        self.work = self.base / "work"
        self.outside = self.base / "outside"
        self.out = self.base / "out"
        self.work.mkdir(parents=True)
        self.outside.mkdir()
        self.delivery = copy_example(self.work / "delivery")
        (self.outside / "marker.txt").write_text(MARKER_TEXT + "\n", encoding="utf-8")
        # a real GeoTIFF outside the delivery: an example image that is not in the small copy
        src = (
            Path(__file__).resolve().parents[2]
            / "examples/deliveries/aerial-pass/images/F03_0105.tif"
        )
        (self.outside / "marker.tif").write_bytes(src.read_bytes())

    def markers(self) -> list[Path]:
        return sorted(p for p in self.outside.iterdir() if p.is_file() and p.stat().st_size < 2**26)

    def args(self, *extra: str, out: bool = True, profile: str = PROFILE) -> list[str]:
        # the checker states the ITT tolerance (the manifest's declared value is evidence only)
        a = [
            "check",
            str(self.delivery),
            "--profile",
            profile,
            "--date",
            "2026-07-01",
            "--param",
            "tolerance_xy=0.5m",
            *(["--param", "map_crs=EPSG:25832"] if profile == PROFILE else []),
        ]
        if out:
            a += ["--out", str(self.out)]
        return a + list(extra)

    def edit(self, rel: str, fn: Callable[[str], str]) -> None:
        p = self.delivery / rel
        p.write_text(fn(p.read_text(encoding="utf-8")), encoding="utf-8")

    def set_image_file(self, value: str, row: int = 1) -> None:
        """Put ``value`` in the ``file`` column of images.csv data row ``row``."""

        def fn(text: str) -> str:
            lines = text.splitlines(keepends=True)
            cells = lines[row].split(",")
            cells[1] = value
            lines[row] = ",".join(cells)
            return "".join(lines)

        self.edit("tables/images.csv", fn)

    def first_image(self) -> Path:
        return self.delivery / "images" / "F01_0101.tif"


@dataclass
class Setup:
    args: list[str]
    expect: str  # exit2 | record | clean
    names: tuple[str, ...] = ()  # text the message (or error record) must contain
    cwd: Path | None = None
    extra_outputs: tuple[Path, ...] = ()  # more folders whose files must not leak markers
    check: Callable[[World], None] | None = None
    #: Budgets: far below what the unbounded code took (hangs past 60-300 s, 3-12 GB) and far above a
    #: quiet run (1.5-4 s, 100-260 MB), so a loaded CI machine (2 cores, other jobs) still passes.
    seconds: float = 20.0
    peak_mb: float = 600.0


CASES: dict[str, Callable[[World], Setup]] = {}


def _write_repeated(fh: Any, char: str, n: int, block: int = 2**22) -> None:
    """Write ``char * n`` in blocks (the test process never holds a huge string)."""
    chunk = char * block
    for _ in range(n // block):
        fh.write(chunk)
    fh.write(char * (n % block))


def case(fn: Callable[[World], Setup]) -> Callable[[World], Setup]:
    CASES[fn.__name__] = fn
    return fn


# ------------------------------------------------------------------- containment (reads)


@case
def image_symlink_outside(w: World) -> Setup:
    w.first_image().unlink()
    w.first_image().symlink_to(w.outside / "marker.tif")
    return Setup(w.args(), "exit2", ("images/F01_0101.tif",))


@case
def images_dir_symlink_outside(w: World) -> Setup:
    os.rename(w.delivery / "images", w.outside / "images")
    (w.delivery / "images").symlink_to(w.outside / "images")
    return Setup(w.args(), "exit2", ("images",))


@case
def document_symlink_outside(w: World) -> Setup:
    doc = w.delivery / "documents" / "internal_qcr.md"
    doc.unlink()
    doc.symlink_to(w.outside / "marker.txt")
    return Setup(w.args(), "exit2", ("documents/internal_qcr.md",))


@case
def unlisted_symlink_to_etc(w: World) -> Setup:
    (w.delivery / "documents" / "extra.txt").symlink_to("/etc/hostname")
    return Setup(w.args(), "exit2", ("documents/extra.txt",))


@case
def table_symlink_to_sparse_3gib_outside(w: World) -> Setup:
    big = w.outside / "huge.csv"
    with open(big, "wb") as fh:
        fh.truncate(3 * 2**30)
    t = w.delivery / "tables" / "images.csv"
    t.unlink()
    t.symlink_to(big)
    return Setup(w.args(), "exit2", ("tables/images.csv",))


@case
def table_sparse_3gib_inside(w: World) -> Setup:
    t = w.delivery / "tables" / "images.csv"
    with open(t, "r+b") as fh:
        fh.truncate(3 * 2**30)
    return Setup(w.args(), "exit2", ("tables/images.csv",))


@case
def file_column_dotdot(w: World) -> Setup:
    w.set_image_file("images/../../../outside/marker.tif")
    return Setup(w.args(), "exit2", ("tables/images.csv", "row 1"))


@case
def file_column_absolute(w: World) -> Setup:
    w.set_image_file(str(w.outside / "marker.tif"))
    return Setup(w.args(), "exit2", ("tables/images.csv", "row 1"))


@case
def file_column_vsicurl(w: World) -> Setup:
    w.set_image_file("/vsicurl/http://127.0.0.1:9/x.tif")
    return Setup(w.args(), "exit2", ("tables/images.csv", "row 1"))


@case
def file_column_vsi_relative(w: World) -> Setup:
    w.set_image_file("vsizip/images/x.zip/a.tif")
    return Setup(w.args(profile=MINI), "clean")


@case
def file_column_url(w: World) -> Setup:
    w.set_image_file("http://127.0.0.1:9/x.tif")
    return Setup(w.args(), "exit2", ("tables/images.csv", "row 1"))


@case
def manifest_table_dotdot(w: World) -> Setup:
    (w.outside / "images.csv").write_text((w.delivery / "tables/images.csv").read_text())
    w.edit(
        "delivery.yaml",
        lambda t: t.replace("images: tables/images.csv", "images: ../../outside/images.csv"),
    )
    return Setup(w.args(), "exit2", ("delivery.yaml",))


@case
def document_absolute(w: World) -> Setup:
    w.edit(
        "delivery.yaml",
        lambda t: t.replace(
            "internal_qcr: documents/internal_qcr.md", f"internal_qcr: {w.outside / 'marker.txt'}"
        ),
    )
    return Setup(w.args(), "exit2", ("delivery.yaml",))


@case
def image_fifo(w: World) -> Setup:
    w.first_image().unlink()
    os.mkfifo(w.first_image())
    return Setup(w.args(), "exit2", ("images/F01_0101.tif",))


@case
def image_dev_zero(w: World) -> Setup:
    w.first_image().unlink()
    w.first_image().symlink_to("/dev/zero")
    return Setup(w.args(), "exit2", ("images/F01_0101.tif",))


@case
def image_is_a_directory(w: World) -> Setup:
    w.first_image().unlink()
    w.first_image().mkdir()
    return Setup(w.args(), "record", ("F01_0101",))


def _vrt(source: Path, band: str) -> str:
    return textwrap.dedent(f"""\
        <VRTDataset rasterXSize="64" rasterYSize="64">
          <SRS>EPSG:25832</SRS>
          <GeoTransform>501700, 0.25, 0, 5401050, 0, -0.25</GeoTransform>
          {band.format(src=source)}
        </VRTDataset>
        """)


@case
def images_are_vrts(w: World) -> Setup:
    """Three GeoTIFF-named GDAL VRTs: to a raster outside, a raw band on a text file, a URL."""
    simple = (
        '<VRTRasterBand dataType="Byte" band="1"><SimpleSource><SourceFilename relativeToVRT="0">'
        "{src}</SourceFilename><SourceBand>1</SourceBand></SimpleSource></VRTRasterBand>"
    )
    raw = (
        '<VRTRasterBand dataType="Byte" band="1" subClass="VRTRawRasterBand"><SourceFilename '
        'relativetoVRT="0">{src}</SourceFilename><ImageOffset>0</ImageOffset><PixelOffset>1'
        "</PixelOffset><LineOffset>1</LineOffset></VRTRasterBand>"
    )
    images = sorted((w.delivery / "images").iterdir())
    images[0].write_text(_vrt(w.outside / "marker.tif", simple))
    images[1].write_text(_vrt(w.outside / "marker.txt", raw))
    images[2].write_text(_vrt(Path("/vsicurl/http://127.0.0.1:9/x.tif"), simple))
    return Setup(w.args(), "record", ("F01_0101",), check=_error_records_for(images))


def _error_records_for(images: list[Path]) -> Callable[[World], None]:
    def check(w: World) -> None:
        import json

        doc = json.loads((w.out / "qcr.json").read_text(encoding="utf-8"))
        errs = json.dumps([r for r in doc["records"] if r["verdict"] == "error"])
        for p in images:
            assert p.stem in errs, f"no error record for {p.name}"

    return check


def _add_seamlines(w: World, rel: str) -> None:
    w.edit(
        "delivery.yaml",
        lambda t: t.replace("\ndocuments:", f"\nvectors: {{seamlines: {rel}}}\ndocuments:"),
    )


@case
def seamlines_ogr_vrt(w: World) -> Setup:
    (w.outside / "seams.csv").write_text(
        f'WKT,name\n"POLYGON((500000 5400000,520000 5400000,520000 5420000,500000 5400000))",{MARKER_TEXT}\n'
    )
    (w.delivery / "vectors").mkdir()
    (w.delivery / "vectors" / "seamlines.gpkg").write_text(
        textwrap.dedent(f"""\
        <OGRVRTDataSource><OGRVRTLayer name="seams">
          <SrcDataSource>{w.outside / "seams.csv"}</SrcDataSource>
          <GeometryType>wkbPolygon</GeometryType><GeometryField encoding="WKT" field="WKT"/>
        </OGRVRTLayer></OGRVRTDataSource>
        """)
    )
    _add_seamlines(w, "vectors/seamlines.gpkg")
    return Setup(w.args(), "record", ("vectors/seamlines.gpkg",))


@case
def seamlines_gpkg_wal_not_rewritten(w: World) -> Setup:
    import numpy as np
    import pyogrio
    import shapely

    build = w.outside / "build"
    build.mkdir()
    g = build / "seamlines.gpkg"
    geoms = np.array([shapely.to_wkb(shapely.box(500000, 5400000, 520000, 5420000))], dtype=object)
    pyogrio.raw.write(
        str(g),
        geometry=geoms,
        field_data=[np.array([1])],
        fields=["seam"],
        geometry_type="Polygon",
        crs="EPSG:25832",
        driver="GPKG",
    )
    con = sqlite3.connect(g)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute("UPDATE gpkg_contents SET description='changed in the WAL'")
    con.commit()
    (w.delivery / "vectors").mkdir()
    for suffix in ("", "-wal"):  # copied while the WAL is not checkpointed
        (w.delivery / "vectors" / f"seamlines.gpkg{suffix}").write_bytes(
            Path(f"{g}{suffix}").read_bytes()
        )
    con.close()
    _add_seamlines(w, "vectors/seamlines.gpkg")
    return Setup(w.args(), "clean")


# ------------------------------------------------------------------- outputs (writes)


@case
def out_inside_delivery(w: World) -> Setup:
    return Setup(w.args("--out", str(w.delivery / "qc-out"), out=False), "exit2", ("--out",))


@case
def cwd_inside_delivery_no_out(w: World) -> Setup:
    return Setup(
        ["check", ".", "--profile", PROFILE, "--date", "2026-07-01"], "exit2", (), cwd=w.delivery
    )


@case
def id_with_dotdot_default_out(w: World) -> Setup:
    w.edit("delivery.yaml", lambda t: t.replace("id: D-2026-014", "id: ../../../escaped"))

    def check(w: World) -> None:
        outs = sorted(p.relative_to(w.base).as_posix() for p in w.base.rglob("*qcr.json"))
        assert outs and all(o.startswith("work/reports/") and o.count("/") == 3 for o in outs), outs

    return Setup(
        w.args(out=False, profile=MINI),
        "clean",
        cwd=w.work,
        extra_outputs=(w.work / "reports",),
        check=check,
    )


@case
def id_absolute_into_delivery(w: World) -> Setup:
    w.edit("delivery.yaml", lambda t: t.replace("id: D-2026-014", f"id: '{w.delivery / 'images'}'"))

    def check(w: World) -> None:
        outs = sorted(p.relative_to(w.base).as_posix() for p in w.base.rglob("*qcr.json"))
        assert outs and all(o.startswith("work/reports/") and o.count("/") == 3 for o in outs), outs

    return Setup(
        w.args(out=False, profile=MINI),
        "clean",
        cwd=w.work,
        extra_outputs=(w.work / "reports",),
        check=check,
    )


@case
def junit_path_is_a_directory(w: World) -> Setup:
    (w.out / "junit.xml").mkdir(parents=True)

    def check(w: World) -> None:
        assert sorted(p.name for p in w.out.rglob("*")) == ["junit.xml"], list(w.out.rglob("*"))

    return Setup(w.args(profile=MINI), "exit2", ("junit.xml",), check=check)


@case
def workers_zero(w: World) -> Setup:
    return Setup(w.args("--workers", "0"), "exit2", ("--workers",))


@case
def ledger_garbage(w: World) -> Setup:
    bad = w.outside / "ledger.sqlite"
    bad.write_bytes(b"this is not a ledger\n" * 100)

    def check(w: World) -> None:
        assert not w.out.exists() or not any(w.out.iterdir())

    return Setup(w.args("--ledger", str(bad)), "exit2", ("ledger",), check=check)


# ------------------------------------------------------------------- bounded rasters


@case
def rasters_declare_too_much(w: World) -> Setup:
    """A sparse tiled BigTIFF declaring 10^6 x 10^6 px (a few MB) and a 2 x 2 image with 5,000 bands."""
    import numpy as np
    import rasterio
    from rasterio.transform import from_origin

    images = sorted((w.delivery / "images").iterdir())[:2]
    for p in images:
        p.unlink()
    geo = {"crs": "EPSG:25832", "transform": from_origin(501700, 5401050, 0.25, 0.25)}
    with rasterio.open(
        images[0],
        "w",
        driver="GTiff",
        width=10**6,
        height=10**6,
        count=1,
        dtype="uint8",
        tiled=True,
        blockxsize=4096,
        blockysize=4096,
        BIGTIFF="YES",
        SPARSE_OK=True,
        **geo,
    ):
        pass
    with rasterio.open(
        images[1], "w", driver="GTiff", width=2, height=2, count=5000, dtype="uint8", **geo
    ) as ds:
        ds.write(np.ones((5000, 2, 2), dtype="uint8"))
    return Setup(w.args(), "record", ("F01_0101", "declares"), check=_error_records_for(images))


# ------------------------------------------------------------------- bounded parsing


_BOMB = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]\n" for i in range(1, 10))


@case
def yaml_alias_bomb_manifest(w: World) -> Setup:
    w.edit(
        "delivery.yaml",
        lambda t: t + "notes_bomb:\n  l0: &l0 [lol]\n" + textwrap.indent(_BOMB, "  "),
    )
    return Setup(w.args(), "exit2", ("delivery.yaml",))


@case
def yaml_alias_bomb_profile(w: World) -> Setup:
    prof = w.work / "bomb.yaml"
    prof.write_text(
        MINI_PROFILE.read_text() + "x_bomb:\n  l0: &l0 [lol]\n" + textwrap.indent(_BOMB, "  ")
    )
    return Setup(w.args(profile=str(prof)), "exit2", ("bomb.yaml",))


@case
def yaml_deep_nesting(w: World) -> Setup:
    w.edit("delivery.yaml", lambda t: t + "notes_deep: " + "[" * 20000 + "]" * 20000 + "\n")
    return Setup(w.args(), "exit2", ("delivery.yaml",))


@case
def manifest_100mib_string(w: World) -> Setup:
    with open(w.delivery / "delivery.yaml", "a", encoding="utf-8") as fh:
        fh.write("notes: '")
        _write_repeated(fh, "a", 100 * 2**20)
        fh.write("'\n")
    return Setup(w.args(), "exit2", ("delivery.yaml",))


@case
def manifest_date_feb_30(w: World) -> Setup:
    w.edit("delivery.yaml", lambda t: t.replace("delivered: 2026-06-12", "delivered: 2026-02-30"))
    return Setup(w.args(), "exit2", ("delivery.yaml:8",))


def _when(w: World, when: str) -> Setup:
    prof = w.work / "expr.yaml"
    prof.write_text(
        MINI_PROFILE.read_text().replace(
            "when: \"manifest.sensor.type == 'aerial'\"", f'when: "{when}"'
        )
    )
    assert when in prof.read_text()
    return Setup(w.args(profile=str(prof)), "exit2", ("expr.yaml",))


@case
def expr_power_tower(w: World) -> Setup:
    return _when(w, "9**9**9 > 1")


@case
def expr_huge_power(w: World) -> Setup:
    return _when(w, "2**1000000 > 1")


@case
def expr_string_repetition(w: World) -> Setup:
    return _when(w, "'a' * 10**10 == 'a'")


@case
def expr_max_240_args(w: World) -> Setup:
    return _when(w, "max(" + ", ".join(["1"] * 240) + ") > 0")


@case
def csv_cell_1gib(w: World) -> Setup:
    t = w.delivery / "tables" / "images.csv"
    lines = t.read_text().splitlines(keepends=True)
    with open(t, "w") as fh:
        fh.write(lines[0])
        fh.write(lines[1].rstrip("\n"))
        _write_repeated(fh, "x", 2**30)
        fh.write("\n")
        fh.writelines(lines[2:])
    return Setup(w.args(), "exit2", ("tables/images.csv",))


@case
def csv_cell_100mib(w: World) -> Setup:
    t = w.delivery / "tables" / "images.csv"
    lines = t.read_text().splitlines(keepends=True)
    with open(t, "w") as fh:
        fh.write(lines[0])
        fh.write(lines[1].rstrip("\n"))
        _write_repeated(fh, "x", 100 * 2**20)
        fh.write("\n")
        fh.writelines(lines[2:])
    return Setup(w.args(), "exit2", ("tables/images.csv", "row 1"))


@case
def csv_cell_128kib(w: World) -> Setup:
    w.edit("tables/images.csv", lambda t: t.replace(",cubic\n", "," + "c" * 2**17 + "\n", 1))
    return Setup(w.args(profile=MINI), "clean")


@case
def csv_million_extra_columns(w: World) -> Setup:
    w.edit("tables/images.csv", lambda t: t.replace(",cubic\n", ",cubic" + ",x" * 10**6 + "\n", 1))
    return Setup(w.args(), "exit2", ("tables/images.csv", "row 1"))


@case
def csv_header_million_columns(w: World) -> Setup:
    w.edit(
        "tables/images.csv",
        lambda t: t.replace(
            "resampling\n", "resampling" + "".join(f",c{i}" for i in range(10**6)) + "\n", 1
        ),
    )
    return Setup(w.args(), "exit2", ("tables/images.csv",))


@case
def csv_header_quoted_newline(w: World) -> Setup:
    w.edit("tables/images.csv", lambda t: t.replace("image_id,file,", '"image\nid",file,', 1))
    return Setup(w.args(), "exit2", ("tables/images.csv",))


@case
def file_name_backslash(w: World) -> Setup:
    os.rename(w.first_image(), w.delivery / "images" / "F01\\0101.tif")
    w.set_image_file("images/F01\\0101.tif")
    return Setup(w.args(profile=MINI), "clean")


@case
def table_is_a_directory(w: World) -> Setup:
    t = w.delivery / "tables" / "cameras.csv"
    t.unlink()
    t.mkdir()
    return Setup(w.args(), "exit2", ("tables/cameras.csv",))
