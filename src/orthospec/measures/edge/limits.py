"""The settings of the edge chain: the step-3 health-check limits and the method's knobs.

One frozen object instead of thirteen keyword arguments, so that a caller (the CLI, the edge
provider, the automatic edge search) states the limits once and every one of them carries its
source. Seed 003 is the CEOS WGCV IVOS edge method (Lee & Helder 2015, processing steps [RD5],
step 3 after [RD2, 2.1] and Helder 2002); "added" marks a limit the seed does not give, argued
in ``docs/edge-method.md`` (section "Health checks").
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ...errors import MeasureError


@dataclass(frozen=True)
class EdgeLimits:
    """Health-check limits (seed step 3) and method settings (steps 5-8) of :func:`measure_edge`."""

    # --- step 3: health checks (a failed one makes the edge invalid; no estimator reported)
    #: 1 (dimensionless): SNR = dDN / ((std_bright + std_dark) / 2) must exceed it; seed 3b
    #: "Uniformity on Bright and Dark area: SNR > 50 (TBR) (Helder, 2002)"
    min_snr: float = 50.0
    #: DN: bright - dark level must exceed it; seed 3c "DN difference ... > 50 (TBR) (Helder, 2002)"
    min_contrast_dn: float = 50.0
    #: deg: edge angle to the along/across direction in [0, max]; the seed's 3d "0 ~ 30 deg
    #: (TBR)" is ``standard_max_angle_deg`` (a warning beyond it); added (issue 31): up to 45 deg
    #: the ESF is sampled as finely (``max_sampling_gap_px``) and measured as accurately
    max_angle_deg: float = 45.0
    #: deg: seed 3d "0 ~ 30 deg (TBR)": an edge beyond it is measured with a warning
    standard_max_angle_deg: float = 30.0
    #: px (lines along the edge): kept lines at least this; seed 3e "> 10 ~ 20 pixels (TBR)",
    #: the upper value, for a stable line fit and ESF
    min_edge_length_px: int = 20
    #: px: median width of the dark and of the bright area beyond its plateau start must exceed
    #: it; seed 3f "Width of Bright and Dark area > 5 pixels (TBR)"
    min_plateau_width_px: float = 5.0
    #: px: largest 5-line running median of the line-fit residuals; seed 3a and TBD table D1
    #: "Limitation of Straight line by One pixel"
    max_straightness_px: float = 1.0
    #: 1: share of lines rejected as outliers by the step-5 line fit; added (a ROI where many
    #: lines miss the edge is not one straight edge)
    max_outlier_fraction: float = 0.2
    #: px: largest step between the ESF's sample positions within +-2 px of the edge; added
    #: (the seed allows 0 deg, where every line samples the same phases, 1 px apart). 0.5 px:
    #: fewer than two phases per pixel cannot resolve the LSF of a sharp system (FWHM ~1 px)
    #: and alias the MTF at Nyquist; a slope p/q samples at cos(theta)/q (1/2: 0.45 px, 1/3:
    #: 0.32 px), which the fits resolve (issue 31: the bin-occupancy refusal there was unfounded)
    max_sampling_gap_px: float = 0.5
    #: 1: largest share of a uniform area's pixels at a saturation level (zero fill counts);
    #: added (a saturated side has a tiny std and would pass the SNR check)
    max_saturated_fraction: float = 0.01

    # --- method settings
    #: px: least distance kept beyond each plateau start in the trimmed ESF; seed 7b "The width
    #: of Bright / Dark area; 1 pixel (TBR)" (the trim reaches >= 3x the start's distance)
    plateau_px: float = 1.0
    #: bins per px of the super-sampled ESF (seed 6-8: ESF of the pixel data, fitted; 10 -> the
    #: 0.1 px bins of docs/edge-method.md step 7)
    oversample: int = 10
    #: Fermi-Dirac terms of the parametric fit; seed 8a-I "Parametric (Fermi-Dirac)" (1 = the
    #: plain Fermi-Dirac function; 3 by default, docs/edge-method.md step 8)
    fermi_terms: int = 3
    #: refine the step-5 line by one least-squares Fermi-Dirac edge over all pixels within 5 px
    #: (added, docs/edge-method.md step 5g); False keeps the seed's line of cubic locations
    refine_line: bool = True

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            val = getattr(self, f.name)
            if isinstance(val, bool) != (f.name == "refine_line") or not (
                isinstance(val, bool) or (isinstance(val, numbers.Real) and math.isfinite(val))
            ):
                raise MeasureError(f"edge limit {f.name} must be a finite number, got {val!r}")
        if int(self.oversample) != self.oversample or self.oversample < 1:
            raise MeasureError(
                f"edge limit oversample must be a whole number >= 1, got {self.oversample!r}"
            )
        if int(self.fermi_terms) != self.fermi_terms or self.fermi_terms < 1:
            raise MeasureError(
                f"edge limit fermi_terms must be a whole number >= 1, got {self.fermi_terms!r}"
            )

    @classmethod
    def merged(cls, limits: EdgeLimits | None, overrides: Mapping[str, Any]) -> EdgeLimits:
        """``limits`` (default: the seed's) with some fields replaced by keyword overrides.

        Raises ``TypeError`` for a name that is not a limit, as a misspelt keyword would.
        """
        base = limits if limits is not None else cls()
        if not overrides:
            return base
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise TypeError(
                f"measure_edge() got unexpected keyword argument(s) {', '.join(unknown)}; "
                f"edge limits are {', '.join(sorted(names))}"
            )
        return dataclasses.replace(base, **overrides)

    @property
    def bin_px(self) -> float:
        """Width of one ESF bin in px (1 / oversample)."""
        return 1.0 / self.oversample
