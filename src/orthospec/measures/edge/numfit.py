"""The numerical kernels of the edge chain in numpy: GCV smoothing spline, bounded
Levenberg-Marquardt, Brent's root and minimum, the F distribution's survival function.

Why not scipy: importing ``scipy.interpolate`` / ``scipy.optimize`` (which pull
``scipy.special`` and ``scipy.linalg``) costs 1.2-2 s, more than the measurement itself, and
``orthospec measure edge`` is timed as a command against MTF Mapper (issue 31). The problems
here are small (tens to a few hundred bins, at most ten parameters), so dense numpy is fast.

The same figures as scipy's chain: the spline minimises the same criterion as
``scipy.interpolate.make_smoothing_spline`` (sum w (y - f)^2 + lam int f''^2, lam by GCV with
Brent's bounded search over (0, n), the same numerator and trace), in Reinsch's form
(Green & Silverman 1994, 2.3) with one generalised eigen-decomposition, so that every GCV
evaluation costs O(n). ``use_scipy(True)`` swaps scipy's routines back in (tests and the
benchmark compare both chains on the same ROIs).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

_SCIPY = False


@contextmanager
def use_scipy(on: bool = True) -> Iterator[None]:
    """Run the chain with scipy's routines (comparison only; not thread-safe)."""
    global _SCIPY
    old, _SCIPY = _SCIPY, on
    try:
        yield
    finally:
        _SCIPY = old


# --------------------------------------------------------------------------- spline


class NaturalSpline:
    """Natural cubic spline through values ``g`` with second derivatives ``gam`` at knots ``x``;
    beyond the end knots the end pieces' cubics continue (as scipy's BSpline extrapolates)."""

    def __init__(self, x: np.ndarray, g: np.ndarray, gam: np.ndarray, nu: int = 0) -> None:
        self.x, self.g, self.gam, self.nu = x, g, gam, nu

    def derivative(self, nu: int = 1) -> NaturalSpline:
        return NaturalSpline(self.x, self.g, self.gam, self.nu + nu)

    def __call__(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        x, g, gam = self.x, self.g, self.gam
        i = np.clip(np.searchsorted(x, q, side="right") - 1, 0, x.size - 2)
        h = x[i + 1] - x[i]
        a = (x[i + 1] - q) / h
        b = (q - x[i]) / h
        if self.nu == 0:
            return a * g[i] + b * g[i + 1] + ((a**3 - a) * gam[i] + (b**3 - b) * gam[i + 1]) * h * h / 6.0
        if self.nu == 1:
            return (g[i + 1] - g[i]) / h + ((3 * b * b - 1) * gam[i + 1] - (3 * a * a - 1) * gam[i]) * h / 6.0
        if self.nu == 2:
            return a * gam[i] + b * gam[i + 1]
        if self.nu == 3:
            return (gam[i + 1] - gam[i]) / h
        return np.zeros_like(q)


def make_smoothing_spline(x: np.ndarray, y: np.ndarray, w: np.ndarray | None = None,
                          lam: float | None = None) -> Any:
    """Cubic smoothing spline of (x, y) with weights w, lam by GCV when None (as scipy's)."""
    if _SCIPY:
        from scipy.interpolate import make_smoothing_spline as msp

        return msp(x, y, w=w, lam=lam)
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    n = x.size
    if x.ndim != 1 or y.shape != x.shape:
        raise ValueError("x and y must be 1-D of the same length")
    if n <= 4:
        raise ValueError("x and y length must be at least 5")
    h = np.diff(x)
    if np.any(h <= 0):
        raise ValueError("x should be an ascending array")
    w = np.ones(n) if w is None else np.ascontiguousarray(w, dtype=float)
    if np.any(w <= 0):
        raise ValueError("invalid vector of weights")
    t, z, resid_basis, mu = _reinsch_basis(x, y, w, h)

    def solve(lam_: float) -> tuple[np.ndarray, np.ndarray]:
        coef = z / (1.0 + lam_ * mu)
        return t @ coef, lam_ * (resid_basis @ coef)

    if lam is None:
        def gcv(lam_: float) -> float:
            res = lam_ * (resid_basis @ (z / (1.0 + lam_ * mu)))
            tr = n - float(np.sum(lam_ * mu / (1.0 + lam_ * mu)))
            denom = (1.0 - tr / n) ** 2
            return float(res @ res) / n / denom if denom > 0 else math.inf

        lam, ok = fminbound(gcv, 0.0, float(n))
        if not ok:
            raise ValueError("unable to find the minimum of the GCV function")
    elif lam < 0:
        raise ValueError("regularization parameter should be non-negative")
    gam, res = solve(float(lam))
    return NaturalSpline(x, y - res, np.concatenate([[0.0], gam, [0.0]]))


def _reinsch_basis(x: np.ndarray, y: np.ndarray, w: np.ndarray,
                   h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The smoothing spline for every lam from one eigen-decomposition: gamma =
    T diag(1 / (1 + lam mu)) z, residuals y - g = lam W^-1 Q gamma."""
    n = x.size
    m = n - 2
    # Q (n x m) and R (m x m) of Green & Silverman: Q^T g = R gamma, int g''^2 = gamma^T R gamma
    q = np.zeros((n, m))
    j = np.arange(m)
    q[j, j] = 1.0 / h[:-1]
    q[j + 1, j] = -1.0 / h[:-1] - 1.0 / h[1:]
    q[j + 2, j] = 1.0 / h[1:]
    r = np.zeros((m, m))
    r[j, j] = (h[:-1] + h[1:]) / 3.0
    r[j[:-1], j[:-1] + 1] = r[j[:-1] + 1, j[:-1]] = h[1:-1] / 6.0
    # generalised eigenproblem M v = mu R v with M = Q^T W^-1 Q: (R + lam M)^-1 = L^-T U (1 + lam mu)^-1 U^T L^-1
    chol = np.linalg.cholesky(r)
    li = np.linalg.inv(chol)
    winv_q = q / w[:, None]
    s = li @ (q.T @ winv_q) @ li.T
    mu, u = np.linalg.eigh(0.5 * (s + s.T))
    mu = np.maximum(mu, 0.0)
    t = li.T @ u  # gamma = t diag(1/(1+lam mu)) t^T Q^T y
    z = t.T @ (q.T @ y)
    return t, z, winv_q @ t, mu


def fminbound(f: Callable[[float], float], x1: float, x2: float, xatol: float = 1e-5,
              maxfun: int = 500) -> tuple[float, bool]:
    """Brent's bounded minimisation (golden section with parabolic steps; Brent 1973, ch. 5;
    Forsythe, Malcolm & Moler's FMIN): the argmin and whether it converged."""
    sqrt_eps = math.sqrt(2.2e-16)
    golden = 0.5 * (3.0 - math.sqrt(5.0))
    a, b = x1, x2
    v = w = xf = a + golden * (b - a)
    d = e = 0.0
    fx = f(xf)
    fv = fw = fx
    num = 1
    xm = 0.5 * (a + b)
    tol1 = sqrt_eps * abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    while abs(xf - xm) > tol2 - 0.5 * (b - a):
        use_golden = True
        if abs(e) > tol1:
            use_golden = False
            r = (xf - w) * (fx - fv)
            qq = (xf - v) * (fx - fw)
            p = (xf - v) * qq - (xf - w) * r
            qq = 2.0 * (qq - r)
            if qq > 0.0:
                p = -p
            qq = abs(qq)
            r, e = e, d
            if abs(p) < abs(0.5 * qq * r) and q_between(p, qq, a - xf, b - xf):
                d = p / qq
                u = xf + d
                if (u - a) < tol2 or (b - u) < tol2:
                    d = tol1 * (1.0 if xm >= xf else -1.0)
            else:
                use_golden = True
        if use_golden:
            e = (a - xf) if xf >= xm else (b - xf)
            d = golden * e
        u = xf + (1.0 if d >= 0 else -1.0) * max(abs(d), tol1)
        fu = f(u)
        num += 1
        if fu <= fx:
            if u >= xf:
                a = xf
            else:
                b = xf
            v, fv, w, fw, xf, fx = w, fw, xf, fx, u, fu
        else:
            if u < xf:
                a = u
            else:
                b = u
            if fu <= fw or w == xf:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v in (xf, w):
                v, fv = u, fu
        xm = 0.5 * (a + b)
        tol1 = sqrt_eps * abs(xf) + xatol / 3.0
        tol2 = 2.0 * tol1
        if num >= maxfun:
            return xf, False
    return xf, math.isfinite(fx)


def q_between(p: float, q: float, lo: float, hi: float) -> bool:
    """p / q strictly inside (lo, hi) for q >= 0, without dividing."""
    return p > q * lo and p < q * hi


# --------------------------------------------------------------------------- roots


def brentq(f: Callable[[float], float], a: float, b: float, xtol: float = 2e-12,
           rtol: float = 8.9e-16, maxiter: int = 100) -> float:
    """A root of f in [a, b] (Brent 1973, ch. 4: bisection, secant and inverse quadratic
    steps); ValueError when f(a) and f(b) have the same sign, as scipy's."""
    if _SCIPY:
        from scipy import optimize

        return float(optimize.brentq(f, a, b))
    fa, fb = f(a), f(b)
    if fa * fb > 0:
        raise ValueError("f(a) and f(b) must have different signs")
    if fa == 0:
        return a
    if fb == 0:
        return b
    c, fc = a, fa
    d = e = b - a
    for _ in range(maxiter):
        if fb * fc > 0:
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 2.0 * rtol * abs(b) + 0.5 * xtol
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0:
            return b
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:
                p, q = 2.0 * m * s, 1.0 - s
            else:
                qa, r = fa / fc, fb / fc
                p = s * (2.0 * m * qa * (qa - r) - (b - a) * (r - 1.0))
                q = (qa - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0:
                q = -q
            p = abs(p)
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e, d = d, p / q
            else:
                d = e = m
        else:
            d = e = m
        a, fa = b, fb
        b += d if abs(d) > tol else (tol if m > 0 else -tol)
        fb = f(b)
    return b


# --------------------------------------------------------------------------- least squares


@dataclass
class LsqResult:
    """What the chain reads of a least-squares fit (the names of scipy's OptimizeResult)."""

    x: np.ndarray
    cost: float  # 0.5 * sum of squared residuals
    status: int  # > 0 converged, 0 out of evaluations, < 0 failed
    nfev: int


def least_squares(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray,
                  jac: Callable[[np.ndarray], np.ndarray] | None = None,
                  bounds: tuple[Any, Any] = (-np.inf, np.inf), x_scale: Any = "jac",
                  max_nfev: int = 200, ftol: float = 1e-12, xtol: float = 1e-12) -> Any:
    """Bounded nonlinear least squares: Levenberg-Marquardt (Marquardt 1963; Moré 1978's
    scaling by the Jacobian's column norms for ``x_scale="jac"``), steps projected on the box,
    a variable held at a bound while the step pushes it out; forward differences without
    ``jac``. Tolerances tighter than scipy's defaults (1e-8), so that both land on the same
    minimum to well below the figures' rounding."""
    if _SCIPY:
        from scipy import optimize

        kw: dict[str, Any] = {"bounds": bounds, "x_scale": x_scale, "max_nfev": max_nfev}
        if jac is not None:
            kw["jac"] = jac
        return optimize.least_squares(fun, x0, **kw)
    x0 = np.asarray(x0, dtype=float)
    lo = np.broadcast_to(np.asarray(bounds[0], dtype=float), x0.shape)
    hi = np.broadcast_to(np.asarray(bounds[1], dtype=float), x0.shape)
    if np.any(lo >= hi):
        raise ValueError("each lower bound must be strictly less than each upper bound")
    x = np.clip(x0, lo, hi)
    r = np.asarray(fun(x), dtype=float)
    nfev = 1
    if not np.all(np.isfinite(r)):
        raise ValueError("residuals are not finite in the initial point")
    cost = 0.5 * float(r @ r)
    fixed = None if isinstance(x_scale, str) else np.broadcast_to(np.asarray(x_scale, float), x.shape)
    dmax = np.zeros(x.size)
    lam = -1.0
    status = 0
    while nfev < max_nfev and status == 0:
        jm = np.asarray(jac(x), dtype=float) if jac is not None else _fd_jac(fun, x, r, hi)
        nfev += 0 if jac is not None else x.size
        g, a = jm.T @ r, jm.T @ jm
        dmax = np.maximum(dmax, np.diag(a))
        diag = 1.0 / fixed**2 if fixed is not None else np.where(dmax > 0, dmax, 1.0)
        if cost == 0.0 or not np.any(g):
            status = 1
            break
        lam = 1e-3 * float(np.max(np.diag(a) / diag, initial=1.0)) if lam < 0 else lam
        while nfev < max_nfev:
            xn = _lm_step(a, g, diag, lam, x, lo, hi)
            if not np.any(xn != x):
                status = 2
                break
            rn = np.asarray(fun(xn), dtype=float)
            nfev += 1
            costn = 0.5 * float(rn @ rn) if np.all(np.isfinite(rn)) else math.inf
            if costn < cost:
                small = np.linalg.norm(xn - x) < xtol * (xtol + np.linalg.norm(x))
                status = 2 if cost - costn < ftol * cost else (3 if small else 0)
                x, r, cost, lam = xn, rn, costn, max(lam / 3.0, 1e-15)
                break
            lam *= 4.0
            if lam > 1e20:
                status = 2
                break
    return LsqResult(x=x, cost=cost, status=status, nfev=nfev)


def _fd_jac(fun: Callable[[np.ndarray], np.ndarray], p: np.ndarray, r0: np.ndarray,
            hi: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian (steps kept inside the upper bound)."""
    out = np.empty((r0.size, p.size))
    for k in range(p.size):
        step = 1.49e-8 * max(abs(p[k]), 1.0)
        step = -step if p[k] + step > hi[k] else step
        pk = p.copy()
        pk[k] += step
        out[:, k] = (np.asarray(fun(pk), dtype=float) - r0) / step
    return out


def _lm_step(a: np.ndarray, g: np.ndarray, diag: np.ndarray, lam: float, x: np.ndarray,
             lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """x + the damped Gauss-Newton step (J^T J + lam D) dx = -g, on the box: a variable at
    its bound whose step points out is held there and the rest solved again."""
    free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
    dx = np.zeros(x.size)
    for _ in range(3):
        if not free.any():
            break
        sub = a[np.ix_(free, free)] + lam * np.diag(diag[free])
        try:
            step = np.linalg.solve(sub, -g[free])
        except np.linalg.LinAlgError:
            step = np.linalg.lstsq(sub, -g[free], rcond=None)[0]
        dx = np.zeros(x.size)
        dx[free] = step
        out = free & (((x <= lo) & (dx < 0)) | ((x >= hi) & (dx > 0)))
        if not out.any():
            break
        free &= ~out
    return np.clip(x + dx, lo, hi)


# --------------------------------------------------------------------------- F distribution


def fdtrc(d1: float, d2: float, f: float) -> float:
    """P(F > f) of the F distribution with (d1, d2) degrees of freedom: the regularised
    incomplete beta I_{d2/(d2 + d1 f)}(d2/2, d1/2) (Abramowitz & Stegun 26.6.2)."""
    if _SCIPY:
        from scipy.special import fdtrc as sc

        return float(sc(d1, d2, f))
    if not (d1 > 0 and d2 > 0) or math.isnan(f):
        return math.nan
    if f <= 0:
        return 1.0
    if math.isinf(f):
        return 0.0
    return betainc(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f))


def betainc(a: float, b: float, x: float) -> float:
    """Regularised incomplete beta I_x(a, b): the continued fraction (A&S 26.5.8) evaluated by
    the modified Lentz method, on the side where it converges fast."""
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    ln_front = (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x)
                + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(ln_front) * _betacf(a, b, x) / a
    return 1.0 - math.exp(ln_front) * _betacf(b, a, 1.0 - x) / b


def _betacf(a: float, b: float, x: float) -> float:
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 1000):
        m2 = 2 * m
        for num in (m * (b - m) * x / ((a + m2 - 1.0) * (a + m2)),
                    -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0))):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return h
