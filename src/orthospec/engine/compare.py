"""A rule's requirement against its measured column: thresholds resolved, units converted, decided.

The comparison, its missing-value policy and its wording belong to the requirement operator
(profile/operators.py); this module resolves what the operator is given: the
measured values in the requirement's unit (px via the item's GSD) and the threshold(s), which may
be expressions over parameters, manifest facts and measures of the rule's scope.

Nothing unmeasured passes: a value that does not convert (px without a GSD) or a threshold that
cannot be computed is ``missing``; a non-finite threshold is ``error``; a threshold naming an
unset parameter raises :class:`Undecidable` (the rule is ``missing`` where it applies).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from .. import units
from ..errors import ExpressionError, OrthospecError, UnitError
from ..profile import expr
from ..profile.models import Requirement, Rule
from ..profile.operators import Decision, Thresholds, operator
from ..profile.wording import requirement_text
from ..units import NON_NUMERIC, canonical, convert
from ..verdicts import Reason
from .context import ERROR, MISSING, Context
from .names import Names, null_tested, param_key

#: (verdict code, item mask, note) for items a comparison could not decide
Undecided = list[tuple[int, np.ndarray, str, Reason]]


class Undecidable(OrthospecError):
    """A rule's requirement needs a value nobody gave (an unset parameter): verdict `missing`."""


def item_gsd(ctx: Context, scope: str, items: list[str]) -> np.ndarray | None:
    """GSD in metres per item, to convert px thresholds (image rows first, else the product GSD)."""
    base = ctx.d.gsd_m
    out = np.full(len(items), np.nan if base is None else base, dtype=float)
    if scope == "image" and ctx.d.table("images") is not None:
        try:
            m = ctx.cache.get("images.gsd")
            vals = pd.to_numeric(m.values.reindex(items), errors="coerce").to_numpy(dtype=float)
            vals = convert(vals, m.unit, "m")
            out = np.where(np.isnan(vals), out, vals)
        except (KeyError, OrthospecError):
            pass  # no per-image GSD: the product GSD stands (or none, and px stays unconverted = missing)
    return None if np.isnan(out).all() else out


def magnitudes(v: Any, unit: str | None, n: int, gsd: np.ndarray | None, what: str) -> np.ndarray:
    """A threshold as float magnitudes in ``unit`` (broadcast to n items: one value is a read-only
    view of stride 0, not n copies of it - a million check points share one threshold)."""
    if hasattr(v, "units"):
        mag = np.asarray(v.magnitude, dtype=float)
        src = str(v.units)
        if unit is None:
            raise UnitError(
                f"{what}: the expression has unit {canonical(src)!r}; give the requirement a unit"
            )
        if v.units == units.ureg.dimensionless:
            # a pure number (e.g. "0.1 * 256") means "in the requirement's unit"
            return _broadcast(mag, n)
        return _broadcast(convert(mag, src, unit, gsd_m=gsd, what=what), n)
    if v is None:
        raise Undecidable(
            f"{what}: the threshold has no value (a fact or parameter it names is not given)"
        )
    if isinstance(v, bool):
        raise UnitError(f"{what}: expected a number, got {v!r}")
    return _broadcast(v, n)


def _broadcast(v: Any, n: int) -> np.ndarray:
    """Float values for n items: one value as a stride-0 view, per-item values as their own array."""
    arr = np.asarray(v, dtype=float)
    return (
        np.broadcast_to(arr, (n,))
        if arr.ndim == 0 or arr.size == 1
        else np.broadcast_to(arr, (n,)).astype(float)
    )


def constant(arr: np.ndarray) -> bool:
    """One value for every item (a stride-0 threshold from :func:`magnitudes`)."""
    return arr.ndim == 1 and arr.size > 0 and arr.strides[0] == 0


def threshold_value(v: Any, names: Names) -> Any:
    if isinstance(v, str):
        return expr.parse(v).evaluate(names)
    return v


def is_expr(ctx: Context, v: str) -> bool:
    """A string value is an expression only if it parses and names a parameter or manifest fact."""
    try:
        e = expr.parse(v)
    except ExpressionError:
        return False
    return bool(e.names) and all(
        n in ctx.params or n.startswith(("manifest.", "param.")) for n in e.names
    )


def need_params(ctx: Context, rule: Rule, req: Requirement) -> None:
    """A threshold naming an unset parameter cannot be decided: raise so the rule is `missing`."""
    for spec in (req.value, req.min, req.max, *(req.values or [])):
        if not isinstance(spec, str) or not is_expr(ctx, spec):
            continue
        unset = sorted(
            n
            for n in expr.parse(spec).names
            if param_key(n) in ctx.params and ctx.params[param_key(n)].value is None
        )
        if unset and not null_tested(spec):
            raise Undecidable(
                f"parameter {', '.join(unset)} is not set, so {rule.id} cannot be decided: "
                "set it in a tender profile or with --param NAME=VALUE"
            )


def req_dict(req: Requirement, resolved: tuple[np.ndarray, ...] | None) -> dict[str, Any]:
    """The requirement as the QCR states it: op, unit, threshold(s) in force (one value or per item)."""
    unit = canonical(req.unit) if req.unit and req.unit not in NON_NUMERIC else req.unit
    out: dict[str, Any] = {"op": req.op, "unit": unit}

    def one(spec: Any, arr: np.ndarray | None) -> Any:
        if arr is None:
            return spec
        if constant(arr):
            uniq = arr[:1][~np.isnan(arr[:1])] if arr.dtype.kind == "f" else arr[:1]
        else:
            uniq = np.unique(arr[~np.isnan(arr)]) if arr.dtype.kind == "f" else arr
        if len(uniq) == 1:
            return float(uniq[0])
        return None  # varies per item; see the record's own threshold

    if req.op == "between":
        out["min"] = one(req.min, resolved[0] if resolved else None)
        out["max"] = one(req.max, resolved[1] if resolved else None)
        if isinstance(req.min, str):
            out["min_expr"] = req.min
        if isinstance(req.max, str):
            out["max_expr"] = req.max
        out["min_inclusive"], out["max_inclusive"] = req.min_inclusive, req.max_inclusive
    elif req.op == "in":
        out["values"] = list(req.values or [])
    elif req.op not in ("present", "true", "false"):
        out["value"] = one(req.value, resolved[0] if resolved else None)
        if isinstance(req.value, str) and resolved is not None:
            out["expr"] = req.value
    if resolved is not None:
        out["_arrays"] = resolved
    out["text"] = requirement_text(req, out)
    return out


class Comparison:
    """One rule's comparison: ``run()`` -> (ok, measured, threshold, unit, undecided)."""

    def __init__(
        self,
        ctx: Context,
        rule: Rule,
        raw: np.ndarray,
        munit: str,
        skip: np.ndarray,
        names: Names,
        items: list[str],
    ) -> None:
        self.ctx, self.rule, self.req = ctx, rule, rule.requirement
        self.raw, self.munit, self.skip, self.names, self.items = raw, munit, skip, names, items
        self.undecided: Undecided = []

    def run(self) -> tuple[np.ndarray, np.ndarray, dict[str, Any], str, Undecided]:
        op, req = self.req.op, self.req
        thr = req_dict(req, None)
        if op in ("present", "true", "false"):
            d = operator(op).decide(self.raw)
            ok = d.ok if op == "present" else d.ok | self.skip
            return ok, self.raw, thr, self.munit, self.undecided
        textual = self.munit in NON_NUMERIC or self.munit == "any"
        if op in ("==", "!=", "in") and (
            textual
            or any(
                isinstance(v, str) and not is_expr(self.ctx, v)
                for v in (req.value, *(req.values or []))
            )
        ):
            return self._text(thr)
        if textual:
            raise UnitError(
                f"measure {self.rule.measure} is {self.munit}, the requirement {op} needs a number"
            )
        return self._numeric()

    def _text(
        self, thr: dict[str, Any]
    ) -> tuple[np.ndarray, np.ndarray, dict[str, Any], str, Undecided]:
        """``==``, ``!=``, ``in`` against literal text (the value as written, or a text expression)."""
        req = self.req
        if req.op == "in":
            t = Thresholds(values=[str(v) for v in req.values or []])
        else:
            target = (
                str(threshold_value(req.value, self.names))
                if isinstance(req.value, str) and is_expr(self.ctx, req.value)
                else str(req.value)
            )
            t = Thresholds(value=target)
        d = operator(req.op).decide(self.raw, t)
        return d.ok | self.skip, d.measured, thr, self.munit, self.undecided

    def _values(self) -> tuple[np.ndarray, str, np.ndarray | None, np.ndarray]:
        """Measured values as floats in the requirement's unit: (values, unit, gsd, lost in conversion)."""
        raw, munit, rule = self.raw, self.munit, self.rule
        values = (
            raw.astype(float)
            if raw.dtype.kind in "fiu"
            else pd.to_numeric(pd.Series(raw), errors="coerce").to_numpy(dtype=float)
        )
        target_unit = canonical(self.req.unit) if self.req.unit else munit
        gsd = (
            item_gsd(self.ctx, rule.scope, self.items)
            if "px" in (canonical(munit), target_unit)
            else None
        )
        before = np.isnan(values)
        if canonical(munit) != target_unit:
            values = convert(values, munit, target_unit, gsd_m=gsd, what=f"measure {rule.measure}")
        lost = np.isnan(values) & ~before & ~self.skip
        if lost.any():
            self.undecided.append(
                (
                    MISSING,
                    lost,
                    f"{rule.measure} in {canonical(munit)} cannot be converted to "
                    f"{target_unit}: no GSD for this item (give images.gsd or product.gsd)",
                    Reason.NO_GSD,
                )
            )
        return values, target_unit, gsd, lost

    def _thresholds(
        self, n: int, gsd: np.ndarray | None
    ) -> tuple[Thresholds, tuple[np.ndarray, ...] | None]:
        req, names, what = self.req, self.names, f"rule {self.rule.id} requirement"
        if req.op == "between":
            lo = (
                magnitudes(threshold_value(req.min, names), req.unit, n, gsd, what)
                if req.min is not None
                else None
            )
            hi = (
                magnitudes(threshold_value(req.max, names), req.unit, n, gsd, what)
                if req.max is not None
                else None
            )
            # an open side is written as no bound (-inf/+inf): only a given bound must be finite
            shown = (
                np.broadcast_to(-np.inf, (n,)) if lo is None else lo,
                np.broadcast_to(np.inf, (n,)) if hi is None else hi,
            )
            return Thresholds(
                min=lo, max=hi, min_inclusive=req.min_inclusive, max_inclusive=req.max_inclusive
            ), shown
        if req.op == "in":
            return Thresholds(
                values=[float(threshold_value(v, names)) for v in req.values or []]
            ), None
        t = magnitudes(threshold_value(req.value, names), req.unit, n, gsd, what)
        return Thresholds(value=t), (t,)

    def _numeric(self) -> tuple[np.ndarray, np.ndarray, dict[str, Any], str, Undecided]:
        rule, skip = self.rule, self.skip
        values, target_unit, gsd, lost = self._values()
        need_params(self.ctx, rule, self.req)
        t, shown = self._thresholds(len(values), gsd)
        d: Decision = operator(self.req.op).decide(values, t)
        thr = req_dict(self.req, shown)
        self.undecided.append(
            (
                MISSING,
                d.no_threshold & ~skip,
                (
                    f"the threshold of {rule.id} cannot be computed for this item (a px threshold without a GSD, "
                    "or a measure it uses is missing)"
                ),
                Reason.NO_THRESHOLD,
            )
        )
        self.undecided.append(
            (
                ERROR,
                d.bad_threshold & ~skip,
                (
                    f"the threshold of {rule.id} is not a finite number ({thr.get('text', '')}): a requirement must "
                    "be a finite value"
                ),
                Reason.BAD_THRESHOLD,
            )
        )
        self.undecided.append(
            (
                MISSING,
                d.no_value & ~skip & ~lost,
                f"no numeric value for {rule.measure}",
                Reason.NO_VALUE,
            )
        )
        return d.ok | skip | d.no_value, values, thr, target_unit, self.undecided
