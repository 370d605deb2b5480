"""The ``tiles-real`` example: a delivery as it arrives, not in orthospec's convention (issue 27).

A 512 x 512 px window of a real Landsat 7 ETM+ GeoTIFF (``../shared/data/real/RGB.byte.tif``, 300 m
pixels, WGS 84 / UTM 18N, CC0) cut into 16 tiles of 128 x 128 px (tiled DEFLATE GeoTIFF with an
overview and the per-band statistics a producer's ``gdalinfo -stats`` stores), with what a
producer ships beside them: a tile index shapefile (one feature names a tile that was not
delivered), a seamline shapefile, the block outlines (GeoJSON), an ISO 19139 and an FGDC CSDGM metadata file
written for it, a check point spreadsheet with German headers over two rows (merged group
cells), decimal commas and no convention at all, and a GCP list as a semicolon CSV.

Nothing here is in the delivery convention: ``orthospec init DRAFT --from
examples/deliveries/tiles-real`` drafts it. The values the metadata state (producer, dates,
accuracy) are fictional; the pixels are real. Fixed seeds and no timestamps: byte-identical output.
"""

from __future__ import annotations

import csv
import hashlib
import shutil
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import rasterio
import yaml
from rasterio.transform import Affine
from rasterio.windows import Window

HERE = Path(__file__).resolve().parent
SOURCE = HERE.parent.parent / "shared" / "data" / "real" / "RGB.byte.tif"
NAME = "tiles-real"
WINDOW = Window(150, 100, 512, 512)  # col_off, row_off, width, height: 99.6 % valid pixels
TILE = 128
PREFIX = "LE07_L3"
ID = "DE-L3-ORTHO-LS7-2026-01"
PRODUCER = "Geodaten Nord GmbH (fictional)"
EMAIL = "qa@geodaten-nord.example"
TITLE = "Landsat 7 ETM+ orthoimage tiles, lot 3 (fictional example)"
ACQUIRED = ("2002-11-04", "2002-11-04")
GSD = 300
ACCURACY_M = 150
CRS_EPSG = 32618
TOLERANCE_XY_M = 450.0  # the ITT's tolerance in the checker's file: 1.5 pixels
BLOCKS = ("B1", "B2")  # west and east halves of the lot
SEED = 27


def _tiles(root: Path) -> list[dict[str, Any]]:
    """Cut the window into tiles; return each tile's name and bounds."""
    with rasterio.open(SOURCE) as src:
        data = src.read(window=WINDOW)
        base = src.window_transform(WINDOW)
        crs, nodata = src.crs, src.nodata
    out = []
    (root / "tiles").mkdir(parents=True)
    n = WINDOW.width // TILE
    for r in range(n):
        for c in range(n):
            name = f"{PREFIX}_R{r + 1}_C{c + 1}"
            block = data[:, r * TILE : (r + 1) * TILE, c * TILE : (c + 1) * TILE]
            t = base * Affine.translation(c * TILE, r * TILE)
            path = root / "tiles" / f"{name}.tif"
            with rasterio.open(
                path,
                "w",
                driver="GTiff",
                width=TILE,
                height=TILE,
                count=3,
                dtype="uint8",
                crs=crs,
                transform=t,
                nodata=nodata,
                compress="deflate",
                predictor=2,
                tiled=True,
                blockxsize=64,
                blockysize=64,
                interleave="pixel",
            ) as ds:
                ds.write(block)
                ds.colorinterp = [
                    rasterio.enums.ColorInterp.red,
                    rasterio.enums.ColorInterp.green,
                    rasterio.enums.ColorInterp.blue,
                ]
                for b in range(3):  # what `gdalinfo -stats` stores: nodata excluded, population std
                    v = block[b][block[b] != nodata].astype(np.float64)
                    ds.update_tags(
                        b + 1,
                        STATISTICS_MINIMUM=f"{v.min():.0f}",
                        STATISTICS_MAXIMUM=f"{v.max():.0f}",
                        STATISTICS_MEAN=repr(float(v.mean())),
                        STATISTICS_STDDEV=repr(float(v.std())),
                    )
            with rasterio.open(path, "r+") as ds:
                ds.build_overviews([2], rasterio.enums.Resampling.average)
            left, top = t.c, t.f
            out.append(
                {
                    "name": name,
                    "row": r,
                    "col": c,
                    "bounds": (left, top + TILE * t.e, left + TILE * t.a, top),
                }
            )
    return out


def _blocks(tiles: list[dict[str, Any]]) -> dict[str, tuple[float, float, float, float]]:
    left = min(t["bounds"][0] for t in tiles)
    bottom = min(t["bounds"][1] for t in tiles)
    right = max(t["bounds"][2] for t in tiles)
    top = max(t["bounds"][3] for t in tiles)
    mid = tiles[0]["bounds"][0] + (right - left) / 2
    return {"B1": (left, bottom, mid, top), "B2": (mid, bottom, right, top)}


def _write_vectors(
    root: Path, tiles: list[dict[str, Any]], blocks: dict[str, tuple[float, float, float, float]]
) -> None:
    import shapely

    (root / "index").mkdir()
    crs = f"EPSG:{CRS_EPSG}"
    # the tile index: one polygon per tile, named; the producer's index also lists a tile of the
    # next row that is not on this disk (listed by the draft as matching no image)
    names = [t["name"] for t in tiles] + [f"{PREFIX}_R5_C1"]
    missing = tiles[-4]["bounds"]
    h = missing[3] - missing[1]
    boxes = [shapely.box(*t["bounds"]) for t in tiles] + [
        shapely.box(missing[0], missing[1] - h, missing[2], missing[1])
    ]
    _write(root / "index" / "tile_index.shp", "ESRI Shapefile", boxes, {"TILE_NAME": names}, crs)
    # seamlines: the one source scene's valid area over the lot
    left = min(t["bounds"][0] for t in tiles)
    bottom = min(t["bounds"][1] for t in tiles)
    right = max(t["bounds"][2] for t in tiles)
    top = max(t["bounds"][3] for t in tiles)
    _write(
        root / "index" / "seamlines.shp",
        "ESRI Shapefile",
        [shapely.box(left, bottom, right, top)],
        {"SCENE": ["LE07_L1TP_014042_20021104"]},
        crs,
    )
    _write(
        root / "index" / "blocks.geojson",
        "GeoJSON",
        [shapely.box(*b) for b in blocks.values()],
        {"BLOCK": list(blocks)},
        crs,
    )


def _write(
    path: Path, driver: str, geoms: list[Any], fields: dict[str, list[str]], crs: str
) -> None:
    import pyogrio.raw
    import shapely

    geometry = np.array([shapely.to_wkb(g) for g in geoms], dtype=object)
    names = list(fields)
    values = [np.array(v, dtype=object) for v in fields.values()]
    # a fixed DBF date (GDAL stamps today's otherwise): the same bytes on every run
    layer_options = (
        {"SPATIAL_INDEX": "NO", "DBF_DATE_LAST_UPDATE": "2026-05-02"}
        if driver == "ESRI Shapefile"
        else {}
    )
    pyogrio.raw.write(
        str(path),
        geometry,
        values,
        names,
        driver=driver,
        crs=crs,
        geometry_type="Polygon",
        layer=path.stem,
        layer_options=layer_options or None,
    )


def _points(
    tiles: list[dict[str, Any]], blocks: dict[str, tuple[float, float, float, float]]
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """20 check points per block on valid pixels (image = reference + error) and 4 GCPs per block."""
    rng = np.random.default_rng(SEED)
    with rasterio.open(SOURCE) as src:
        valid = src.read(1, window=WINDOW) > 0
        t = src.window_transform(WINDOW)
    cps, gcps = [], []
    for b, (left, _bottom, right, _top) in blocks.items():
        c0 = round((left - t.c) / t.a)
        c1 = round((right - t.c) / t.a)
        picked = 0
        while picked < 24:
            row = int(rng.integers(4, WINDOW.height - 4))
            col = int(rng.integers(c0 + 4, c1 - 4))
            if not valid[row, col]:
                continue
            x_ref = t.c + (col + rng.uniform(0.2, 0.8)) * t.a
            y_ref = t.f + (row + rng.uniform(0.2, 0.8)) * t.e
            z = float(rng.uniform(2.0, 40.0))
            if picked < 20:
                dx, dy = rng.normal(0.0, 95.0, 2)
                cps.append(
                    {
                        "id": f"{b}-K{picked + 1:02d}",
                        "x": x_ref + dx,
                        "y": y_ref + dy,
                        "x_ref": x_ref,
                        "y_ref": y_ref,
                        "z_ref": z,
                    }
                )
            else:
                gcps.append(
                    {"id": f"{b}-P{picked - 19}", "x": x_ref, "y": y_ref, "z": z, "precision": 0.05}
                )
            picked += 1
    return cps, gcps


def _comma(v: float, digits: int) -> str:
    return f"{v:.{digits}f}".replace(".", ",")


def _xlsx(path: Path, cps: list[dict[str, Any]]) -> None:
    """The survey as the surveyor's spreadsheet program saved it: a title row, group titles merged
    over their columns, German names with units, coordinates as text with decimal commas."""
    from openpyxl import Workbook

    wb = Workbook()
    ws = wb.active
    ws.title = "Kontrollpunkte"
    ws.append(["Kontrollpunkte Los 3, GNSS-Kampagne Oktober 2002 (fiktiv)"])
    ws.append(["Punkt", "Orthofoto", None, "GNSS-Messung", None, None, "Quelle"])
    ws.append(
        [None, "Rechtswert [m]", "Hochwert [m]", "Rechtswert [m]", "Hochwert [m]", "Höhe [m]", None]
    )
    ws.merge_cells("B2:C2")
    ws.merge_cells("D2:F2")
    for p in cps:
        ws.append(
            [
                p["id"],
                _comma(p["x"], 2),
                _comma(p["y"], 2),
                _comma(p["x_ref"], 3),
                _comma(p["y_ref"], 3),
                _comma(p["z_ref"], 3),
                "GNSS RTK, unabhängig vom Auftragnehmer (fiktiv)",
            ]
        )
    tmp = path.with_suffix(".tmp")
    wb.save(tmp)
    _normalise_zip(tmp, path)
    tmp.unlink()


def _normalise_zip(src: Path, dst: Path) -> None:
    """openpyxl stamps the creation time into docProps/core.xml and the zip entries: fixed here so
    the file is byte-identical from run to run."""
    import re

    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in sorted(zin.infolist(), key=lambda i: i.filename):
            data = zin.read(item.filename)
            if item.filename == "docProps/core.xml":
                data = re.sub(
                    rb"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}Z", b"2026-05-02T00:00:00Z", data
                )
            info = zipfile.ZipInfo(item.filename, date_time=(2026, 5, 2, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            zout.writestr(info, data)


def _gcp_csv(path: Path, gcps: list[dict[str, Any]]) -> None:
    with path.open("w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh, delimiter=";", lineterminator="\r\n")
        w.writerow(["Pkt", "Rechtswert", "Hochwert", "Höhe", "Genauigkeit Lage"])
        for g in gcps:
            w.writerow(
                [
                    g["id"],
                    _comma(g["x"], 3),
                    _comma(g["y"], 3),
                    _comma(g["z"], 3),
                    _comma(g["precision"], 2),
                ]
            )


def _bbox_wgs84(tiles: list[dict[str, Any]]) -> tuple[float, float, float, float]:
    from pyproj import Transformer

    t = Transformer.from_crs(CRS_EPSG, 4326, always_xy=True)
    left = min(x["bounds"][0] for x in tiles)
    bottom = min(x["bounds"][1] for x in tiles)
    right = max(x["bounds"][2] for x in tiles)
    top = max(x["bounds"][3] for x in tiles)
    xs, ys = t.transform([left, left, right, right], [bottom, top, bottom, top])
    return round(min(xs), 4), round(min(ys), 4), round(max(xs), 4), round(max(ys), 4)


def _iso(bbox: tuple[float, float, float, float]) -> str:
    w, s, e, n = bbox
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<gmi:MI_Metadata xmlns:gmi="http://www.isotc211.org/2005/gmi" xmlns:gmd="http://www.isotc211.org/2005/gmd"
    xmlns:gco="http://www.isotc211.org/2005/gco" xmlns:gml="http://www.opengis.net/gml/3.2"
    xmlns:xlink="http://www.w3.org/1999/xlink">
  <gmd:fileIdentifier><gco:CharacterString>{ID}</gco:CharacterString></gmd:fileIdentifier>
  <gmd:language><gmd:LanguageCode codeList="http://www.loc.gov/standards/iso639-2/" codeListValue="eng">eng</gmd:LanguageCode></gmd:language>
  <gmd:hierarchyLevel><gmd:MD_ScopeCode codeList="http://standards.iso.org/iso/19139/resources/gmxCodelists.xml#MD_ScopeCode" codeListValue="dataset">dataset</gmd:MD_ScopeCode></gmd:hierarchyLevel>
  <gmd:contact>
    <gmd:CI_ResponsibleParty>
      <gmd:organisationName><gco:CharacterString>{PRODUCER}</gco:CharacterString></gmd:organisationName>
      <gmd:role><gmd:CI_RoleCode codeList="http://standards.iso.org/iso/19139/resources/gmxCodelists.xml#CI_RoleCode" codeListValue="pointOfContact">pointOfContact</gmd:CI_RoleCode></gmd:role>
    </gmd:CI_ResponsibleParty>
  </gmd:contact>
  <gmd:dateStamp><gco:Date>2026-05-02</gco:Date></gmd:dateStamp>
  <gmd:metadataStandardName><gco:CharacterString>ISO 19115-2:2009 (ISO/TS 19139)</gco:CharacterString></gmd:metadataStandardName>
  <gmd:referenceSystemInfo>
    <gmd:MD_ReferenceSystem>
      <gmd:referenceSystemIdentifier>
        <gmd:RS_Identifier>
          <gmd:code><gco:CharacterString>http://www.opengis.net/def/crs/EPSG/0/{CRS_EPSG}</gco:CharacterString></gmd:code>
          <gmd:codeSpace><gco:CharacterString>EPSG</gco:CharacterString></gmd:codeSpace>
        </gmd:RS_Identifier>
      </gmd:referenceSystemIdentifier>
    </gmd:MD_ReferenceSystem>
  </gmd:referenceSystemInfo>
  <gmd:identificationInfo>
    <gmd:MD_DataIdentification>
      <gmd:citation>
        <gmd:CI_Citation>
          <gmd:title><gco:CharacterString>{TITLE}</gco:CharacterString></gmd:title>
          <gmd:date>
            <gmd:CI_Date>
              <gmd:date><gco:Date>2026-05-02</gco:Date></gmd:date>
              <gmd:dateType><gmd:CI_DateTypeCode codeList="http://standards.iso.org/iso/19139/resources/gmxCodelists.xml#CI_DateTypeCode" codeListValue="creation">creation</gmd:CI_DateTypeCode></gmd:dateType>
            </gmd:CI_Date>
          </gmd:date>
        </gmd:CI_Citation>
      </gmd:citation>
      <gmd:abstract><gco:CharacterString>Orthorectified Landsat 7 ETM+ imagery (bands 3, 2, 1 as red, green, blue) resampled to 300 m pixels and delivered as 16 tiles of 128 x 128 pixels (fictional delivery written for orthospec's example).</gco:CharacterString></gmd:abstract>
      <gmd:pointOfContact>
        <gmd:CI_ResponsibleParty>
          <gmd:organisationName><gco:CharacterString>{PRODUCER}</gco:CharacterString></gmd:organisationName>
          <gmd:contactInfo>
            <gmd:CI_Contact>
              <gmd:address><gmd:CI_Address><gmd:electronicMailAddress><gco:CharacterString>{EMAIL}</gco:CharacterString></gmd:electronicMailAddress></gmd:CI_Address></gmd:address>
            </gmd:CI_Contact>
          </gmd:contactInfo>
          <gmd:role><gmd:CI_RoleCode codeList="http://standards.iso.org/iso/19139/resources/gmxCodelists.xml#CI_RoleCode" codeListValue="originator">originator</gmd:CI_RoleCode></gmd:role>
        </gmd:CI_ResponsibleParty>
      </gmd:pointOfContact>
      <gmd:spatialRepresentationType><gmd:MD_SpatialRepresentationTypeCode codeList="http://standards.iso.org/iso/19139/resources/gmxCodelists.xml#MD_SpatialRepresentationTypeCode" codeListValue="grid">grid</gmd:MD_SpatialRepresentationTypeCode></gmd:spatialRepresentationType>
      <gmd:spatialResolution>
        <gmd:MD_Resolution>
          <gmd:distance><gco:Distance uom="m">{GSD}</gco:Distance></gmd:distance>
        </gmd:MD_Resolution>
      </gmd:spatialResolution>
      <gmd:language><gmd:LanguageCode codeList="http://www.loc.gov/standards/iso639-2/" codeListValue="eng">eng</gmd:LanguageCode></gmd:language>
      <gmd:topicCategory><gmd:MD_TopicCategoryCode>imageryBaseMapsEarthCover</gmd:MD_TopicCategoryCode></gmd:topicCategory>
      <gmd:extent>
        <gmd:EX_Extent>
          <gmd:geographicElement>
            <gmd:EX_GeographicBoundingBox>
              <gmd:westBoundLongitude><gco:Decimal>{w}</gco:Decimal></gmd:westBoundLongitude>
              <gmd:eastBoundLongitude><gco:Decimal>{e}</gco:Decimal></gmd:eastBoundLongitude>
              <gmd:southBoundLatitude><gco:Decimal>{s}</gco:Decimal></gmd:southBoundLatitude>
              <gmd:northBoundLatitude><gco:Decimal>{n}</gco:Decimal></gmd:northBoundLatitude>
            </gmd:EX_GeographicBoundingBox>
          </gmd:geographicElement>
          <gmd:temporalElement>
            <gmd:EX_TemporalExtent>
              <gmd:extent>
                <gml:TimePeriod gml:id="acquisition">
                  <gml:beginPosition>{ACQUIRED[0]}</gml:beginPosition>
                  <gml:endPosition>{ACQUIRED[1]}</gml:endPosition>
                </gml:TimePeriod>
              </gmd:extent>
            </gmd:EX_TemporalExtent>
          </gmd:temporalElement>
        </gmd:EX_Extent>
      </gmd:extent>
    </gmd:MD_DataIdentification>
  </gmd:identificationInfo>
  <gmd:contentInfo>
    <gmi:MI_CoverageDescription>
      <gmd:attributeDescription><gco:RecordType>reflectance DN</gco:RecordType></gmd:attributeDescription>
      <gmd:contentType><gmd:MD_CoverageContentTypeCode codeList="http://standards.iso.org/iso/19139/resources/gmxCodelists.xml#MD_CoverageContentTypeCode" codeListValue="image">image</gmd:MD_CoverageContentTypeCode></gmd:contentType>
      <gmd:dimension><gmd:MD_Band><gmd:descriptor><gco:CharacterString>red (ETM+ band 3)</gco:CharacterString></gmd:descriptor><gmd:bitsPerValue><gco:Integer>8</gco:Integer></gmd:bitsPerValue></gmd:MD_Band></gmd:dimension>
      <gmd:dimension><gmd:MD_Band><gmd:descriptor><gco:CharacterString>green (ETM+ band 2)</gco:CharacterString></gmd:descriptor><gmd:bitsPerValue><gco:Integer>8</gco:Integer></gmd:bitsPerValue></gmd:MD_Band></gmd:dimension>
      <gmd:dimension><gmd:MD_Band><gmd:descriptor><gco:CharacterString>blue (ETM+ band 1)</gco:CharacterString></gmd:descriptor><gmd:bitsPerValue><gco:Integer>8</gco:Integer></gmd:bitsPerValue></gmd:MD_Band></gmd:dimension>
    </gmi:MI_CoverageDescription>
  </gmd:contentInfo>
  <gmd:dataQualityInfo>
    <gmd:DQ_DataQuality>
      <gmd:scope><gmd:DQ_Scope><gmd:level><gmd:MD_ScopeCode codeList="http://standards.iso.org/iso/19139/resources/gmxCodelists.xml#MD_ScopeCode" codeListValue="dataset">dataset</gmd:MD_ScopeCode></gmd:level></gmd:DQ_Scope></gmd:scope>
      <gmd:report>
        <gmd:DQ_AbsoluteExternalPositionalAccuracy>
          <gmd:nameOfMeasure><gco:CharacterString>RMSE planimetric</gco:CharacterString></gmd:nameOfMeasure>
          <gmd:result>
            <gmd:DQ_QuantitativeResult>
              <gmd:valueUnit xlink:href="http://www.opengis.net/def/uom/EPSG/0/9001"/>
              <gmd:value><gco:Record>{ACCURACY_M}</gco:Record></gmd:value>
            </gmd:DQ_QuantitativeResult>
          </gmd:result>
        </gmd:DQ_AbsoluteExternalPositionalAccuracy>
      </gmd:report>
      <gmd:lineage>
        <gmd:LI_Lineage>
          <gmd:statement><gco:CharacterString>Level-1 terrain-corrected scene, resampled (cubic convolution) to 300 m, cut into 128 x 128 pixel tiles, DEFLATE compressed with internal overviews.</gco:CharacterString></gmd:statement>
        </gmd:LI_Lineage>
      </gmd:lineage>
    </gmd:DQ_DataQuality>
  </gmd:dataQualityInfo>
  <gmi:acquisitionInformation>
    <gmi:MI_AcquisitionInformation>
      <gmi:instrument>
        <gmi:MI_Instrument>
          <gmi:identifier><gmd:MD_Identifier><gmd:code><gco:CharacterString>ETM+</gco:CharacterString></gmd:code></gmd:MD_Identifier></gmi:identifier>
          <gmi:type><gco:CharacterString>multispectral scanner</gco:CharacterString></gmi:type>
        </gmi:MI_Instrument>
      </gmi:instrument>
      <gmi:platform>
        <gmi:MI_Platform>
          <gmi:identifier><gmd:MD_Identifier><gmd:code><gco:CharacterString>Landsat-7</gco:CharacterString></gmd:code></gmd:MD_Identifier></gmi:identifier>
          <gmi:description><gco:CharacterString>Landsat 7 satellite</gco:CharacterString></gmi:description>
          <gmi:instrument xlink:href="#ETM"/>
        </gmi:MI_Platform>
      </gmi:platform>
    </gmi:MI_AcquisitionInformation>
  </gmi:acquisitionInformation>
</gmi:MI_Metadata>
"""


def _fgdc(bbox: tuple[float, float, float, float]) -> str:
    w, s, e, n = bbox
    d0, d1 = (x.replace("-", "") for x in ACQUIRED)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!DOCTYPE metadata SYSTEM "http://www.fgdc.gov/metadata/fgdc-std-001-1998.dtd">
<metadata>
  <idinfo>
    <citation>
      <citeinfo>
        <origin>{PRODUCER}</origin>
        <pubdate>20260502</pubdate>
        <title>{TITLE}</title>
        <geoform>remote-sensing image</geoform>
      </citeinfo>
    </citation>
    <descript>
      <abstract>Orthorectified Landsat 7 ETM+ imagery, 300 m pixels, 16 tiles (fictional delivery).</abstract>
      <purpose>Example delivery for orthospec init --from.</purpose>
    </descript>
    <timeperd>
      <timeinfo><rngdates><begdate>{d0}</begdate><enddate>{d1}</enddate></rngdates></timeinfo>
      <current>ground condition</current>
    </timeperd>
    <status><progress>Complete</progress><update>None planned</update></status>
    <spdom><bounding><westbc>{w}</westbc><eastbc>{e}</eastbc><northbc>{n}</northbc><southbc>{s}</southbc></bounding></spdom>
    <keywords><theme><themekt>None</themekt><themekey>orthoimagery</themekey><themekey>Landsat</themekey></theme></keywords>
    <plainsid>
      <missname>Landsat 7</missname>
      <platflnm>Landsat-7</platflnm>
      <instshnm>ETM+</instshnm>
      <instflnm>Enhanced Thematic Mapper Plus</instflnm>
    </plainsid>
    <accconst>None</accconst>
    <useconst>None</useconst>
    <ptcontac>
      <cntinfo>
        <cntorgp><cntorg>{PRODUCER}</cntorg></cntorgp>
        <cntemail>{EMAIL}</cntemail>
      </cntinfo>
    </ptcontac>
  </idinfo>
  <dataqual>
    <attracc><attraccr>Not assessed.</attraccr></attracc>
    <logic>Tiles edge-matched, no gaps.</logic>
    <complete>16 tiles of the lot.</complete>
    <posacc>
      <horizpa>
        <horizpar>Planimetric RMSE from independent GNSS check points.</horizpar>
        <qhorizpa>
          <horizpav>{ACCURACY_M}</horizpav>
          <horizpae>RMSE planimetric, metres</horizpae>
        </qhorizpa>
      </horizpa>
    </posacc>
    <lineage>
      <procstep>
        <procdesc>Level-1 terrain-corrected scene, resampled (cubic convolution) to 300 m, cut into 128 x 128 pixel tiles, DEFLATE compressed with internal overviews.</procdesc>
        <procdate>20260430</procdate>
      </procstep>
    </lineage>
  </dataqual>
  <spdoinfo><direct>Raster</direct><rastinfo><rasttype>Grid Cell</rasttype><rowcount>512</rowcount><colcount>512</colcount></rastinfo></spdoinfo>
  <spref>
    <horizsys>
      <planar>
        <gridsys>
          <gridsysn>Universal Transverse Mercator</gridsysn>
          <utm><utmzone>18</utmzone><transmer><sfctrmer>0.9996</sfctrmer><longcm>-75</longcm><latprjo>0</latprjo><feast>500000</feast><fnorth>0</fnorth></transmer></utm>
        </gridsys>
        <planci>
          <plance>row and column</plance>
          <coordrep><absres>{GSD}</absres><ordres>{GSD}</ordres></coordrep>
          <plandu>meters</plandu>
        </planci>
      </planar>
      <geodetic><horizdn>World Geodetic System 1984</horizdn><ellips>WGS 84</ellips><semiaxis>6378137</semiaxis><denflat>298.257223563</denflat></geodetic>
    </horizsys>
  </spref>
  <metainfo>
    <metd>20260502</metd>
    <metc><cntinfo><cntorgp><cntorg>{PRODUCER}</cntorg></cntorgp><cntemail>{EMAIL}</cntemail></cntinfo></metc>
    <metstdn>FGDC Content Standard for Digital Geospatial Metadata</metstdn>
    <metstdv>FGDC-STD-001-1998</metstdv>
  </metainfo>
</metadata>
"""


README = """# tiles-real: a delivery as it arrives

Generated by `examples/tiles_real.py` (called by `examples/generate.py`; do not edit by hand). Not in
orthospec's delivery convention: this is what a paying agency receives. `orthospec init --from`
drafts the delivery from it; `orthospec check` judges the draft.

| path | what |
|---|---|
| `tiles/*.tif` | 16 orthoimage tiles, 128 x 128 px, 300 m, WGS 84 / UTM 18N, 3-band uint8, tiled DEFLATE with an overview and stored band statistics: a real Landsat 7 ETM+ image (`../shared/data/real/RGB.byte.tif`, CC0) |
| `index/tile_index.shp` | the producer's tile index (`TILE_NAME`); it also lists `{prefix}_R5_C1`, not on this disk |
| `index/seamlines.shp` | the mosaic's seamline polygon (one source scene) |
| `index/blocks.geojson` | the block outlines `B1` (west) and `B2` (east) (`BLOCK`) |
| `metadata/*_iso19139.xml`, `metadata/*_fgdc.xml` | ISO 19115-2/19139 and FGDC CSDGM metadata (fictional producer, dates and accuracy) |
| `survey/Kontrollpunkte_Los3.xlsx` | 40 check points: a title row, group titles merged over two header rows, German names, coordinates as text with decimal commas |
| `survey/Passpunkte.csv` | 8 GCPs, `;`-separated, decimal commas, no unit in the header |

From the repository root, the two commands from this folder to a report:

```bash
.venv/bin/orthospec init out/tiles-draft --from examples/deliveries/tiles-real
.venv/bin/orthospec check out/tiles-draft --profile jrc-v3 --checker examples/checker/tiles-real.yaml \\
    --out out/tiles-report --date 2026-05-20
```

The draft (`out/tiles-draft/`) holds `delivery.yaml` (every value with the file and XPath it was
read from), `tables/images.csv`, `tables/checkpoints.csv`, `tables/gcps.csv`, `INGEST.md` (what was
read, decided and refused) and `TODO.md` (what the files do not tell, with the rules that stay
`missing`). The check's verdict is **REJECTED** (exit 1): the files alone leave the rules listed in
the draft's TODO.md `missing` (the satellite scene records, the delivery date, the operator, the
contractor's reports, the checker's manual checks), and every `missing` record names its TODO.md
line (`tests/test_ingest_draft.py` checks both). Nothing was written by hand between the two
commands; the checker's file (`examples/checker/tiles-real.yaml`) states the ITT tolerance, the map
projection and the block outlines in force.
"""


def generate(out: Path, checker_dir: Path) -> Path:
    """Write ``out/tiles-real`` and ``checker_dir/tiles-real.yaml``; return the folder."""
    root = Path(out) / NAME
    if root.exists():
        shutil.rmtree(root)
    root.mkdir(parents=True)
    tiles = _tiles(root)
    blocks = _blocks(tiles)
    _write_vectors(root, tiles, blocks)
    (root / "metadata").mkdir()
    bbox = _bbox_wgs84(tiles)
    (root / "metadata" / f"{PREFIX}_iso19139.xml").write_text(_iso(bbox), encoding="utf-8")
    (root / "metadata" / f"{PREFIX}_fgdc.xml").write_text(_fgdc(bbox), encoding="utf-8")
    (root / "survey").mkdir()
    cps, gcps = _points(tiles, blocks)
    _xlsx(root / "survey" / "Kontrollpunkte_Los3.xlsx", cps)
    _gcp_csv(root / "survey" / "Passpunkte.csv", gcps)
    checker = _checker(root, blocks, checker_dir)
    checker_dir.mkdir(parents=True, exist_ok=True)
    head = (
        "# Generated by examples/tiles_real.py: do not edit by hand, run `python examples/generate.py`.\n"
        "# The external QC's file for the draft of tiles-real (`orthospec init DRAFT --from\n"
        "# examples/deliveries/tiles-real`): the ITT values and the block outlines in force.\n"
    )
    (checker_dir / f"{NAME}.yaml").write_text(
        head + yaml.safe_dump(checker, sort_keys=False, width=100), encoding="utf-8"
    )
    (root / "README.md").write_text(README.format(prefix=PREFIX), encoding="utf-8")
    return root


def _checker(
    root: Path, blocks: dict[str, tuple[float, float, float, float]], checker_dir: Path
) -> dict[str, Any]:
    """The checker's file for the draft, pinned on the draft's check point table (drafted here with
    the library, as `orthospec init --from` does; the draft is byte-identical from run to run); and
    the checker folders whose check points `orthospec measure checkpoints` measured on the draft
    (issue 29: :func:`_measured_folders`)."""
    from orthospec.ingest import Options, make_draft

    with tempfile.TemporaryDirectory() as tmp:
        draft = Path(tmp) / "draft"
        make_draft(draft, [root], Options(workers=1))
        sha = hashlib.sha256((draft / "tables" / "checkpoints.csv").read_bytes()).hexdigest()
        ident = yaml.safe_load((draft / "delivery.yaml").read_text(encoding="utf-8"))["id"]
        checker = {
            "orthospec_checker": 1,
            "checker": {
                "name": "A. Weber (fictional)",
                "role": "external QC",
                "organisation": "the paying agency's control contractor (fictional)",
            },
            "delivery": {"id": ident, "files": {"tables/checkpoints.csv": sha}},
            "parameters": {
                "tolerance_xy": {"value": TOLERANCE_XY_M, "unit": "m"},
                "map_crs": f"EPSG:{CRS_EPSG}",
            },
            "blocks": [
                {"id": b, "polygon": [[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]}
                for b, (x0, y0, x1, y1) in blocks.items()
            ],
        }
        _measured_folders(draft, checker, checker_dir)
    return checker


# --- issue 29: the external QC's check points, measured by `orthospec measure checkpoints` ---------
#: the planted error of the delivery against the checker's reference, in metres (x, y): the
#: reference orthoimage is the same scene georeferenced (dx, dy) away, so every delivered feature
#: lies at (true - shift); the measured image-minus-true offset must come out as -shift
SHIFTS: dict[str, tuple[float, float]] = {
    "tiles-real": (111.0, -63.0),  # 0.37 / -0.21 px: 128 m, within the 450 m tolerance
    "tiles-real-fail": (480.0, -390.0),  # 1.6 / -1.3 px: 618 m, beyond it
}
#: pixels (col, row) of the window where the reference orthophoto has a cloud (flat 250 DN over
#: CLOUD_PX x CLOUD_PX): the points surveyed there go to the hand list (low texture)
CLOUDS: tuple[tuple[int, int], ...] = ((64, 448), (320, 192))
CLOUD_PX = 48
#: the command's options: a 32 px template searched 8 px either way needs a point 24 px inside its
#: 128 px tile; the checker surveys two well-defined points per tile, 30 px or more inside it
CHIP_PX, SEARCH_PX, MARGIN_PX = 32, 8, 30
SURVEY_SOURCE = "GNSS RTK survey by the external QC, independent of the contractor (fictional)"


def _reference(path: Path, shift: tuple[float, float], seed: int) -> None:
    """The checker's reference orthophoto: the window's luminance (one band), radiometrically
    unlike the delivery (gain, offset, noise, a cloud over two surveyed points) and georeferenced
    ``shift`` metres from the delivered tiles."""
    with rasterio.open(SOURCE) as src:
        data = src.read(window=WINDOW).astype(np.float64)
        t = src.window_transform(WINDOW)
        crs = src.crs
    valid = (data > 0).all(axis=0)
    lum = data.mean(axis=0) * 0.9 + 12.0 + np.random.default_rng(seed).normal(0.0, 2.0, valid.shape)
    for c, r in CLOUDS:
        h = CLOUD_PX // 2
        lum[r - h : r + h, c - h : c + h] = 250.0
    out = np.where(valid, np.clip(np.rint(lum), 1, 255), 0).astype(np.uint8)
    transform = Affine(t.a, t.b, t.c + shift[0], t.d, t.e, t.f + shift[1])
    path.parent.mkdir(parents=True, exist_ok=True)
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=out.shape[1],
        height=out.shape[0],
        count=1,
        dtype="uint8",
        crs=crs,
        transform=transform,
        nodata=0,
        compress="deflate",
        predictor=2,
        tiled=True,
        blockxsize=256,
        blockysize=256,
    ) as ds:
        ds.write(out, 1)
        ds.colorinterp = [rasterio.enums.ColorInterp.gray]


def _survey(path: Path) -> None:
    """The checker's survey: true coordinates of two points per tile (30 px or more inside it, fixed
    seed) and of the two points under the reference's cloud."""
    from scipy.ndimage import maximum_filter

    with rasterio.open(SOURCE) as src:
        t = src.window_transform(WINDOW)
        zero = (src.read(window=WINDOW) == 0).any(axis=0)
    # a 0 DN in any band is no-data in the tiles (nodata 0): the scene has a few inside (dark
    # water), and a search window that meets one goes to the hand list; the checker picks its points
    # where the matching window (template and search, 25 px either way) is clear of them
    valid = ~maximum_filter(zero, size=2 * MARGIN_PX - 7)
    rng = np.random.default_rng(SEED + 29)
    rows = []
    n = WINDOW.width // TILE
    for r in range(n):
        for c in range(n):
            k = 0
            while k < 2:
                col = c * TILE + float(rng.uniform(MARGIN_PX, TILE - MARGIN_PX))
                row = r * TILE + float(rng.uniform(MARGIN_PX, TILE - MARGIN_PX))
                if not valid[int(row), int(col)]:
                    continue
                k += 1
                x, y = t * (col, row)
                rows.append((f"Q-R{r + 1}C{c + 1}-{k}", x, y, float(rng.uniform(2.0, 40.0))))
    for k, (c, r) in enumerate(CLOUDS):
        x, y = t * (c + 0.5, r + 0.5)
        rows.append((f"Q-W{k + 1}", x, y, 5.0))
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["point_id", "x", "y", "z", "source", "precision_xy"])
        for pid, x, y, z in rows:
            w.writerow([pid, f"{x:.3f}", f"{y:.3f}", f"{z:.3f}", SURVEY_SOURCE, "0.05"])


def _measured_folders(draft: Path, checker: dict[str, Any], checker_dir: Path) -> None:
    """examples/checker/tiles-real{,-fail}/: reference, survey, and the table and hand list that
    `orthospec measure checkpoints DRAFT --reference ... --points ... --out ...` writes (run here
    through the library, the same function the command calls)."""
    import os

    from orthospec.measures.matching import MatchSettings
    from orthospec.raster.checkpoints import MeasureOptions, measure_checkpoints

    options = MeasureOptions(chip_px=CHIP_PX, settings=MatchSettings(search_px=SEARCH_PX))
    # paths as the README's command gives them from the repository root (the table records the
    # reference's path): the same table from here, into any folder, and from the command line
    base = draft.parent / "repo"
    (base / "examples").mkdir(parents=True)
    checker_dir.mkdir(parents=True, exist_ok=True)
    (base / "examples" / "checker").symlink_to(checker_dir.resolve(), target_is_directory=True)
    cwd = Path.cwd()
    for k, (name, shift) in enumerate(SHIFTS.items()):
        folder = checker_dir / name
        if folder.exists():
            shutil.rmtree(folder)
        _reference(folder / "reference" / "reference.tif", shift, SEED + k)
        _survey(folder / "survey.csv")
        rel = Path("examples") / "checker" / name
        os.chdir(base)
        try:
            measure_checkpoints(
                draft.resolve(),
                rel / "reference" / "reference.tif",
                rel / "survey.csv",
                rel,
                options=options,
            )
        finally:
            os.chdir(cwd)
        head = (
            f"# Generated by examples/tiles_real.py: do not edit by hand, run `python examples/generate.py`.\n"
            f"# The external QC's folder for the draft of tiles-real; tables/checkpoints.csv was written by\n"
            f"# `orthospec measure checkpoints` from reference/reference.tif (the scene georeferenced\n"
            f"# {shift[0]:g}, {shift[1]:g} m away: the planted error) and survey.csv (issue 29).\n"
        )
        (folder / "checker.yaml").write_text(
            head + yaml.safe_dump(checker, sort_keys=False, width=100), encoding="utf-8"
        )
