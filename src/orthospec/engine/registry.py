"""Measure providers register here: ``@provider(scope=..., measures={name: unit})``.

A provider is a function ``fn(ctx: ProviderContext) -> Iterable[Measured]`` registered for one
scope and a fixed set of measure names with their units. This module holds only what a provider
needs (the decorator, ``Measured``, ``ProviderContext``, ``RowEvidence``, the scopes) and imports
no provider: finding the providers (built-in modules, plugins), looking a measure up and calling
each provider once per run live one level up, in engine/catalog.py. So a provider module (built-in
or plugin) imports this module, and nothing here imports a provider (no cycle, issue 15 item 2).
A registered measure is announced to profile/catalog.py, so profile validation knows plugin measures
without importing the engine.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..errors import MeasureError
from ..profile import catalog as spec_catalog
from ..provenance import Evidence

if TYPE_CHECKING:
    from ..delivery.reader import Delivery

#: Scopes in report order; the evaluator sorts records by this.
SCOPES: tuple[str, ...] = (
    "delivery", "project", "block", "image", "band", "checkpoint", "gcp", "flight", "camera",
    "scanner", "dem", "mosaic", "edge",
)


@dataclass
class Measured:
    """One measure over the items of one scope, with the evidence behind each value."""

    name: str
    scope: str
    unit: str
    values: pd.Series
    evidence: pd.Series | RowEvidence
    detail: dict[str, Any] | None = None
    #: per-item explanation when a value is missing or could not be computed (reason text)
    notes: pd.Series | None = None
    #: items whose value could not be computed because their input is broken (verdict `error`)
    errors: pd.Series | None = None
    #: items the measure does not apply to (verdict `not_applicable`), value = reason text
    na: pd.Series | None = None

    def __post_init__(self) -> None:
        self.values.index = self.values.index.astype(str)
        if isinstance(self.evidence, pd.Series):
            self.evidence = self.evidence.reindex(self.values.index)
            self.evidence = self.evidence.map(lambda e: e if isinstance(e, tuple) else ())

    def evidence_for(self, items: list[str]) -> Sequence[tuple[Evidence, ...]]:
        """Evidence per item, in ``items`` order (empty tuple where there is none)."""
        if isinstance(self.evidence, RowEvidence):
            return self.evidence.take(items)
        ev = self.evidence.reindex(items)
        return [e if isinstance(e, tuple) else () for e in ev.tolist()]


class RowEvidence:
    """Per-row evidence of one table, built only when a record is written (no tuple per row)."""

    def __init__(self, file: str, sha256: str, rows: pd.Series) -> None:
        self.file, self.sha256 = file, sha256
        self.rows = rows  # index = item id, value = 1-based data row

    def take(self, items: list[str]) -> _LazyEvidence:
        rows = self.rows.reindex(items).to_numpy(dtype=float)
        return _LazyEvidence(self.file, self.sha256, rows)


class _LazyEvidence(Sequence[tuple[Evidence, ...]]):
    def __init__(self, file: str, sha256: str, rows: np.ndarray) -> None:
        self.file, self.sha256, self.rows = file, sha256, rows

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, i: int) -> tuple[Evidence, ...]:  # type: ignore[override]
        r = self.rows[i]
        if np.isnan(r):
            return ()
        return (Evidence(self.file, self.sha256, (int(r),)),)


@dataclass(frozen=True)
class EngineOptions:
    """How the engine and its providers run (typed, frozen): what ``orthospec.api.CheckOptions``
    hands down below the API layer. Only ``sample`` can change a verdict."""

    #: worker processes for raster checks (None: the engine decides, at most the cores)
    workers: int | None = None
    #: Dask distributed scheduler address (``check --scheduler``)
    scheduler: str | None = None
    #: show a progress line on stderr while rasters are scanned
    progress: bool = False
    #: ``(scope, items)`` from ``orthospec.engine.sample.read_sample``: only those items are checked
    sample: tuple[str, frozenset[str] | set[str]] | None = None
    #: raster result cache folder (results keyed by file SHA-256)
    cache_dir: str | None = None

    @classmethod
    def of(cls, options: EngineOptions | Mapping[str, Any] | None) -> EngineOptions:
        """The options as given: an EngineOptions, or a mapping of its field names (None values are the
        defaults; an unknown name is refused, never silently ignored)."""
        if options is None:
            return cls()
        if isinstance(options, EngineOptions):
            return options
        known = {f.name for f in fields(cls)}
        bad = sorted(set(options) - known)
        if bad:
            raise ValueError(
                f"unknown engine option(s) {', '.join(bad)}; known: {', '.join(sorted(known))}"
            )
        given = {k: v for k, v in options.items() if v is not None}
        if "cache_dir" in given:
            given["cache_dir"] = str(given["cache_dir"])
        return cls(**given)

    def get(self, name: str, default: Any = None) -> Any:
        """Read an option by name, as providers written against the former string-keyed mapping do."""
        return getattr(self, name, default) if name in {f.name for f in fields(self)} else default


@dataclass
class ProviderContext:
    """What a provider may read: the opened delivery, the resolved parameters, options."""

    delivery: Delivery
    parameters: Mapping[str, Any]  # name -> pint Quantity, str, bool, number
    options: EngineOptions = field(
        default_factory=EngineOptions
    )  # workers, scheduler, cache, sample
    #: shared work between providers of one run (e.g. one pass over the checkpoints)
    memo: dict[str, Any] = field(default_factory=dict)
    #: the profile's named classes (e.g. ``resolution`` of JRC §9.1), for computed class measures
    classes: Mapping[str, Any] = field(default_factory=dict)
    #: the checker's evidence for this run (delivery/checker.py ``Checker``: its file, folder, tables), None
    #: without one. It lives here, never on the ``Delivery`` (issue 26: no state carried to the next check)
    checker: Any = None
    #: the outlines the checker states (delivery/outlines.py ``StatedOutlines``), None: the manifest's are in force
    outlines: Any = None
    #: the checker's marked inspection grid (inspection/grid.py ``Grid``), None without one
    inspection: Any = None

    def block_outlines(self) -> dict[str, tuple[Any, Evidence]]:
        """Block id -> (ring, evidence) of the outlines in force for this run: the checker's when it states
        blocks, else the manifest's (``Delivery.block_outlines``; red team R13/R17)."""
        return self.delivery.block_outlines(self.outlines)

    def area_of_interest_in_force(self) -> tuple[Any, Evidence] | None:
        """(ring, evidence) of the area of interest the checker states, or None: the manifest's is in force."""
        return None if self.outlines is None else self.outlines.area_of_interest


ProviderFn = Callable[[ProviderContext], Iterable[Measured]]


@dataclass(frozen=True)
class ProviderSpec:
    fn: ProviderFn
    scope: str
    measures: Mapping[str, str]  # name -> unit
    description: str


_PROVIDERS: dict[str, ProviderSpec] = {}


def provider(*, scope: str, measures: Mapping[str, str]) -> Callable[[ProviderFn], ProviderFn]:
    """Register ``fn`` as the provider of ``measures`` (name -> unit) at ``scope``."""
    if scope not in SCOPES:
        raise ValueError(f"unknown scope {scope!r}; expected one of {', '.join(SCOPES)}")

    def deco(fn: ProviderFn) -> ProviderFn:
        spec = ProviderSpec(fn, scope, dict(measures), (fn.__doc__ or "").strip().split("\n")[0])
        for name in measures:
            if name in _PROVIDERS and _PROVIDERS[name].fn is not fn:
                raise ValueError(f"measure {name!r} is provided twice")
            _PROVIDERS[name] = spec
            spec_catalog.announce(name, scope, spec.measures[name])
        return fn

    return deco


#: Measures the evaluator computes itself in its second phase, from item verdicts.
ROLLUP: dict[str, tuple[str, str]] = {
    "rollup.image_rejected_share": ("delivery", "%"),
    "rollup.image_failed_share": ("delivery", "%"),
    "rollup.images_sampled_share": ("delivery", "%"),
    "rollup.block_rejected_share": ("project", "%"),
    "rollup.blocks_checked_share": ("project", "%"),
    "rollup.images_rejected": ("delivery", "1"),
    "rollup.blocks_rejected": ("project", "1"),
}


#: One line per measure for ``orthospec measures`` (issue 13 item 8): what the number is, so that
#: e.g. ``ce90``, ``ce90_empirical`` and ``ce90_selected`` can be told apart. One table for every
#: provider; tests/test_measures_descriptions.py fails when a registered measure has none.
MEASURE_DESCRIPTIONS: dict[str, str] = {
    # acquisition (JRC §3.4)
    "acquisition.date": (
        "the image's acquisition date from its records (exposure time, scene "
        "date, else its flight's day)"
    ),
    "acquisition.days_outside_window": (
        "days the image was acquired before or after the ITT's acquisition window (0 inside)"
    ),
    "acquisition.outside_declared_window": (
        "images acquired outside the window delivery.yaml declares (dates.acquired_from/to)"
    ),
    # satellite scenes (JRC Table 9)
    "scene.area": "area of the scene's delivered orthoimage footprint, from the raster",
    "scene.gcp_count": "GCPs of gcps.csv that controlled the scene (image_id naming it, else inside its footprint)",
    "scene.gcp_count_agrees": "the meta-database's scenes.gcp_count equals the GCPs counted in gcps.csv",
    "scene.gcp_strip_supplement": "GCPs Table 9 adds for a strip scene: 2 per additional 100 km² (parameters)",
    "scene.gcp_quadrants": (
        "quarters of the scene's orthoimage footprint holding one of its GCPs "
        "(Table 9 distribution)"
    ),
    "scene.checkpoints_on_gcps": "check points measured on the scene that are GCPs of that scene (same id or position)",
    # delivered DEM files (JRC Table 7)
    "demfile.crs_ok": "the DEM file's CRS (horizontal part) is the map projection in force (map_crs)",
    "demfile.nodata_share": "share of no-data cells of the DEM file inside the project's blocks",
    "demfile.spikes": "DEM cells farther than dem_spike_height from the median of their 3 x 3 neighbourhood",
    # sample, QCR set, GCP pattern, seamlines
    "sample.strata_missed": (
        "blocks, terrain tags, problem batches and high view angles the "
        "external-QC sample leaves out (JRC §12.4)"
    ),
    "qcr.minimum_set_missing": "QCRs of JRC Table 6 (aerial) or Table 10 (satellite) with no record in the delivery",
    "gcp_pattern.gaps": "places of the JRC Table 4 GCP pattern the block's GCPs leave empty",
    "seamline.area_selection_faults": (
        "seamline polygons outside their image's footprint or not from the most nadir image"
    ),
    "gcp.source_kind": (
        "kind of source of the GCP (survey, map, photogrammetric, orthoimage): "
        "source_type, else read from source"
    ),
    "points.shared_ids": "identifiers naming both a GCP and a check point (JRC §7.3 unique to project)",
    "scanner.schedule_gaps": "ends of the scanning period (first, last scan date) without a scanner test (JRC §6.2.2)",
    "block.space_resection_images": (
        "images of a block produced by space resection (each should be its own block, §12.7)"
    ),
    # camera, flight, geometry
    "camera.calibration_age": "years from the camera calibration certificate to the start of acquisition (JRC §5.2.4)",
    "flight.images": "number of photos of the flight",
    "flight.roll_max_abs": "largest absolute roll of the flight's photos (JRC §5.2.4)",
    "flight.roll_mean_abs": "mean absolute roll of the flight's photos (JRC §5.2.4)",
    "geometry.gsd_from_flying_height": "ground pixel of a photo from flying height and camera: H / c x pixel pitch",
    # per check point
    "checkpoint.blunder_ok": "the point is not a blunder, or it is excluded with a documented reason (JRC §12.6)",
    "checkpoint.decision": "the point's decision: kept, excluded (with reason) or blunder candidate",
    "checkpoint.dr": "radial discrepancy of the point, sqrt(dx² + dy²)",
    "checkpoint.dx": "x discrepancy of the point, image minus reference",
    "checkpoint.dy": "y discrepancy of the point, image minus reference",
    "checkpoint.dz": "z discrepancy of the point, image minus reference",
    # per block: check-point statistics
    "checkpoints.asprs_rmse_h": "ASPRS Ed. 2 horizontal accuracy: sqrt(RMSEx² + RMSEy² + survey RMSE_H²)",
    "checkpoints.asprs_rmse_v": "ASPRS Ed. 2 vertical accuracy: sqrt(RMSEz² + survey RMSE_V²)",
    "checkpoints.bias_negligible": (
        "the bias test (mean radial error / sigma_c) allows the circular-normal CE model (USGS)"
    ),
    "checkpoints.bias_p_x": "two-sided p-value of the t-test that the mean x discrepancy is zero",
    "checkpoints.bias_p_y": "two-sided p-value of the t-test that the mean y discrepancy is zero",
    "checkpoints.bias_p_z": "two-sided p-value of the t-test that the mean z discrepancy is zero",
    "checkpoints.bias_ratio": "mean radial bias over sigma_c (USGS bias test; small = negligible)",
    "checkpoints.bias_t_x": "t statistic of the mean x discrepancy (mean / (std / sqrt(n)))",
    "checkpoints.bias_t_y": "t statistic of the mean y discrepancy (mean / (std / sqrt(n)))",
    "checkpoints.bias_t_z": "t statistic of the mean z discrepancy (mean / (std / sqrt(n)))",
    "checkpoints.blunders": "blunder candidates: points beyond the maximum tolerable discrepancy (JRC §12.6)",
    "checkpoints.blunders_uninspected": "blunder candidates not excluded with a documented justification",
    "checkpoints.blunders_unjustified": "exclusion requests §12.6 does not allow (within tolerance or unjustified)",
    "checkpoints.ce90": "CE90 from the RMSE under the circular-normal model (NGA/USGS formula)",
    "checkpoints.ce90_empirical": "90th percentile of the radial discrepancies (linear percentile, no model)",
    "checkpoints.ce90_selected": "ce90 when the bias test allows the model, else ce90_empirical",
    "checkpoints.ce95": "CE95 from the RMSE under the circular-normal model (NGA/USGS formula)",
    "checkpoints.ce95_empirical": "95th percentile of the radial discrepancies (linear percentile, no model)",
    "checkpoints.duplicate_locations": "points repeating an earlier point's reference position "
                                       "(nearer than separation; JRC §12.5)",
    "checkpoints.block_cells_bad": "points whose block cell names the block but not exactly one "
                                   "block, e.g. 'B02;B02' (§12.7)",
    "checkpoints.imprecise": "points whose precision_xy exceeds tolerance_xy / "
                             "checkpoint_accuracy_factor (JRC Definitions)",
    "checkpoints.nssda_method": "how nssda_horizontal_95 was computed: equal, approximation or "
                                "elliptical (ratio < 0.6)",
    "checkpoints.screened": "check points left out of the block's statistics as not independent measurements",
    "checkpoints.separation": "distance below which two positions are one point: max(k x "
                              "tolerance_xy, n px x GSD, 1 mm)",
    "checkpoints.std_ratio": "min(std_x, std_y) / max(std_x, std_y) (seed 000 Standard Deviation Min/Max Ratio)",
    "checkpoints.zero_residuals": "points with a residual of exactly 0 in x and y: not measured on "
                                  "the image (JRC §12.6)",
    "checkpoints.ce95_selected": "ce95 when the bias test allows the model, else ce95_empirical",
    "checkpoints.excluded": "check points excluded from the statistics (with a reason)",
    "checkpoints.max_abs_dx": "largest absolute x discrepancy of the kept points",
    "checkpoints.max_abs_dy": "largest absolute y discrepancy of the kept points",
    "checkpoints.max_abs_dz": "largest absolute z discrepancy of the kept points",
    "checkpoints.max_dr": "largest radial discrepancy of the kept points",
    "checkpoints.mean_x": "mean x discrepancy of the kept points (systematic shift)",
    "checkpoints.mean_y": "mean y discrepancy of the kept points (systematic shift)",
    "checkpoints.mean_z": "mean z discrepancy of the kept points (systematic shift)",
    "checkpoints.min_gcp_distance": "smallest distance from a check point to a GCP (independence, JRC §12.4)",
    "checkpoints.n": "check points used in the statistics (after exclusions)",
    "checkpoints.n_all": "check points in the block's statistics before blunder exclusions "
                         "(screened points not counted)",
    "checkpoints.near_gcp": "points nearer to a GCP than separation (or "
                            "min_checkpoint_gcp_distance), or with a GCP's id",
    "checkpoints.nssda_approximation_holds": "RMSEmin/RMSEmax is within 0.6-1, where the NSSDA formula applies (FGDC)",
    "checkpoints.nssda_horizontal_95": "NSSDA horizontal accuracy at 95 % confidence (FGDC-STD-007.3-1998)",
    "checkpoints.nssda_ratio": "RMSEmin / RMSEmax of the two horizontal axes (NSSDA validity check)",
    "checkpoints.nssda_vertical_95": "NSSDA vertical accuracy at 95 % confidence: 1.96 x RMSEz",
    "checkpoints.outside_block": "check points outside the block polygon",
    "checkpoints.quadrant_min_share": "share of check points in the emptiest quadrant of the block (JRC §12.5)",
    "checkpoints.reported_diff_x": "|reported RMSEx - recomputed RMSEx| (contractor's value vs ours)",
    "checkpoints.reported_diff_y": "|reported RMSEy - recomputed RMSEy| (contractor's value vs ours)",
    "checkpoints.reported_diff_z": "|reported RMSEz - recomputed RMSEz| (contractor's value vs ours)",
    "checkpoints.rmse_r": "radial RMSE, sqrt(RMSEx² + RMSEy²)",
    "checkpoints.rmse_x": "RMSE of the x discrepancies of the kept points (JRC §12.7)",
    "checkpoints.rmse_x_all": "RMSE of the x discrepancies of all points, exclusions included",
    "checkpoints.rmse_x_gsd": "RMSEx in ground pixels (RMSEx / GSD)",
    "checkpoints.rmse_y": "RMSE of the y discrepancies of the kept points (JRC §12.7)",
    "checkpoints.rmse_y_all": "RMSE of the y discrepancies of all points, exclusions included",
    "checkpoints.rmse_y_gsd": "RMSEy in ground pixels (RMSEy / GSD)",
    "checkpoints.rmse_z": "RMSE of the z discrepancies of the kept points",
    "checkpoints.rmse_z_all": "RMSE of the z discrepancies of all points, exclusions included",
    "checkpoints.spacing_ratio": "smallest nearest-neighbour distance over a tenth of the points' extent diagonal",
    "checkpoints.std_x": "standard deviation of the x discrepancies of the kept points",
    "checkpoints.std_y": "standard deviation of the y discrepancies of the kept points",
    "checkpoints.std_z": "standard deviation of the z discrepancies of the kept points",
    # the checker's evidence (engine/providers/checker_evidence.py) and the contractor's internal QC
    "checker.external_checkpoints": (
        "the check point statistics are the checker's measurements "
        "(its tables/checkpoints.csv), not the contractor's"
    ),
    "checker.points_unbound": (
        "the checker's check points left out: their image_sha256 is not "
        "that of the image delivered now"
    ),
    "checker.points_unhashed": (
        "the checker's check points that record no image_sha256 (not bound to the pixels measured)"
    ),
    "inspection.inspected_share": (
        "share of the inspection grid's area (the sampled images) whose "
        "cells the checker inspected, %"
    ),
    "inspection.present": "the checker folder holds a marked inspection grid (inspection.gpkg)",
    "internal_qc.agrees": (
        "the contractor's internal-QC points and the checker's give the block "
        "the same RMSEx/RMSEy pass or fail"
    ),
    "internal_qc.imprecise": (
        "the contractor's internal-QC check points whose reference accuracy "
        "is blank or worse than tolerance_xy / 3"
    ),
    "internal_qc.n": "the contractor's internal-QC check points used in its statistics (after exclusions)",
    "internal_qc.rmse_x": "RMSE of the x discrepancies of the contractor's internal-QC check points (JRC §12.5)",
    "internal_qc.rmse_y": "RMSE of the y discrepancies of the contractor's internal-QC check points (JRC §12.5)",
    "internal_qc.rmse_z": "RMSE of the z discrepancies of the contractor's internal-QC check points",
    # derived
    "derived.camera_agrees": "the declared camera format and pixel are the model's published ones (specs/cameras.yaml)",
    "derived.dem_blocks": "blocks each DEM serves: its block value, else its footprint over the block polygons",
    "derived.block_outlines_agree": (
        "delivery.yaml's block outlines agree with those of the "
        "checker's file (within 1 %, same blocks; JRC §12.4)"
    ),
    "derived.area_of_interest_agrees": (
        "the declared area of interest agrees with the one in "
        "force from the checker's file (within 1 %; JRC §5.2.2)"
    ),
    "derived.project_crs_agrees": (
        "the manifest's project.crs names the map projection in force "
        "(parameter map_crs, JRC §12.4 Table 12)"
    ),
    "derived.dem_delivered": (
        "a DEM is delivered: the dem table names a DEM file, or "
        "product.dem_delivered is true (JRC §12.7)"
    ),
    "derived.dem_delivered_agrees": "the declared product.dem_delivered agrees with the delivered files",
    "derived.dem_used": (
        "a DEM was used: delivered, recorded in the dem table, or recorded by the "
        "scenes (dem_grid_size, dem_accuracy)"
    ),
    "derived.is_master": (
        "the scene is a master image: named in the checker's master_images, else "
        "flagged scenes.is_master (JRC Table 9)"
    ),
    "derived.master_images_agree": 'the scenes flagged is_master are exactly the checker\'s '
                                   'master_images (JRC Table 9 "identify as master image")',
    "derived.master_images": "number of scenes declared master image (scenes.is_master, JRC Table 9)",
    "derived.orthorectification": "how the orthoimages were produced, from the blocks' methods and the manifest",
    "derived.pansharpened": "the product is pan-sharpened, computed from the bands table (JRC §10.5)",
    "derived.pansharpened_agrees": "the computed pan-sharpening agrees with the manifest's declaration",
    "derived.photo_coverage": "share of the area of interest the photo lay-down covers (JRC §5.2.2)",
    "derived.resolution_class": "JRC §9.1 resolution class of the image from its pixel size",
    "derived.resolution_class_agrees": "the computed resolution class agrees with the declared one",
    # edge targets
    "edge.angle": "edge angle to the nearest pixel axis (slanted-edge health check)",
    "edge.bright_width_px": "width of the bright plateau beside the edge (health check)",
    "edge.dark_width_px": "width of the dark plateau beside the edge (health check)",
    "edge.direction": "edge orientation: along-track or across-track",
    "edge.dn_difference": "contrast: bright minus dark plateau level (health check)",
    "edge.effective_resolution_factor": "effective resolution over the nominal pixel, from the edge chain",
    "edge.fwhm": "full width at half maximum of the line spread function",
    "edge.fwhm25": "width of the line spread function at 25 % of its maximum",
    "edge.giqe4_niirs": "NIIRS predicted by GIQE 4 from the two-direction RER (USGS)",
    "edge.length_px": "length of the fitted edge (health check)",
    "edge.mtf_nyquist": "modulation transfer function at the Nyquist frequency",
    "edge.rer": "relative edge response: ESF rise between -0.5 and +0.5 px",
    "edge.rer_combined": "geometric mean of the along- and across-track RER (USGS)",
    "edge.slope": "peak slope of the normalised edge spread function, per pixel",
    "edge.snr": "edge signal-to-noise ratio: contrast over plateau noise (health check)",
    "edge.straightness_px": "largest residual of the edge points from the fitted line (health check)",
    "edge.valid": "every health check of the edge target passed",
    "edge.width80": "width of the line spread function holding 80 % of its area",
    # mosaic
    "mosaic.aoi_coverage": "share of the area of interest covered by image footprints",
    "mosaic.seamline_coverage": "share of the area of interest covered by seamline polygons",
    "mosaic.seamline_overlap": "area where seamline polygons overlap each other, % of the area of interest",
    "mosaic.seamlines_invalid": "seamline polygons that are not valid geometries",
    # rasters
    "raster.band_count": "number of bands in the image file",
    "raster.bands": "band layout of the image (e.g. R,G,B,NIR)",
    "raster.bit_depth": "radiometric bit depth declared for the image (bits per sample)",
    "raster.bit_depth_container": "bits per sample of the file's data type (8, 16, ...)",
    "raster.bit_depth_agrees": (
        "the declared bit depth is the file's: its NBITS, else between the "
        "bits used and its sample type's"
    ),
    "raster.bright_margin": "gap between the brightest DN and the top of the range, % of the range (worst band)",
    "raster.cloud_cover": (
        "measured cloud cover: share of bright, white pixels (red, green, blue; "
        "snow counts too), % (JRC §6.3)"
    ),
    "raster.cloud_cover_declared_diff": "|declared images.cloud_cover - measured cloud cover|, percentage points",
    "raster.cloud_cover_mean": 'mean of the measured cloud cover over the delivered images, % (JRC §6.3 "in average")',
    "raster.compression": "compression of the image file",
    "raster.content_unique": (
        "the image is no copy of another: not its file, SHA-256, decoded "
        "pixels or a near copy (JRC Table 12)"
    ),
    "raster.crs_epsg": "EPSG code of the image's coordinate reference system",
    "raster.crs_ok": (
        "the image's CRS is the map projection in force (parameter map_crs; missing "
        "when the profile states none)"
    ),
    "raster.cv_percent": "coefficient of variation (std / mean) of the luminosity, else of the flattest band, %",
    "raster.cv_percent_max": "largest per-band coefficient of variation (std / mean), in %",
    "raster.cv_percent_min": "smallest per-band coefficient of variation (std / mean), in %",
    "raster.dark_margin": "gap between the darkest DN and the bottom of the range, % of the range (worst band)",
    "raster.exists": "the listed image file exists in the delivery",
    "raster.file_unique": (
        "the image row names its own file: no other row names the same file or "
        "a file with the same SHA-256"
    ),
    "raster.format": "file format of the image (GDAL driver)",
    "raster.georeferenced": "the image carries a geotransform",
    "raster.gsd_declared_diff": (
        "largest |declared GSD (images.gsd, else product.gsd) - the "
        "file's pixel size| / pixel size, in %"
    ),
    "raster.in_area": (
        "the file's footprint overlaps its block's outline in force, else the area "
        "of interest (JRC §12.4 Table 12)"
    ),
    "raster.listed_missing": "images listed in the images table but not found on disk",
    "raster.lossless": "the image's compression is lossless",
    "raster.mean_dn": "mean DN of the image (all bands)",
    "raster.misregistration": "largest band-to-band misregistration, in pixels",
    "raster.name_ok": "the file name follows the naming convention (JRC §6.4)",
    "raster.nodata_declared": "the image declares a no-data value",
    "raster.nodata_share": "share of no-data pixels in the image",
    "raster.nonfinite_pixels": "float-band pixels that are NaN or +/-Inf and not no-data (excluded "
                               "from every statistic)",
    "raster.noise_std": "noise standard deviation estimated in homogeneous areas, in DN",
    "raster.noise_std_8bit": "noise_std rescaled to an 8-bit range",
    "raster.pixel_size": "ground pixel size of the image from its geotransform",
    "raster.pixel_size_diff": "|pixel size - product GSD| / GSD, in %",
    "raster.readable": "the image file opens and its pixels read without error",
    "raster.reported_max_diff": "|reported max DN - largest DN of the file| (images.max_dn vs the pixels)",
    "raster.reported_mean_diff": "|reported mean DN - computed mean DN| (contractor's value vs ours)",
    "raster.reported_min_diff": "|reported min DN - smallest DN of the file| (images.min_dn vs the pixels)",
    "raster.reported_std_diff": "|reported DN std - computed DN std| (contractor's value vs ours)",
    "raster.saturation_high": "share of pixels at the maximum value (all bands)",
    "raster.saturation_high_max_band": "share of pixels at the maximum value in the worst band",
    "raster.saturation_low": "share of pixels at the minimum value (all bands)",
    "raster.saturation_low_max_band": "share of pixels at the minimum value in the worst band",
    "raster.std_dn": "standard deviation of the image DN (all bands)",
    "raster.std_max": "largest per-band standard deviation of the DN",
    "raster.tiled": "the image file is internally tiled",
    "raster.unlisted_files": "image files on disk that the images table does not list (JRC §6.4)",
    "raster.used_bits": "bits actually used by the DN values (largest over the bands)",
    # evaluator roll-ups
    "rollup.image_rejected_share": "share of the images that are rejected",
    "rollup.image_failed_share": "share of tested images rejected, or failing/warning on a Chapter "
                                 "6 or §9.2 rule (§12.3)",
    "rollup.images_sampled_share": "share of the images in the checked sample",
    "rollup.block_rejected_share": "share of the blocks that are rejected",
    "rollup.blocks_checked_share": "share of the blocks that were checked",
    "rollup.images_rejected": "number of rejected images",
    "rollup.blocks_rejected": "number of rejected blocks",
}


def describe(name: str) -> str:
    """The one-line description of a registered or roll-up measure ('' when none)."""
    return MEASURE_DESCRIPTIONS.get(name, "")


class UnknownMeasure(MeasureError, KeyError):
    """No provider supplies this measure (a profile naming it fails validation first)."""

    def __str__(self) -> str:
        return f"no provider for measure {self.args[0]!r}"
