"""Requirement operators: for each ``op`` of a rule's requirement, the comparison, the missing-value
policy and the wording, in one registered object.

The evaluator decides a rule through :meth:`Operator.decide`; the QCR record, the terminal, `explain`
and the tender annex word the requirement through :meth:`Operator.text` (via
:func:`orthospec.profile.wording.requirement_text`), so the annex the buyer publishes and the QCR the
contractor receives state the same requirement the same way.

Missing-value policy (nothing unmeasured passes, JRC §12): a missing measured value (None, NaN, an
empty string, a number that is not a number) is ``missing`` - except for ``present``, whose
requirement *is* the value, so there it is ``fail``; a threshold that cannot be computed (NaN) is
``missing``; a threshold given but not finite (±inf) is ``error``. When several apply to one item the
measured value's policy wins, then ``error``, then ``missing``.

Standard library at import time; numpy is imported when a comparison first runs, so the commands
that only word a rule (`explain`, `spec validate`, the annex) never import it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from .. import verdicts as V

if TYPE_CHECKING:
    import numpy as np

__all__ = ["OPERATORS", "Decision", "Operator", "Thresholds", "is_missing", "operator"]


def is_missing(v: Any) -> bool:
    """One measured value is missing: None, NaN, pandas NA/NaT, or an empty string."""
    if v is None:
        return True
    if isinstance(v, float):
        return math.isnan(v)
    if isinstance(v, str):
        return not v.strip()
    return type(v).__name__ in ("NAType", "NaTType")


@dataclass(frozen=True)
class Thresholds:
    """The resolved threshold(s) of one requirement: numbers (scalar or one per item) or literal text.

    ``value`` for the comparisons, ``min``/``max`` for ``between`` (None = that side is open),
    ``values`` for ``in``. A string threshold makes ``==``, ``!=`` and ``in`` compare text.
    """

    value: Any = None
    min: Any = None
    max: Any = None
    min_inclusive: bool = True
    max_inclusive: bool = True
    values: Sequence[Any] | None = None


@dataclass(frozen=True)
class Decision:
    """What an operator decided per item; :meth:`verdicts` applies the missing-value policy."""

    op: Operator
    ok: np.ndarray  # bool: the requirement is met (meaningless where undecided)
    no_value: np.ndarray  # bool: the measured value is missing
    no_threshold: np.ndarray  # bool: a threshold could not be computed (NaN)
    bad_threshold: np.ndarray  # bool: a given threshold is not finite (±inf)
    measured: np.ndarray  # the measured values as compared (floats, or text for text compares)

    @property
    def undecided(self) -> np.ndarray:
        return self.no_value | self.no_threshold | self.bad_threshold

    def verdicts(self, fail: str = V.FAIL) -> np.ndarray:
        """Verdict names per item; ``fail`` is what an unmet requirement gives (``warn`` for a
        recommended rule)."""
        import numpy as np

        out = np.where(self.ok, V.PASS, fail).astype(object)
        out[self.no_threshold] = V.MISSING
        out[self.bad_threshold] = V.ERROR
        out[self.no_value] = self.op.missing_value
        return out

    def codes(self, fail: str = V.FAIL) -> np.ndarray:
        """The same as integer codes (``orthospec.verdicts.CODE``), for the evaluator's int8 columns."""
        import numpy as np

        out = np.where(self.ok, V.CODE[V.PASS], V.CODE[fail]).astype(np.int8)
        out[self.no_threshold] = V.CODE[V.MISSING]
        out[self.bad_threshold] = V.CODE[V.ERROR]
        out[self.no_value] = V.CODE[self.op.missing_value]
        return out


class Operator:
    """One requirement operator. Subclasses implement :meth:`_decide` and :meth:`text`."""

    #: verdict of an item whose measured value is missing
    missing_value: ClassVar[str] = V.MISSING
    #: verdict of an item whose threshold cannot be computed (NaN)
    missing_threshold: ClassVar[str] = V.MISSING
    #: verdict of an item whose given threshold is not finite
    nonfinite_threshold: ClassVar[str] = V.ERROR
    #: the requirement reads thresholds (value / min / max / values)
    has_threshold: ClassVar[bool] = True
    #: the thresholds a measured number is compared with by order (what a pass can be close to:
    #: the ledger's marginal passes, JRC §12.7)
    bounds: ClassVar[tuple[str, ...]] = ()

    def __init__(self, name: str, symbol: str, unmet: str = "") -> None:
        self.name = name
        self.symbol = symbol
        #: the relation of a value that does not meet the requirement (``>`` for ``<=``)
        self.unmet = unmet

    def unmet_text(
        self,
        measured: str,
        value: str = "",
        *,
        lo: str = "",
        hi: str = "",
        min_inclusive: bool = True,
        max_inclusive: bool = True,
        values: Sequence[str] = (),
        unit: str = "",
    ) -> str | None:
        """How a finding states a value that does not meet the requirement (``0.641 m > 0.5 m``),
        from texts already formatted (``unit`` follows each number); None when the operator has no
        such sentence (the message says it)."""
        if self.unmet and value:
            return f"{measured}{unit} {self.unmet} {value}{unit}"
        return None

    def __repr__(self) -> str:
        return f"<operator {self.name}>"

    def decide(self, measured: Any, thresholds: Thresholds | None = None) -> Decision:
        """Compare every measured value with the threshold(s) (vectorised over items)."""
        import numpy as np

        raw = np.asarray(measured) if not isinstance(measured, np.ndarray) else measured
        if raw.ndim == 0:
            raw = raw.reshape(1)
        return self._decide(raw, thresholds or Thresholds())

    def _decide(self, raw: np.ndarray, t: Thresholds) -> Decision:
        raise NotImplementedError

    def text(
        self,
        value: str = "",
        *,
        lo: str = "",
        hi: str = "",
        min_inclusive: bool = True,
        max_inclusive: bool = True,
        values: Sequence[str] = (),
    ) -> str:
        """The requirement in words, from threshold texts already formatted with their unit."""
        raise NotImplementedError

    # helpers shared by the subclasses
    def _decision(
        self,
        ok: np.ndarray,
        no_value: np.ndarray,
        measured: np.ndarray,
        no_threshold: np.ndarray | None = None,
        bad_threshold: np.ndarray | None = None,
    ) -> Decision:
        import numpy as np

        none = np.zeros(len(ok), dtype=bool)
        return Decision(
            self,
            np.asarray(ok, dtype=bool),
            np.asarray(no_value, dtype=bool),
            none if no_threshold is None else no_threshold,
            none if bad_threshold is None else bad_threshold,
            measured,
        )


def _floats(raw: np.ndarray) -> np.ndarray:
    """Measured values as floats; a value that is not a number becomes NaN (missing)."""
    import numpy as np

    if raw.dtype.kind in "fiub":
        return raw.astype(float)

    def one(v: Any) -> float:
        try:
            return float(v)
        except (TypeError, ValueError):
            return math.nan

    return np.fromiter((one(v) for v in raw), dtype=float, count=len(raw))


def _texts(raw: np.ndarray) -> np.ndarray:
    """Measured values as text; a missing value becomes None."""
    import numpy as np

    return np.array([None if is_missing(v) else str(v) for v in raw], dtype=object)


def _bound(v: Any, n: int) -> np.ndarray:
    import numpy as np

    return np.broadcast_to(np.asarray(v, dtype=float), (n,)).astype(float)


def _is_text(*vals: Any) -> bool:
    return any(isinstance(v, str) for v in vals)


class _Order(Operator):
    """``<``, ``<=``, ``>``, ``>=``: numbers only."""

    bounds: ClassVar[tuple[str, ...]] = ("value",)
    _UFUNC: ClassVar[dict[str, str]] = {
        "<": "less",
        "<=": "less_equal",
        ">": "greater",
        ">=": "greater_equal",
    }

    def _decide(self, raw: np.ndarray, t: Thresholds) -> Decision:
        import numpy as np

        values = _floats(raw)
        thr = _bound(math.nan if t.value is None else t.value, len(values))
        with np.errstate(invalid="ignore"):
            ok = getattr(np, self._UFUNC[self.name])(values, thr)
        return self._decision(ok, np.isnan(values), values, np.isnan(thr), np.isinf(thr))

    def text(self, value: str = "", **_: Any) -> str:
        return f"{self.symbol} {value}"


class _Equality(Operator):
    """``==``, ``!=``: numbers within ``numpy.isclose`` (rtol 1e-5, atol 1e-8), or text exactly."""

    def _decide(self, raw: np.ndarray, t: Thresholds) -> Decision:
        import numpy as np

        if _is_text(t.value):
            vals = _texts(raw)
            eq = np.array([v == t.value for v in vals], dtype=bool)
            miss = np.array([v is None for v in vals], dtype=bool)
            return self._decision(eq if self.name == "==" else ~eq, miss, vals)
        values = _floats(raw)
        thr = _bound(math.nan if t.value is None else t.value, len(values))
        with np.errstate(invalid="ignore"):
            eq = np.isclose(values, thr)
        return self._decision(
            eq if self.name == "==" else ~eq, np.isnan(values), values, np.isnan(thr), np.isinf(thr)
        )

    def text(self, value: str = "", **_: Any) -> str:
        return f"{self.symbol} {value}"


class _Between(Operator):
    """``between``: ``min``/``max`` each inclusive unless said; a side not given is open."""

    bounds: ClassVar[tuple[str, ...]] = ("min", "max")

    def _decide(self, raw: np.ndarray, t: Thresholds) -> Decision:
        import numpy as np

        values = _floats(raw)
        n = len(values)
        lo = _bound(-math.inf if t.min is None else t.min, n)
        hi = _bound(math.inf if t.max is None else t.max, n)
        with np.errstate(invalid="ignore"):
            a = values >= lo if t.min_inclusive else values > lo
            b = values <= hi if t.max_inclusive else values < hi
        given = [x for x, spec in ((lo, t.min), (hi, t.max)) if spec is not None]
        none = np.zeros(n, dtype=bool)
        no_thr = np.logical_or.reduce([np.isnan(x) for x in given]) if given else none
        bad_thr = np.logical_or.reduce([np.isinf(x) for x in given]) if given else none
        return self._decision(a & b, np.isnan(values), values, no_thr, bad_thr)

    def unmet_text(
        self,
        measured: str,
        value: str = "",
        *,
        lo: str = "",
        hi: str = "",
        min_inclusive: bool = True,
        max_inclusive: bool = True,
        values: Sequence[str] = (),
        unit: str = "",
    ) -> str | None:
        lb, rb = "[" if min_inclusive else "(", "]" if max_inclusive else ")"
        return f"{measured}{unit} outside {lb}{lo or '−∞'}, {hi or '+∞'}{rb}{unit}"

    def text(
        self,
        value: str = "",
        *,
        lo: str = "",
        hi: str = "",
        min_inclusive: bool = True,
        max_inclusive: bool = True,
        **_: Any,
    ) -> str:
        return (
            f"between {lo or '−∞'} ({'incl.' if min_inclusive else 'excl.'}) "
            f"and {hi or '+∞'} ({'incl.' if max_inclusive else 'excl.'})"
        )


class _In(Operator):
    """``in``: one of the listed values (text when any listed value is text, else numbers)."""

    def _decide(self, raw: np.ndarray, t: Thresholds) -> Decision:
        import numpy as np

        allowed = list(t.values or [])
        if _is_text(*allowed):
            vals = _texts(raw)
            words = {str(v) for v in allowed}
            ok = np.array([v in words for v in vals], dtype=bool)
            return self._decision(ok, np.array([v is None for v in vals], dtype=bool), vals)
        values = _floats(raw)
        nums = np.asarray(allowed, dtype=float)
        ok = np.isin(values, nums)
        no_thr = np.full(len(values), bool(np.isnan(nums).any()))
        return self._decision(ok, np.isnan(values), values, no_thr)

    def text(self, value: str = "", *, values: Sequence[str] = (), **_: Any) -> str:
        return "one of " + ", ".join(values)

    def unmet_text(
        self, measured: str, value: str = "", *, values: Sequence[str] = (), **_: Any
    ) -> str:
        return f"{measured} not one of {', '.join(values)}"


class _Present(Operator):
    """``present``: the value is given. A missing value is not undecided here: it is the failure."""

    missing_value: ClassVar[str] = V.FAIL
    has_threshold: ClassVar[bool] = False

    def _decide(self, raw: np.ndarray, t: Thresholds) -> Decision:
        import numpy as np

        if raw.dtype.kind == "f":
            miss = np.isnan(raw)
        elif raw.dtype.kind in "iub":
            miss = np.zeros(len(raw), dtype=bool)
        else:
            miss = np.fromiter((is_missing(v) for v in raw), dtype=bool, count=len(raw))
        return self._decision(~miss, np.zeros(len(raw), dtype=bool), raw)

    def text(self, value: str = "", **_: Any) -> str:
        return "present"


class _Truth(Operator):
    """``true`` / ``false``: the value is that boolean (a number or word is not a boolean)."""

    has_threshold: ClassVar[bool] = False

    def _decide(self, raw: np.ndarray, t: Thresholds) -> Decision:
        import numpy as np

        want = self.name == "true"
        if raw.dtype.kind == "b":
            return self._decision(raw == want, np.zeros(len(raw), dtype=bool), raw)
        ok = np.fromiter(
            ((v is want) or (isinstance(v, np.bool_) and bool(v) is want) for v in raw),
            dtype=bool,
            count=len(raw),
        )
        miss = np.fromiter((is_missing(v) for v in raw), dtype=bool, count=len(raw))
        return self._decision(ok, miss, raw)

    def text(self, value: str = "", **_: Any) -> str:
        return f"is {self.name}"

    def unmet_text(self, measured: str, value: str = "", **_: Any) -> str:
        return f"{measured}, required {self.name}"


#: every requirement operator, by its name in a profile (`spec.models.Op`)
OPERATORS: dict[str, Operator] = {}


def _register(op: Operator) -> None:
    if op.name in OPERATORS:
        raise ValueError(f"operator {op.name!r} registered twice")
    OPERATORS[op.name] = op


for _op in (
    _Order("<", "<", "≥"),
    _Order("<=", "≤", ">"),
    _Order(">", ">", "≤"),
    _Order(">=", "≥", "<"),
    _Equality("==", "=", "≠"),
    _Equality("!=", "≠", "="),
    _Between("between", "between"),
    _In("in", "in"),
    _Present("present", "present"),
    _Truth("true", "true"),
    _Truth("false", "false"),
):
    _register(_op)


def operator(name: str) -> Operator:
    """The registered operator ``name`` (the profile model has already refused any other)."""
    try:
        return OPERATORS[name]
    except KeyError:
        raise KeyError(
            f"unknown requirement operator {name!r}; known: {', '.join(OPERATORS)}"
        ) from None
