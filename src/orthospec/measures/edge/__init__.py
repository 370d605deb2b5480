"""Spatial quality from an edge target: the CEOS WGCV IVOS 12-step method.

Source: seed ``003_ceb4b69be8905903.txt`` (Lee & Helder 2015, "Edge target for
Spatial Quality", processing steps [RD5]); RER two-direction form from seed
``000_64edc9235d9ff7d6.txt`` (USGS); effective resolution from seed
``004_0930f95275292898.txt`` (Passini, Jacobsen, Day). ``docs/edge-method.md``
explains every choice where the seed says TBD/TBR/TBC.

The chain (seed step in brackets) on a 2-D ROI holding one straight edge:

* orientation [4a]: the ROI is transposed so that the edge runs near the
  columns (profile along x), and mirrored so that dark is left, bright right
  [4b]. Everything below runs in that working frame, so results do not depend
  on edge polarity or on transposing the image.
* per line [5a-c]: largest adjacent difference, cubic through the four pixels
  around it, edge at the cubic's inflection point.
* robust line [5d-f]: least squares of all locations, iteratively rejecting
  lines beyond 3 robust sigmas (1.4826 MAD, floor 0.05 px); angle to the
  along/across direction.
* ESF [6]: every pixel of the kept lines at its *perpendicular* distance
  ``d = (x - x_edge(y)) cos(theta)`` from the fitted line.
* plateaus [7]: cubic smoothing spline of the binned ESF; the starts of the dark
  and bright plateaus are the LSF's inflection points (extrema of ESF'');
  the uniform areas begin at 3x the start's distance from the centre (>= 1 px
  beyond it) or where the LSF falls below 2 % of its peak, whichever is further;
  the ESF is trimmed at max(``plateau_px``, 3x the start's distance, 1 px into
  the uniform area) beyond each start; the dark/bright levels and the
  uniformity (SNR) come from the uniform areas.
* fits [8]: a physical model (added): the PSF (Gaussian, x box, x disk, core + halo,
  unsharp-masked, diffraction-limited pupil) integrated over the square pixel at the measured
  angle, chosen by its leave-one-out error (issue 31), primary when its lack-of-fit F test
  passes (else the better of it and the spline out of sample); every RER, FWHM and MTF@Ny
  with a standard uncertainty (noise and the spread of the plausible models); non-parametric (GCV
  cubic smoothing spline, scipy's criterion in numpy, on the ESF
  binned at 1/``oversample`` px, weighted by counts) and parametric (sum of
  Fermi-Dirac functions); both normalised 0..1.
* RER [9] at +-0.5 px around the centre (LSF peak for the spline, ESF = 0.5
  for the parametric fit, as the seed says); LSF [10] by differentiation;
  FWHM and widths at 25 % / 80 % [11]; MTF [12] by FFT of the LSF normalised
  at zero frequency, value at Nyquist (0.5 cycles/px).

Health checks [3] fail with their measured values; then ``valid`` is False and
no estimator is reported. Only malformed input raises :class:`MeasureError`.

Layout (one module per group of steps; each imports only modules listed before it):
``limits`` (:class:`EdgeLimits`: the step-3 limits and method settings, with sources),
``result`` (the returned types and shared constants), ``bins`` (binned ESF, smoothing
spline), ``estimators`` (steps 9-12 on a fit, primary fit, USGS RER), ``fits`` (step 8:
spline, Fermi-Dirac), ``pupil`` (the diffraction-limited PSF), ``model`` (step 8: the physical
PSF models, their choice and the uncertainty), ``locate`` (steps 4-5),
``esf`` (steps 6-7), ``health`` (step 3), ``chain`` (:func:`measure_edge`).
"""

from __future__ import annotations

from .chain import measure_edge
from .estimators import rer_two_directions
from .limits import EdgeLimits
from .result import (
    DIRECTION_CONVENTION,
    ESTIMATORS,
    NYQUIST,
    PSF_FITS,
    SPLINE,
    EdgeFit,
    EdgeResult,
    Estimate,
    HealthCheck,
)

__all__ = [
    "DIRECTION_CONVENTION",
    "ESTIMATORS",
    "NYQUIST",
    "PSF_FITS",
    "SPLINE",
    "EdgeFit",
    "EdgeLimits",
    "EdgeResult",
    "Estimate",
    "HealthCheck",
    "measure_edge",
    "rer_two_directions",
]
