"""Least-squares fits with residual statistics: interior orientation, scanner grid, warps.

Pure numpy. Sources: JRC EUR 23638 EN §6.2.2 and Table 3 (affine interior orientation: RMSE
< 0.5 px with four corner fiducials, < 1.0 px with eight, no residual > 0.7 px; scanner
geometry with a photogrammetric grid of at least 5 x 5 points, RMSE < 5 µm and no residual
> 15 µm after an affine transformation) and Table 9 / §9.5 (first or second order polynomial
warps only, GCP residual RMSE, √PRESS).

Conventions
-----------
* A 2-D affine transformation is the first-order polynomial ``u = a0 + a1·x + a2·y`` (and the
  same for ``v``): six parameters. Second order adds ``x², x·y, y²`` (twelve parameters).
* Residual = observed target coordinate minus fitted, in the target unit.
* ``rmse_x``/``rmse_y`` are per-axis ``sqrt(Σv²/n)`` (the tolerances are 1-D RMSEs);
  ``rmse_r = sqrt(rmse_x² + rmse_y²)``; ``max_residual`` is the longest residual *vector*
  ``sqrt(vx² + vy²)`` (conservative reading of "no residual greater than ...").
* PRESS: the JRC glossary defines it as "the average of these squared differences" while the
  name says *sum*. We return the **mean** (so ``sqrt_press_*`` is in the unit of the
  residuals, as the glossary intends); ``press_sum_r`` gives the sum as well. Leave-one-out
  residuals come in closed form from the hat matrix, ``e_i / (1 - h_ii)``, not n refits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import MeasureError

__all__ = [
    "IO_LIMITS_PX",
    "SCANNER_LIMITS_UM",
    "FitResult",
    "fit_affine",
    "fit_polynomial",
    "interior_orientation",
    "interior_orientation_limits",
    "scanner_grid_fit",
]

#: JRC §6.2.2: number of fiducials -> (RMSE limit px, maximum residual px).
IO_LIMITS_PX: dict[int, tuple[float, float]] = {4: (0.5, 0.7), 8: (1.0, 0.7)}
#: JRC Table 3: scanner geometry RMSE < 5 µm, no residual > 15 µm.
SCANNER_LIMITS_UM = (5.0, 15.0)
_MAX_ORDER = 2


@dataclass(frozen=True)
class FitResult:
    """A fitted polynomial transformation and its residual statistics (lengths in ``unit``)."""

    kind: str
    order: int
    unit: str
    n: int
    n_params: int  # per axis
    rmse_x: float
    rmse_y: float
    rmse_r: float
    max_abs_x: float
    max_abs_y: float
    max_residual: float
    max_residual_id: str
    press_x: float | None
    press_y: float | None
    press_r: float | None
    press_sum_r: float | None
    sqrt_press_x: float | None
    sqrt_press_y: float | None
    sqrt_press_r: float | None
    residual_x: np.ndarray = field(repr=False, compare=False)
    residual_y: np.ndarray = field(repr=False, compare=False)
    loo_x: np.ndarray | None = field(repr=False, compare=False)
    loo_y: np.ndarray | None = field(repr=False, compare=False)
    ids: np.ndarray | None = field(repr=False, compare=False)
    grid_shape: tuple[int, int] | None = None
    _coef: np.ndarray = field(repr=False, compare=False, default_factory=lambda: np.empty(0))
    _norm: tuple[float, float, float] = field(repr=False, compare=False, default=(0.0, 0.0, 1.0))

    @property
    def rmse_max_axis(self) -> float:
        """The larger per-axis RMSE: what a 1-D tolerance is compared with."""
        return max(self.rmse_x, self.rmse_y)

    def predict(self, src: Any) -> np.ndarray:
        """Apply the fitted transformation to ``(m, 2)`` source coordinates."""
        xy = np.asarray(src, dtype=float).reshape(-1, 2)
        return _design(xy, self.order, self._norm) @ self._coef


def _check_xy(name: str, arr: Any) -> np.ndarray:
    a = np.asarray(arr, dtype=float)
    if a.ndim != 2 or a.shape[1] != 2:
        raise MeasureError(f"{name} has shape {a.shape}; expected (n, 2) coordinates")
    return a


def _design(xy: np.ndarray, order: int, norm: tuple[float, float, float]) -> np.ndarray:
    """Design matrix on normalised coordinates (centred, scaled) for conditioning."""
    cx, cy, s = norm
    x = (xy[:, 0] - cx) / s
    y = (xy[:, 1] - cy) / s
    cols = [np.ones_like(x), x, y]
    if order == 2:
        cols += [x * x, x * y, y * y]
    return np.column_stack(cols)


def fit_polynomial(
    src: Any,
    dst: Any,
    *,
    order: int,
    ids: Sequence[Any] | np.ndarray | None = None,
    unit: str = "m",
    kind: str | None = None,
) -> FitResult:
    """Least-squares polynomial warp ``dst = P(src)`` of order 1 or 2, with residuals and PRESS.

    Parameters
    ----------
    src, dst
        ``(n, 2)`` arrays: e.g. image coordinates of GCPs and their map coordinates.
    order
        1 (affine) or 2. Order 3 or more raises: JRC Table 9, "Use a first or second order
        polynomial, third order must not be used".
    unit
        Unit of ``dst`` (residuals and RMSE are in it).

    Raises
    ------
    MeasureError
        Bad order, shapes, non-finite values, duplicate ids, too few points for the order
        (need more points than parameters), a degenerate (e.g. collinear) configuration, or
        a point whose leave-one-out prediction is undefined (leverage 1).
    """
    if order >= 3:
        raise MeasureError(
            f"polynomial order {order} refused: JRC EUR 23638 EN Table 9 says 'Use a first or "
            "second order polynomial, third order must not be used'"
        )
    if order < 1:
        raise MeasureError(f"polynomial order must be 1 or 2, got {order}")
    s, d = _check_xy("src", src), _check_xy("dst", dst)
    n = s.shape[0]
    if d.shape[0] != n:
        raise MeasureError(f"src has {n} points but dst has {d.shape[0]}")
    id_arr = None if ids is None else np.asarray([str(i) for i in ids], dtype=object)
    if id_arr is not None:
        if id_arr.size != n:
            raise MeasureError(f"{id_arr.size} ids given for {n} points")
        uniq, counts = np.unique(id_arr.astype(str), return_counts=True)
        if (counts > 1).any():
            raise MeasureError(f"duplicate point ids: {', '.join(uniq[counts > 1][:20])}")
    bad = ~(np.isfinite(s).all(axis=1) & np.isfinite(d).all(axis=1))
    if bad.any():
        where = id_arr[bad][:20] if id_arr is not None else np.flatnonzero(bad)[:20]
        raise MeasureError(f"non-finite coordinates for point(s) {', '.join(map(str, where))}")
    p = 3 if order == 1 else 6
    if n <= p:
        raise MeasureError(
            f"{n} points for a polynomial of order {order} ({p} parameters per axis): need at "
            f"least {p + 1} for residuals and PRESS"
        )

    centre = s.mean(axis=0)
    scale = float(np.abs(s - centre).max()) or 1.0
    norm = (float(centre[0]), float(centre[1]), scale)
    X = _design(s, order, norm)
    q, r = np.linalg.qr(X, mode="reduced")
    diag = np.abs(np.diag(r))
    if diag.min() <= 1e-10 * max(diag.max(), 1.0):
        raise MeasureError(
            f"degenerate point configuration for order {order} (e.g. collinear points): the "
            "polynomial is not determined"
        )
    coef = np.linalg.solve(r, q.T @ d)  # (p, 2)
    resid = d - X @ coef
    h = np.einsum("ij,ij->i", q, q)
    one_minus_h = 1.0 - h
    if (one_minus_h <= 1e-10).any():
        lev = id_arr[one_minus_h <= 1e-10] if id_arr is not None else np.flatnonzero(one_minus_h <= 1e-10)
        raise MeasureError(
            f"point(s) {', '.join(map(str, lev[:20]))} have leverage 1: the fit passes through "
            "them whatever their position, so their leave-one-out (PRESS) prediction is undefined"
        )
    loo = resid / one_minus_h[:, None]
    press_x = float(np.mean(loo[:, 0] ** 2))
    press_y = float(np.mean(loo[:, 1] ** 2))
    vx, vy = resid[:, 0], resid[:, 1]
    vr = np.hypot(vx, vy)
    imax = int(np.argmax(vr))
    rx = float(np.sqrt(np.mean(vx * vx)))
    ry = float(np.sqrt(np.mean(vy * vy)))
    return FitResult(
        kind=kind or ("affine" if order == 1 else "polynomial-2"),
        order=order, unit=unit, n=n, n_params=p,
        rmse_x=rx, rmse_y=ry, rmse_r=float(np.hypot(rx, ry)),
        max_abs_x=float(np.abs(vx).max()), max_abs_y=float(np.abs(vy).max()),
        max_residual=float(vr[imax]),
        max_residual_id=str(id_arr[imax]) if id_arr is not None else str(imax),
        press_x=press_x, press_y=press_y, press_r=press_x + press_y,
        press_sum_r=float(n * (press_x + press_y)),
        sqrt_press_x=float(np.sqrt(press_x)), sqrt_press_y=float(np.sqrt(press_y)),
        sqrt_press_r=float(np.sqrt(press_x + press_y)),
        residual_x=vx, residual_y=vy, loo_x=loo[:, 0], loo_y=loo[:, 1], ids=id_arr,
        _coef=coef, _norm=norm,
    )


def fit_affine(
    src: Any, dst: Any, *, ids: Sequence[Any] | np.ndarray | None = None, unit: str = "m"
) -> FitResult:
    """Six-parameter affine fit (first-order polynomial), see :func:`fit_polynomial`."""
    return fit_polynomial(src, dst, order=1, ids=ids, unit=unit)


def interior_orientation_limits(n_fiducials: int) -> tuple[float, float]:
    """JRC §6.2.2 limits ``(rmse_px, max_residual_px)`` for 4 or 8 fiducials."""
    try:
        return IO_LIMITS_PX[n_fiducials]
    except KeyError:
        raise MeasureError(
            f"{n_fiducials} fiducials: JRC §6.2.2 states interior-orientation tolerances for 4 "
            "(corner) or 8 fiducials only"
        ) from None


def interior_orientation(
    measured_px: Any,
    calibrated_mm: Any,
    *,
    ids: Sequence[Any] | np.ndarray | None = None,
) -> FitResult:
    """Affine interior orientation: calibrated fiducials (mm) -> measured image positions (px).

    Residuals are in pixels, the unit of the JRC tolerances. Four or eight fiducials only
    (:func:`interior_orientation_limits`); with four, 2 degrees of freedom per axis remain.
    """
    meas = _check_xy("measured_px", measured_px)
    interior_orientation_limits(meas.shape[0])
    return fit_polynomial(calibrated_mm, meas, order=1, ids=ids, unit="px",
                          kind="interior-orientation")


def _grid_shape(ref: np.ndarray) -> tuple[int, int]:
    """Distinct columns and rows of a reference grid (coordinates rounded to its extent)."""
    extent = float(np.ptp(ref, axis=0).max()) or 1.0
    q = np.round(ref / (extent * 1e-6)).astype(np.int64)
    return int(np.unique(q[:, 1]).size), int(np.unique(q[:, 0]).size)


def scanner_grid_fit(
    measured_um: Any,
    reference_um: Any,
    *,
    ids: Sequence[Any] | np.ndarray | None = None,
    min_grid: int = 5,
) -> FitResult:
    """Scanner geometry test (JRC Table 3): affine fit of a measured calibration grid, in µm.

    ``grid_shape`` = (rows, columns) of distinct reference coordinates. A grid smaller than
    ``min_grid x min_grid`` (JRC: "measure at least 5 x 5 points") raises MeasureError: the
    test was not carried out as specified, so its RMSE would not be evidence.
    """
    ref = _check_xy("reference_um", reference_um)
    rows, cols = _grid_shape(ref)
    if rows < min_grid or cols < min_grid:
        raise MeasureError(
            f"scanner calibration grid is {rows} x {cols}; JRC Table 3 requires at least "
            f"{min_grid} x {min_grid} points"
        )
    res = fit_polynomial(ref, measured_um, order=1, ids=ids, unit="µm", kind="scanner-grid")
    return replace(res, grid_shape=(rows, cols))
