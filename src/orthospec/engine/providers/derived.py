"""The ``derived.*`` facts, computed from the delivery's data rather than trusted as declared flags,
live in modules by subject (issue 28); this module keeps their former import path.

* orthorectification.py: ``derived.orthorectification``;
* pixel.py: the measured pixel size and ``derived.resolution_class`` / ``_agrees`` (JRC §9.1);
* camera.py: published camera formats and ``derived.camera_agrees``;
* coverage.py: the photo lay-down and ``derived.photo_coverage`` (JRC §5.2.2);
* outlines.py: ``derived.block_outlines_agree`` and ``derived.area_of_interest_agrees``;
* masters.py: ``derived.master_images``, ``derived.is_master``, ``derived.master_images_agree``;
* project_crs.py: ``derived.project_crs_agrees`` (JRC §12.4 Table 12);
* dem.py: ``derived.dem_blocks``, ``derived.dem_delivered``, ``derived.dem_used``,
  ``derived.dem_delivered_agrees``;
* pansharpening.py: ``derived.pansharpened`` / ``_agrees`` (JRC §10.5).

Their arithmetic is in measures/ (laydown.py, outlines.py, pansharpening.py, classes.py). No measure
is registered here.
"""

from __future__ import annotations

from ...measures.laydown import GSD_TOLERANCE
from ...measures.outlines import OUTLINE_TOLERANCE
from ...measures.outlines import disagreement as _disagreement
from ...measures.pansharpening import PAN_MARGIN
from .camera import CAMERA, FORMAT_COLUMNS, camera_agrees, known_camera
from .coverage import COVERAGE, photo_coverage
from .dem import DEM, DEM_PRESENCE, SCENE_DEM_COLUMNS, dem_blocks, dem_presence
from .masters import (
    MASTER,
    MASTER_AGREE,
    MASTER_EVIDENCE,
    MASTER_FLAG,
    is_master,
    master_images,
    master_images_agree,
    named_masters,
)
from .orthorectification import DELIVERY, orthorectification
from .outlines import AOI_AGREE, OUTLINES_AGREE, area_of_interest_agrees, block_outlines_agree
from .pansharpening import PANSHARPENED, pansharpened
from .pixel import IMAGE, measured_pixel_m, resolution_class
from .project_crs import PROJECT_CRS, project_crs_agrees

__all__ = [
    "AOI_AGREE",
    "CAMERA",
    "COVERAGE",
    "DELIVERY",
    "DEM",
    "DEM_PRESENCE",
    "FORMAT_COLUMNS",
    "GSD_TOLERANCE",
    "IMAGE",
    "MASTER",
    "MASTER_AGREE",
    "MASTER_EVIDENCE",
    "MASTER_FLAG",
    "OUTLINES_AGREE",
    "OUTLINE_TOLERANCE",
    "PANSHARPENED",
    "PAN_MARGIN",
    "PROJECT_CRS",
    "SCENE_DEM_COLUMNS",
    "_disagreement",
    "area_of_interest_agrees",
    "block_outlines_agree",
    "camera_agrees",
    "dem_blocks",
    "dem_presence",
    "is_master",
    "known_camera",
    "master_images",
    "master_images_agree",
    "measured_pixel_m",
    "named_masters",
    "orthorectification",
    "pansharpened",
    "photo_coverage",
    "project_crs_agrees",
    "resolution_class",
]
