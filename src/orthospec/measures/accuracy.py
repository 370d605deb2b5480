"""Checkpoint accuracy statistics: RMSE, NSSDA, CE90/CE95, bias test, blunders.

Pure numpy, no I/O. Sources:

* USGS in-situ geometric characterisation (seed ``000_...``): ``ΔX = X_input - X_control``,
  ``RMSE = sqrt(ΣΔ²/n)``, ``RMSE_net = sqrt(RMSE_x² + RMSE_y²)``,
  ``CE90 = 2.1460/2·(RMSE_x + RMSE_y)``, ``CE95 = 2.4477/2·(RMSE_x + RMSE_y)``, standard
  deviations with ``n-1``, ``σ_c = (σ_x + σ_y)/2``, ``μ_H = sqrt(μ_x² + μ_y²)``; when the bias
  is not negligible CE90/CE95 are the 90th/95th percentiles of ``ΔR = sqrt(ΔX² + ΔY²)``.
* FGDC-STD-007.3-1998 (NSSDA): horizontal accuracy at 95 % is ``1.7308·RMSE_r`` when
  ``RMSE_x = RMSE_y`` and approximately ``2.4477·0.5·(RMSE_x + RMSE_y)`` when
  ``RMSE_min/RMSE_max`` is in [0.6, 1.0]; vertical accuracy at 95 % is ``1.9600·RMSE_z``. Below
  0.6 the closed form does not hold and :func:`elliptical_radius` computes what it approximates:
  the radius holding 95 % of a normal error independent in x and y (the model the NSSDA states,
  after Greenwalt and Schultz 1968, whose 2.4477 = sqrt(-2 ln 0.05) is its circular case).
* JRC EUR 23638 EN §12.6 (maximum tolerable discrepancy = 3 × calculated RMSE) and Table 9
  ("Maximum residual should not exceed 3 x the target RMSE").

Every length statistic is in the unit of the input deltas (``unit``); :meth:`AccuracyStats.in_gsd`
gives the same statistics in multiples of the GSD.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from typing import Any, Literal

import numpy as np
import pandas as pd

from ..errors import MeasureError

__all__ = [
    "BIAS_RATIO_LIMIT",
    "CE90_FACTOR",
    "CE95_FACTOR",
    "NSSDA_EQUAL_FACTOR",
    "NSSDA_RATIO_RANGE",
    "NSSDA_VERTICAL_FACTOR",
    "AccuracyStats",
    "BlunderDecision",
    "BlunderResult",
    "accuracy_stats",
    "bias_significance",
    "ce90_formula",
    "ce95_formula",
    "deltas_from_coordinates",
    "detect_blunders",
    "elliptical_radius",
    "empirical_percentile",
    "nssda_horizontal",
    "rmse_net",
    "str_ids",
]

#: USGS/FGDC circular-error factors (seed 000: "These equations may be found in FGDC-STD-007.3-1998").
CE90_FACTOR = 2.1460
CE95_FACTOR = 2.4477
#: NSSDA factor for RMSE_r when RMSE_x = RMSE_y (FGDC-STD-007.3-1998, Appendix 3-A).
NSSDA_EQUAL_FACTOR = 1.7308
#: NSSDA vertical factor at 95 % for RMSE_z.
NSSDA_VERTICAL_FACTOR = 1.9600
#: Range of RMSE_min/RMSE_max where the NSSDA approximation 2.4477·0.5·(RMSE_x+RMSE_y) holds.
NSSDA_RATIO_RANGE = (0.6, 1.0)
#: Bias is not negligible when μ_H/σ_c exceeds this (seed 000).
BIAS_RATIO_LIMIT = 0.1

PercentileMethod = Literal["linear", "nearest-rank"]
_NUMPY_METHOD = {"linear": "linear", "nearest-rank": "inverted_cdf"}

# Fields of AccuracyStats that are lengths (scale with the input, divide by the GSD).
_LENGTH_FIELDS = (
    "mean_x",
    "mean_y",
    "mean_z",
    "std_x",
    "std_y",
    "std_z",
    "rmse_x",
    "rmse_y",
    "rmse_z",
    "rmse_r",
    "nssda_horizontal_95",
    "nssda_vertical_95",
    "ce90",
    "ce95",
    "sigma_c",
    "mu_h",
    "ce90_empirical",
    "ce95_empirical",
    "max_abs_dx",
    "max_abs_dy",
    "max_abs_dz",
    "max_dr",
)


# --------------------------------------------------------------------------- formulas


def rmse_net(rmse_x: Any, rmse_y: Any) -> Any:
    """``RMSE_net = RMSE_r = sqrt(RMSE_x² + RMSE_y²)`` (seed 000), elementwise."""
    return np.hypot(rmse_x, rmse_y)


def ce90_formula(rmse_x: Any, rmse_y: Any) -> Any:
    """``CE90 = 2.1460/2·(RMSE_x + RMSE_y)`` (seed 000), valid when bias is negligible."""
    return CE90_FACTOR / 2.0 * (np.asarray(rmse_x, dtype=float) + np.asarray(rmse_y, dtype=float))


def ce95_formula(rmse_x: Any, rmse_y: Any) -> Any:
    """``CE95 = 2.4477/2·(RMSE_x + RMSE_y)`` (seed 000), valid when bias is negligible."""
    return CE95_FACTOR / 2.0 * (np.asarray(rmse_x, dtype=float) + np.asarray(rmse_y, dtype=float))


#: Gauss-Legendre nodes of :func:`elliptical_probability` (the integrand is smooth: 96 give ~1e-12)
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(96)


def elliptical_probability(r: float, sigma_x: float, sigma_y: float) -> float:
    """P(sqrt(X² + Y²) <= r) for X ~ N(0, sigma_x²), Y ~ N(0, sigma_y²) independent.

    ``P = ∫ φ(x/σx)/σx · (2Φ(sqrt(r² - x²)/σy) - 1) dx`` over ``|x| <= r``, with ``x = r sin t``
    (smooth on [-π/2, π/2]) by Gauss-Legendre. ``sigma_y = 0`` is the one-dimensional case."""
    from scipy.special import ndtr

    if r <= 0:
        return 0.0
    if sigma_x <= 0 or sigma_y <= 0:
        s = max(sigma_x, sigma_y)
        return 1.0 if s == 0 else float(2.0 * ndtr(r / s) - 1.0)
    t = 0.5 * math.pi * _GL_NODES
    x, w = r * np.sin(t), r * np.cos(t)
    with np.errstate(
        over="ignore"
    ):  # w / sigma_y overflows to inf for a tiny sigma_y: ndtr(inf) = 1
        inner = 2.0 * ndtr(w / sigma_y) - 1.0
    dens = np.exp(-0.5 * (x / sigma_x) ** 2) / (sigma_x * math.sqrt(2.0 * math.pi))
    return float(0.5 * math.pi * np.sum(_GL_WEIGHTS * dens * inner * w))


def elliptical_radius(sigma_x: float, sigma_y: float, p: float = 0.95) -> float:
    """The radius holding ``p`` of a normal error independent in x and y (circular error of an
    elliptical distribution). It lies between the one-dimensional quantile of the larger sigma
    (1.9600·σmax at 95 %) and the circular one (2.4477·σmax), where the root is bracketed."""
    from scipy.optimize import brentq
    from scipy.special import ndtri

    hi_s, lo_s = max(sigma_x, sigma_y), min(sigma_x, sigma_y)
    if hi_s <= 0:
        return 0.0
    lo = float(ndtri(0.5 + p / 2.0)) * hi_s  # P(|X| <= r) = p: a lower bound
    hi = math.sqrt(-2.0 * math.log(1.0 - p)) * hi_s  # both sigmas = σmax: an upper bound
    if lo_s <= 0:
        return lo

    def gap(r: float) -> float:
        return elliptical_probability(r, hi_s, lo_s) - p

    # at the ends of the bracket the quadrature may land a hair on the wrong side: the end is the root
    if gap(lo) >= 0:
        return lo
    if gap(hi) <= 0:
        return hi
    return float(brentq(gap, lo, hi, xtol=1e-12 * hi_s))


def nssda_horizontal(rmse_x: float, rmse_y: float) -> tuple[float, float, bool, str]:
    """NSSDA horizontal accuracy at 95 % (FGDC-STD-007.3-1998).

    Returns ``(accuracy, ratio, holds, method)``: ``ratio = RMSE_min/RMSE_max`` (1 when both
    are zero); ``method`` is ``"equal"`` (1.7308·RMSE_r, exact case RMSE_x = RMSE_y),
    ``"approximation"`` (2.4477·0.5·(RMSE_x+RMSE_y), 0.6 <= ratio <= 1) or ``"elliptical"``:
    below 0.6 the closed form does not hold (``holds`` False) and the accuracy is the radius
    holding 95 % of the normal error with sigmas RMSE_x and RMSE_y (:func:`elliptical_radius`),
    the computation the closed form approximates - a method switch, never a failure.
    """
    lo, hi = min(rmse_x, rmse_y), max(rmse_x, rmse_y)
    ratio = 1.0 if hi == 0.0 else lo / hi
    if rmse_x == rmse_y:
        return NSSDA_EQUAL_FACTOR * math.hypot(rmse_x, rmse_y), ratio, True, "equal"
    if NSSDA_RATIO_RANGE[0] <= ratio <= NSSDA_RATIO_RANGE[1]:
        return CE95_FACTOR * 0.5 * (rmse_x + rmse_y), ratio, True, "approximation"
    return elliptical_radius(rmse_x, rmse_y, 0.95), ratio, False, "elliptical"


def empirical_percentile(values: Any, q: float, *, method: PercentileMethod = "linear") -> float:
    """The ``q``-th percentile of ``values`` as the seed's "90% {ΔR}".

    ``method="linear"`` is Hyndman & Fan type 7 (numpy's default): with the sorted values
    ``v_0..v_{n-1}``, ``h = (n-1)·q/100`` and the result ``v_⌊h⌋ + (h-⌊h⌋)(v_⌊h⌋+1 - v_⌊h⌋)``.
    ``method="nearest-rank"`` is Hyndman & Fan type 1: the smallest value such that at least
    q % of the values are <= it, i.e. ``v_{⌈q·n/100⌉-1}`` (never interpolates, never below
    the share of points it claims).
    """
    if method not in _NUMPY_METHOD:
        raise MeasureError(f"percentile method {method!r} unknown; use 'linear' or 'nearest-rank'")
    arr = np.asarray(values, dtype=float)
    if arr.size == 0:
        raise MeasureError("percentile of an empty set of values")
    return float(np.percentile(arr, q, method=_NUMPY_METHOD[method]))  # type: ignore[call-overload]


# --------------------------------------------------------------------------- validation


def str_ids(ids: Sequence[Any] | np.ndarray) -> np.ndarray:
    """Ids as a 1-D object array of str: an object array that holds only str already (a table's
    id column) as it is (one C scan says so), else each converted (``map`` in C)."""
    if isinstance(ids, np.ndarray) and ids.dtype == object and ids.ndim == 1:
        if pd.api.types.infer_dtype(ids, skipna=False) in ("string", "empty"):
            return ids
        return np.fromiter(map(str, ids), dtype=object, count=ids.size)
    return np.asarray([str(i) for i in ids], dtype=object)


def _as_ids(ids: Sequence[Any] | np.ndarray | None, n: int) -> np.ndarray:
    """Point ids as an object array of str."""
    if ids is None:
        return np.arange(n).astype(str).astype(object)
    arr = str_ids(ids)
    if arr.shape != (n,):
        raise MeasureError(f"{arr.size} point ids given for {n} points")
    return arr


def _validate(
    arrays: Mapping[str, np.ndarray | None], ids: np.ndarray, *, min_points: int = 2
) -> None:
    """Shape, count, finiteness and id-uniqueness checks that name the offending points."""
    n = ids.size
    for name, arr in arrays.items():
        if arr is None:
            continue
        if arr.ndim != 1 or arr.size != n:
            raise MeasureError(f"{name} has shape {arr.shape}; expected ({n},) like the point ids")
    if n < min_points:
        raise MeasureError(f"{n} point(s) given; at least {min_points} are needed for statistics")
    repeated = pd.Index(ids, dtype=object).duplicated()  # hashing, not sorting a fixed-width copy
    if repeated.any():
        dup = ", ".join(sorted(set(ids[repeated].tolist()))[:20])
        raise MeasureError(f"duplicate point ids: {dup}")
    for name, arr in arrays.items():
        if arr is None:
            continue
        bad = ~np.isfinite(arr)
        if bad.any():
            shown = ", ".join(ids[bad][:20])
            more = f" (+{int(bad.sum()) - 20} more)" if bad.sum() > 20 else ""
            raise MeasureError(f"{name} is not a finite number for point(s) {shown}{more}")


def _f(a: Any) -> np.ndarray | None:
    return None if a is None else np.asarray(a, dtype=float)


def deltas_from_coordinates(
    x: Any, y: Any, x_ref: Any, y_ref: Any, z: Any = None, z_ref: Any = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Deltas image minus reference, ``ΔX = X_input - X_control`` (seed 000)."""
    if (z is None) != (z_ref is None):
        raise MeasureError("z and z_ref must be given together")
    dx = np.asarray(x, dtype=float) - np.asarray(x_ref, dtype=float)
    dy = np.asarray(y, dtype=float) - np.asarray(y_ref, dtype=float)
    dz = None if z is None else np.asarray(z, dtype=float) - np.asarray(z_ref, dtype=float)
    return dx, dy, dz


# --------------------------------------------------------------------------- statistics


@dataclass(frozen=True)
class AccuracyStats:
    """Summary statistics of checkpoint discrepancies (lengths in ``unit``).

    Bias decision: the seed writes the test as ``μ_x/σ_c > 0.1`` but its results table
    tabulates ``μ_H/σ_c``; ``μ_x`` alone would ignore a purely northing bias and its sign, so
    :attr:`bias_negligible` uses ``bias_ratio = μ_H/σ_c`` and :attr:`bias_ratio_x` =
    ``|μ_x|/σ_c`` is reported beside it. ``σ_c = 0`` with a non-zero bias gives ``inf``.
    """

    n: int
    unit: str
    mean_x: float
    mean_y: float
    mean_z: float | None
    std_x: float
    std_y: float
    std_z: float | None
    rmse_x: float
    rmse_y: float
    rmse_z: float | None
    rmse_r: float
    #: NSSDA horizontal accuracy at 95 % and how it was obtained
    nssda_horizontal_95: float
    nssda_ratio: float
    nssda_approximation_holds: bool
    nssda_method: str
    nssda_vertical_95: float | None
    #: USGS/FGDC formula values (valid when bias is negligible)
    ce90: float
    ce95: float
    #: bias test (seed 000)
    sigma_c: float
    mu_h: float
    std_ratio: float
    bias_ratio: float
    bias_ratio_x: float
    bias_negligible: bool
    #: empirical percentiles of ΔR and the definition used
    ce90_empirical: float
    ce95_empirical: float
    percentile_method: str
    max_abs_dx: float
    max_abs_dy: float
    max_abs_dz: float | None
    max_dr: float
    gsd: float | None = None

    @property
    def ce90_selected(self) -> float:
        """CE90 the seed says to use: the formula if bias is negligible, else empirical."""
        return self.ce90 if self.bias_negligible else self.ce90_empirical

    @property
    def ce95_selected(self) -> float:
        return self.ce95 if self.bias_negligible else self.ce95_empirical

    @property
    def ce_method(self) -> str:
        return "formula" if self.bias_negligible else "empirical"

    def in_gsd(self) -> AccuracyStats:
        """The same statistics with every length divided by the GSD (unit ``px``)."""
        if self.gsd is None:
            raise MeasureError("no GSD given: statistics cannot be expressed in GSD units")
        changes: dict[str, Any] = {
            name: (None if getattr(self, name) is None else getattr(self, name) / self.gsd)
            for name in _LENGTH_FIELDS
        }
        return replace(self, unit="px", **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain values (absent axes are None), plus the selected CE values."""
        out: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        out["ce90_selected"] = self.ce90_selected
        out["ce95_selected"] = self.ce95_selected
        out["ce_method"] = self.ce_method
        return out


def _axis(d: np.ndarray) -> tuple[float, float, float, float]:
    """mean, std (n-1), rmse (n), max |d| of one axis.

    The RMSE is computed on ``d / max|d|`` and scaled back so tiny deltas do not underflow
    (a zero RMSE with non-zero deltas would make every point a blunder).
    """
    mean = float(d.mean())
    std = float(d.std(ddof=1))
    peak = float(np.abs(d).max())
    if peak == 0.0:
        return mean, std, 0.0, 0.0
    u = d / peak
    rmse = peak * float(np.sqrt(np.mean(u * u)))
    return mean, std, rmse, peak


def accuracy_stats(
    dx: Any,
    dy: Any,
    dz: Any = None,
    *,
    ids: Sequence[Any] | np.ndarray | None = None,
    gsd: float | None = None,
    unit: str = "m",
    percentile_method: PercentileMethod = "linear",
    validate: bool = True,
) -> AccuracyStats:
    """Statistics of checkpoint deltas (image minus reference) per seed 000 and NSSDA.

    Parameters
    ----------
    dx, dy, dz
        Deltas per point in ``unit``; ``dz`` optional (DEM / vertical checkpoints).
    ids
        Point ids used in error messages; default the 0-based positions.
    gsd
        Ground sample distance in ``unit`` per pixel; enables :meth:`AccuracyStats.in_gsd`.
    percentile_method
        Definition of the empirical CE90/CE95 percentiles, see :func:`empirical_percentile`.
    validate
        Skip id checks when the caller already validated (large benchmarks).

    Raises
    ------
    MeasureError
        Fewer than 2 points, non-finite values, duplicate ids, mismatched shapes, bad GSD.
    """
    ax, ay, az = _f(dx), _f(dy), _f(dz)
    assert ax is not None and ay is not None
    n = int(ax.size)
    if validate:
        id_arr = _as_ids(ids, n)
        _validate({"dx": ax, "dy": ay, "dz": az}, id_arr)
    elif n < 2:
        raise MeasureError(f"{n} point(s) given; at least 2 are needed for statistics")
    if gsd is not None and not (math.isfinite(gsd) and gsd > 0):
        raise MeasureError(f"GSD must be a positive number, got {gsd!r}")

    mx, sx, rx, maxx = _axis(ax)
    my, sy, ry, maxy = _axis(ay)
    mz: float | None = None
    sz: float | None = None
    rz: float | None = None
    maxz: float | None = None
    nssda_v: float | None = None
    if az is not None:
        mz, sz, rz, maxz = _axis(az)
        nssda_v = NSSDA_VERTICAL_FACTOR * rz

    rr = float(math.hypot(rx, ry))
    nssda_h, ratio, holds, method = nssda_horizontal(rx, ry)
    sigma_c = (sx + sy) / 2.0
    mu_h = math.hypot(mx, my)
    std_ratio = 1.0 if max(sx, sy) == 0 else min(sx, sy) / max(sx, sy)
    bias_ratio = _safe_ratio(mu_h, sigma_c)
    bias_ratio_x = _safe_ratio(abs(mx), sigma_c)
    dr = np.hypot(ax, ay)
    return AccuracyStats(
        n=n,
        unit=unit,
        mean_x=mx,
        mean_y=my,
        mean_z=mz,
        std_x=sx,
        std_y=sy,
        std_z=sz,
        rmse_x=rx,
        rmse_y=ry,
        rmse_z=rz,
        rmse_r=rr,
        nssda_horizontal_95=float(nssda_h),
        nssda_ratio=float(ratio),
        nssda_approximation_holds=bool(holds),
        nssda_method=method,
        nssda_vertical_95=nssda_v,
        ce90=float(ce90_formula(rx, ry)),
        ce95=float(ce95_formula(rx, ry)),
        sigma_c=sigma_c,
        mu_h=mu_h,
        std_ratio=std_ratio,
        bias_ratio=bias_ratio,
        bias_ratio_x=bias_ratio_x,
        bias_negligible=bool(bias_ratio <= BIAS_RATIO_LIMIT),
        ce90_empirical=empirical_percentile(dr, 90, method=percentile_method),
        ce95_empirical=empirical_percentile(dr, 95, method=percentile_method),
        percentile_method=percentile_method,
        max_abs_dx=maxx,
        max_abs_dy=maxy,
        max_abs_dz=maxz,
        max_dr=float(dr.max()),
        gsd=gsd,
    )


def bias_significance(
    mean: float | None, std: float | None, n: int
) -> tuple[float | None, float | None]:
    """One-sample Student t of a mean error and its two-sided p-value: systematic error per axis.

    ``t = |μ| / (σ/√n)`` with ``σ`` the standard deviation with ``n-1`` (the seed 000 definition,
    ``σ_x = sqrt(Σ(ΔX-μ_x)²/(n-1))``), and ``p = 2·(1 - F_t(t; n-1))``. The USGS bias ratio
    ``μ/σ`` (seed 000: "If μ_x/σ_c > 0.1, then bias is not negligible") says how large the mean
    is against the spread; ``t`` says whether it is distinguishable from zero with n points, so a
    uniform 0.45 m shift under a 0.5 m tolerance is found even though the RMSE passes (JRC §12.4
    asks for a guard against systematic error). Returns ``(None, None)`` for ``n < 2`` or an
    absent axis; ``σ = 0`` gives ``t = inf, p = 0`` for a non-zero mean and ``t = 0, p = 1`` for
    a zero mean.
    """
    if mean is None or std is None or n < 2 or not (math.isfinite(mean) and math.isfinite(std)):
        return None, None
    if std == 0.0:
        return (0.0, 1.0) if mean == 0.0 else (math.inf, 0.0)
    # Student's t survival function sf(t; k) = stdtr(k, -t), exactly what scipy.stats.t.sf
    # computes, without importing scipy.stats (~0.25 s of every check's start-up)
    from scipy.special import stdtr

    t = abs(mean) / (std / math.sqrt(n))
    return float(t), float(2.0 * stdtr(n - 1, -t))


def _safe_ratio(num: float, den: float) -> float:
    if den > 0:
        return num / den
    return 0.0 if num == 0 else math.inf


# --------------------------------------------------------------------------- blunders

BlunderBasis = Literal["calculated", "target"]

#: decision values, one per point
KEPT = "kept"  # within the maximum tolerable discrepancy
CANDIDATE_KEPT = "candidate_kept"  # exceeds it, no exclusion requested
EXCLUDED = "excluded"  # exceeds it and the exclusion is justified
ERROR_WITHIN_TOLERANCE = "error_within_tolerance"  # exclusion requested but within tolerance
ERROR_NO_JUSTIFICATION = "error_no_justification"  # exclusion requested without justification


@dataclass(frozen=True)
class BlunderDecision:
    """The blunder decision for one checkpoint (one QCR record each)."""

    point_id: str
    dx: float
    dy: float
    dz: float | None
    dr: float
    exceeds_x: bool
    exceeds_y: bool
    exceeds_z: bool
    exceeds_r: bool
    candidate: bool
    exclusion_requested: bool
    justification: str
    decision: str
    reason: str

    @property
    def is_error(self) -> bool:
        return self.decision in (ERROR_WITHIN_TOLERANCE, ERROR_NO_JUSTIFICATION)


@dataclass(frozen=True)
class BlunderResult:
    """Blunder screening of a checkpoint set (JRC §12.6, Table 9).

    Per-point results are arrays (vectorised); :attr:`decisions` turns them into one
    :class:`BlunderDecision` per point for QCRs. ``stats_all`` uses every point;
    ``stats_kept`` drops only the justified exclusions (None when fewer than 2 points would
    remain, see ``note``).
    """

    basis: str
    factor: float
    limit_x: float
    limit_y: float
    limit_z: float | None
    limit_r: float
    stats_all: AccuracyStats
    stats_kept: AccuracyStats | None
    ids: np.ndarray = field(repr=False, compare=False)
    dx: np.ndarray = field(repr=False, compare=False)
    dy: np.ndarray = field(repr=False, compare=False)
    dz: np.ndarray | None = field(repr=False, compare=False)
    exceeds_x: np.ndarray = field(repr=False, compare=False)
    exceeds_y: np.ndarray = field(repr=False, compare=False)
    exceeds_z: np.ndarray = field(repr=False, compare=False)
    exceeds_r: np.ndarray = field(repr=False, compare=False)
    decision: np.ndarray = field(repr=False, compare=False)  # one decision string per point
    justifications: dict[str, str] = field(repr=False, compare=False, default_factory=dict)
    note: str = ""

    # Derived per-point arrays are cached (the dataclass is frozen and has no slots, so
    # ``cached_property`` writes the instance ``__dict__``): a national delivery has millions of
    # points, and rebuilding them on every access was the check-point path's main cost.
    @cached_property
    def candidate(self) -> np.ndarray:
        return self.exceeds_x | self.exceeds_y | self.exceeds_z

    @cached_property
    def dr(self) -> np.ndarray:
        """Radial discrepancy ``ΔR = sqrt(ΔX² + ΔY²)`` per point."""
        return np.hypot(self.dx, self.dy)

    @cached_property
    def is_error(self) -> np.ndarray:
        """Per point: an exclusion request that §12.6 does not allow (kept, reported as error)."""
        return (self.decision == ERROR_WITHIN_TOLERANCE) | (self.decision == ERROR_NO_JUSTIFICATION)

    @property
    def candidates(self) -> tuple[str, ...]:
        return tuple(self.ids[self.candidate].tolist())

    @property
    def excluded(self) -> tuple[str, ...]:
        return tuple(self.ids[self.decision == EXCLUDED].tolist())

    @property
    def error_ids(self) -> tuple[str, ...]:
        return tuple(self.ids[self.is_error].tolist())

    @property
    def errors(self) -> tuple[BlunderDecision, ...]:
        return tuple(self.decisions[i] for i in np.flatnonzero(self.is_error))

    @cached_property
    def reasons(self) -> np.ndarray:
        """The reason text per point (object array), built once per (decision, axes) class.

        Only five decisions times eight axis combinations exist; the per-point part is the
        justification of an excluded point, appended for those points alone.
        """
        n = self.ids.size
        code = np.zeros(n, dtype=np.int64)
        for k, name in enumerate(_DECISIONS):
            code[self.decision == name] = k
        key = code * 8 + self.exceeds_x * 4 + self.exceeds_y * 2 + self.exceeds_z * 1
        uniq, inverse = np.unique(key, return_inverse=True)
        texts = np.empty(len(uniq), dtype=object)
        for j, k in enumerate(uniq.tolist()):
            texts[j] = _reason(_DECISIONS[k // 8], bool(k & 4), bool(k & 2), bool(k & 1), "")
        out = texts[inverse.reshape(-1)] if n else np.empty(0, dtype=object)
        ids = self.ids
        for i in np.flatnonzero(self.decision == EXCLUDED).tolist():
            out[i] = _reason(
                EXCLUDED,
                bool(self.exceeds_x[i]),
                bool(self.exceeds_y[i]),
                bool(self.exceeds_z[i]),
                self.justifications.get(ids[i], ""),
            )
        return out

    @cached_property
    def decisions(self) -> tuple[BlunderDecision, ...]:
        """One decision per point, in input order, with its reason text (built once)."""
        dr, reasons = self.dr.tolist(), self.reasons
        dx, dy = self.dx.tolist(), self.dy.tolist()
        dz = [None] * self.ids.size if self.dz is None else self.dz.tolist()
        ex, ey, ez, er = (
            a.tolist() for a in (self.exceeds_x, self.exceeds_y, self.exceeds_z, self.exceeds_r)
        )
        cand = self.candidate.tolist()
        return tuple(
            BlunderDecision(
                point_id=pid,
                dx=dx[i],
                dy=dy[i],
                dz=dz[i],
                dr=dr[i],
                exceeds_x=ex[i],
                exceeds_y=ey[i],
                exceeds_z=ez[i],
                exceeds_r=er[i],
                candidate=cand[i],
                exclusion_requested=pid in self.justifications,
                justification=self.justifications.get(pid, ""),
                decision=str(self.decision[i]),
                reason=reasons[i],
            )
            for i, pid in enumerate(self.ids.tolist())
        )


_DECISIONS = (KEPT, ERROR_WITHIN_TOLERANCE, CANDIDATE_KEPT, ERROR_NO_JUSTIFICATION, EXCLUDED)


def _reason(decision: str, ex: bool, ey: bool, ez: bool, just: str) -> str:
    """The §12.6 reason text of one decision (the axes that exceed the maximum discrepancy)."""
    axes = [a for a, f in (("x", ex), ("y", ey), ("z", ez)) if f]
    over = "exceeds the maximum tolerable discrepancy in " + ", ".join(axes)
    return {
        KEPT: "within the maximum tolerable discrepancy",
        ERROR_WITHIN_TOLERANCE: "exclusion requested but the point is within the maximum "
        "tolerable discrepancy; it stays in the sample (JRC §12.6)",
        CANDIDATE_KEPT: f"{over}; no exclusion requested, kept",
        ERROR_NO_JUSTIFICATION: f"{over}; exclusion requested without a justification, kept",
        EXCLUDED: f"{over}; excluded: {just}",
    }[decision]


def detect_blunders(
    dx: Any,
    dy: Any,
    dz: Any = None,
    *,
    ids: Sequence[Any] | np.ndarray | None = None,
    basis: BlunderBasis = "calculated",
    factor: float = 3.0,
    target_rmse_xy: float | None = None,
    target_rmse_z: float | None = None,
    exclusions: Mapping[str, str | None] | None = None,
    gsd: float | None = None,
    unit: str = "m",
    percentile_method: PercentileMethod = "linear",
) -> BlunderResult:
    """Flag blunder candidates and apply justified exclusions.

    ``basis="calculated"`` follows JRC §12.6: the maximum tolerable discrepancy is
    ``factor × RMSE`` calculated from all points (per axis: 3·RMSE_x, 3·RMSE_y, 3·RMSE_z).
    ``basis="target"`` follows Table 9 ("3 x the target RMSE"): ``factor × target_rmse_xy``
    on each planimetric axis and ``factor × target_rmse_z`` vertically (without
    ``target_rmse_z`` the z axis is not screened and ``note`` says so). Note that with the
    calculated basis no point can exceed 3·RMSE when n <= 9 (``max|d| <= sqrt(n)·RMSE``).

    How a radial discrepancy meets a 1-D RMSE: a point is a *candidate* when ``|dx| >
    limit_x`` or ``|dy| > limit_y`` (or ``|dz| > limit_z``), the axes the tolerances are
    stated in (§12.7 applies X and Y independently). ``ΔR`` is compared with
    ``limit_r = sqrt(limit_x² + limit_y²)`` and reported as ``exceeds_r`` only; it never
    makes a candidate by itself.

    ``exclusions`` maps point id -> justification. An exclusion is applied only to a
    candidate with a non-empty justification; a request on a point within tolerance, or
    without justification, is kept in the statistics and returned as an error decision
    ("No point that is within the maximum tolerance may be eliminated", §12.6).

    Raises
    ------
    MeasureError
        Invalid deltas (see :func:`accuracy_stats`), unknown ids in ``exclusions``, a missing
        or non-positive planimetric target RMSE for ``basis="target"``, an unknown basis.
    """
    ax, ay, az = _f(dx), _f(dy), _f(dz)
    assert ax is not None and ay is not None
    id_arr = _as_ids(ids, ax.size)
    stats = accuracy_stats(
        ax, ay, az, ids=id_arr, gsd=gsd, unit=unit, percentile_method=percentile_method
    )
    if not (math.isfinite(factor) and factor > 0):
        raise MeasureError(f"blunder factor must be positive, got {factor!r}")
    if basis == "calculated":
        lx, ly = factor * stats.rmse_x, factor * stats.rmse_y
        lz = None if stats.rmse_z is None else factor * stats.rmse_z
    elif basis == "target":
        if target_rmse_xy is None or not target_rmse_xy > 0:
            raise MeasureError(
                "blunder basis 'target' needs a positive target RMSE (target_rmse_xy)"
            )
        lx = ly = factor * float(target_rmse_xy)
        if az is None or target_rmse_z is None:
            lz = None  # z not screened: reported in ``note``
        elif not target_rmse_z > 0:
            raise MeasureError(f"target_rmse_z must be positive, got {target_rmse_z!r}")
        else:
            lz = factor * float(target_rmse_z)
    else:
        raise MeasureError(f"blunder basis {basis!r} unknown; use 'calculated' or 'target'")
    lr = math.hypot(lx, ly)

    requests = {str(k): (v or "").strip() for k, v in (exclusions or {}).items()}
    pos = (
        pd.Index(id_arr, dtype=object).get_indexer(list(requests))
        if requests
        else np.zeros(0, dtype=np.intp)
    )
    unknown = sorted(pid for pid, i in zip(requests, pos.tolist(), strict=True) if i < 0)
    if unknown:
        raise MeasureError(f"exclusion requested for unknown point id(s): {', '.join(unknown)}")

    ex = np.abs(ax) > lx
    ey = np.abs(ay) > ly
    ez = np.zeros(ax.size, bool) if az is None or lz is None else np.abs(az) > lz
    er = np.hypot(ax, ay) > lr
    cand = ex | ey | ez
    requested = np.zeros(ax.size, bool)
    justified = np.zeros(ax.size, bool)
    if requests:
        requested[pos] = True
        justified[pos] = [bool(just) for just in requests.values()]
    # codes, then one shared str object per decision (not a fixed-width copy and a str per point)
    choice = np.select(
        [~cand & ~requested, ~cand & requested, cand & ~requested, cand & ~justified],
        [0, 1, 2, 3],
        default=4,
    )
    decision = np.array(
        [KEPT, ERROR_WITHIN_TOLERANCE, CANDIDATE_KEPT, ERROR_NO_JUSTIFICATION, EXCLUDED],
        dtype=object,
    )[choice]
    keep = decision != EXCLUDED

    note = ""
    if az is not None and lz is None:
        note = "dz not screened for blunders: no target RMSE_z given (basis 'target'); "
    kept_stats: AccuracyStats | None
    if keep.all():
        kept_stats = stats
    elif keep.sum() < 2:
        kept_stats = None
        note += f"only {int(keep.sum())} point(s) left after exclusions"
    else:
        kept_stats = accuracy_stats(
            ax[keep],
            ay[keep],
            None if az is None else az[keep],
            ids=id_arr[keep],
            gsd=gsd,
            unit=unit,
            percentile_method=percentile_method,
        )
    return BlunderResult(
        basis=basis,
        factor=factor,
        limit_x=lx,
        limit_y=ly,
        limit_z=lz,
        limit_r=lr,
        stats_all=stats,
        stats_kept=kept_stats,
        ids=id_arr,
        dx=ax,
        dy=ay,
        dz=az,
        exceeds_x=ex,
        exceeds_y=ey,
        exceeds_z=ez,
        exceeds_r=er,
        decision=decision,
        justifications=requests,
        note=note,
    )
