"""General Image Quality Equation (GIQE): predicted NIIRS from GSD, RER, overshoot and noise.

Why: the USGS seed (``000_64edc9235d9ff7d6.txt``, "RER Notes") names RER as the input of
the GIQE, which turns the edge measures into one interpretability rating (NIIRS) that a
tender can ask for. Two published versions are implemented, each with its inputs
recorded in the result:

* **GIQE 4** (Leachtenauer, Malila, Irvine, Colburn & Salvaggio, "General Image-Quality
  Equation: GIQE", Applied Optics 36(32):8322-8328, 1997)::

      NIIRS = 10.251 - a log10(GSD_GM) + b log10(RER_GM) - 0.656 H_GM - 0.344 G / SNR
      a = 3.32, b = 1.559 if RER_GM >= 0.9;  a = 3.16, b = 2.817 otherwise

  GSD in inches, geometric means of the two image directions. H is the edge overshoot:
  the largest normalised edge response 1.0-3.0 px from the edge (0.25-px steps), or the
  value at 1.25 px if the edge rises monotonically (:func:`edge_overshoot`). G is the
  noise gain of the sharpening (MTFC) kernel, 1 without sharpening. The G/SNR
  coefficient is 0.344 as in the paper and as cited in most implementations; pyBSM
  (Kitware/AFRL) prints 0.334, a 0.003-NIIRS difference at G/SNR = 0.3.

* **GIQE 5** (NGA, "The General Image Quality Equation version 5.0", 16 Sep 2015, public
  release; as implemented in pyBSM ``giqe5``)::

      NIIRS = 9.57 - 3.32 log10(GSD) + 3.32 (1 - exp(-1.9 / SNR)) log10(RER)
              - 2 (log10 RER)^4 - 1.8 / SNR
      RER = (max(RER_x, RER_y) * min(RER_x, RER_y)^2)^(1/3)

  GSD in inches. NGA's worked case (its Figure 1): RER 0.35, GSD 20.8 in, SNR 50 gives
  NIIRS 5.0 (tested). No overshoot or noise-gain term: version 5 rates the unsharpened
  image.

GSD here is the ground sample distance of the product (orthoimages are already in the
ground plane, so neither version's elevation-angle correction is applied; pass the
geometric-mean ground GSD). Both versions are regressions on rated imagery with a
standard error of about 0.3 NIIRS; outside RER 0.2-1.3 or SNR < 2 they extrapolate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import MeasureError

__all__ = ["GIQE4", "GIQE5", "GiqeResult", "edge_overshoot", "giqe4", "giqe5"]

INCH_M = 0.0254

# Leachtenauer et al. 1997, Applied Optics 36(32), eq. (1)
GIQE4 = {
    "c0": 10.251,
    "a_rer_ge_0.9": 3.32, "b_rer_ge_0.9": 1.559,
    "a_rer_lt_0.9": 3.16, "b_rer_lt_0.9": 2.817,
    "h": 0.656, "g_over_snr": 0.344,
}
# NGA GIQE 5.0, 16 Sep 2015
GIQE5 = {"a0": 9.57, "a1": -3.32, "a2": 3.32, "a3": -1.9, "a4": -2.0, "a5": -1.8}


@dataclass(frozen=True)
class GiqeResult:
    """A predicted NIIRS with the version, the inputs as used and the coefficients."""

    version: str
    niirs: float
    inputs: dict[str, float]
    coefficients: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"giqe.version": self.version, "giqe.niirs": self.niirs}
        out.update({f"giqe.input.{k}": v for k, v in self.inputs.items()})
        return out


def _positive(name: str, value: float, allow_inf: bool = False) -> float:
    v = float(value)
    if not (v > 0 and (math.isfinite(v) or allow_inf)):
        raise MeasureError(f"GIQE input {name} must be a positive number, got {value!r}")
    return v


def giqe4(*, gsd_m: float, rer: float, overshoot: float = 1.0, noise_gain: float = 1.0,
          snr: float = math.inf) -> GiqeResult:
    """GIQE 4 NIIRS (Leachtenauer et al. 1997) from geometric-mean GSD (m), RER, H, G and SNR.

    ``snr = inf`` drops the noise term (a noise-free prediction); H defaults to 1.0 (an
    edge that rises monotonically to its plateau), G to 1.0 (no sharpening).
    """
    gsd = _positive("gsd_m", gsd_m)
    r = _positive("rer", rer)
    h = float(overshoot)
    g = _positive("noise_gain", noise_gain)
    s = _positive("snr", snr, allow_inf=True)
    c = GIQE4
    hi = r >= 0.9
    a = c["a_rer_ge_0.9"] if hi else c["a_rer_lt_0.9"]
    b = c["b_rer_ge_0.9"] if hi else c["b_rer_lt_0.9"]
    niirs = (c["c0"] - a * math.log10(gsd / INCH_M) + b * math.log10(r)
             - c["h"] * h - c["g_over_snr"] * g / s)
    return GiqeResult("4", niirs, {
        "gsd_m": gsd, "gsd_in": gsd / INCH_M, "rer": r, "overshoot_h": h, "noise_gain": g,
        "snr": s}, {"c0": c["c0"], "a": a, "b": b, "h": c["h"], "g_over_snr": c["g_over_snr"]})


def giqe5(*, gsd_m: float, rer_x: float, rer_y: float | None = None,
          snr: float = math.inf) -> GiqeResult:
    """GIQE 5 NIIRS (NGA 2015) from GSD (m), the RER of two directions and SNR.

    With one RER (``rer_y`` None) both directions take it.
    """
    gsd = _positive("gsd_m", gsd_m)
    rx = _positive("rer_x", rer_x)
    ry = rx if rer_y is None else _positive("rer_y", rer_y)
    s = _positive("snr", snr, allow_inf=True)
    rer = (max(rx, ry) * min(rx, ry) ** 2) ** (1.0 / 3.0)
    c = GIQE5
    lr = math.log10(rer)
    niirs = (c["a0"] + c["a1"] * math.log10(gsd / INCH_M)
             + c["a2"] * (1.0 - math.exp(c["a3"] / s)) * lr + c["a4"] * lr**4 + c["a5"] / s)
    return GiqeResult("5", niirs, {
        "gsd_m": gsd, "gsd_in": gsd / INCH_M, "rer_x": rx, "rer_y": ry, "rer": rer, "snr": s},
        dict(c))


def edge_overshoot(esf_at: Any, centre_px: float) -> float:
    """GIQE overshoot H of a normalised edge response (0 dark .. 1 bright).

    Leachtenauer et al. 1997: "measured over the range of 1.0 to 3.0 pixels from the edge
    in 0.25-pixel increments. If the edge is monotonically increasing, it is defined as
    the value at 1.25 pixels from the edge."
    """
    d = centre_px + np.arange(1.0, 3.0 + 1e-9, 0.25)
    e = np.asarray(esf_at(d), dtype=float)
    # "monotonically increasing" up to rounding (1e-9 of the step), so that the choice
    # between the two readings does not flip on numerical noise
    if np.all(np.diff(e) >= -1e-9):
        return float(esf_at(np.array([centre_px + 1.25]))[0])
    return float(e.max())
