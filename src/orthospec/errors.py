"""One exception tree for orthospec.

::

    OrthospecError                  root; the CLI maps it to exit code 2
    ├── SpecError (ValueError)      a profile is invalid (file, line, column, rule id)
    ├── DeliveryError (ValueError)  a delivery is invalid (file, row or YAML path, column)
    ├── ExpressionError (ValueError) a profile expression is outside the safe grammar
    ├── UnitError (ValueError)      a unit is unknown or two units cannot meet
    ├── MeasureError (ValueError)   a measure cannot be computed from the data given
    ├── LedgerError (RuntimeError)  the QCR ledger is unreadable or fails verification
    └── ReportError (RuntimeError)  a report could not be rendered

Failures of a delivery against a profile are *results* (QCRs), never exceptions:
raise only when the input itself cannot be read or understood.
"""

from __future__ import annotations


class OrthospecError(Exception):
    """Root of every error orthospec raises on purpose."""

    exit_code = 2


class SpecError(OrthospecError, ValueError):
    """A spec profile cannot be loaded, validated or resolved."""

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | None = None,
        rule: str | None = None,
    ) -> None:
        self.file, self.line, self.column, self.rule = file, line, column, rule
        where = _where(file, line, column)
        who = f" (rule {rule})" if rule else ""
        super().__init__(f"{where}{message}{who}")


class DeliveryError(OrthospecError, ValueError):
    """A delivery folder, manifest or table cannot be read as the convention says."""

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | None = None,
        row: int | None = None,
        field: str | None = None,
    ) -> None:
        self.file, self.line, self.column, self.row, self.field = file, line, column, row, field
        where = _where(file, line, column)
        if row is not None:
            where = f"{file}: row {row}: " if file else f"row {row}: "
        fld = f"column {field!r}: " if field else ""
        super().__init__(f"{where}{fld}{message}")


class ExpressionError(OrthospecError, ValueError):
    """An expression uses syntax or names outside the safe grammar."""


class UnitError(OrthospecError, ValueError):
    """A unit is unknown, or a value in one unit meets a threshold in an incompatible one."""


class MeasureError(OrthospecError, ValueError):
    """A measure cannot be computed from the data given (too few points, bad shape...)."""


class LedgerError(OrthospecError, RuntimeError):
    """The QCR ledger cannot be opened, written or verified."""


class ReportError(OrthospecError, RuntimeError):
    """A report cannot be rendered."""


def _where(file: str | None, line: int | None, column: int | None) -> str:
    if not file:
        return ""
    if line is None:
        return f"{file}: "
    if column is None:
        return f"{file}:{line}: "
    return f"{file}:{line}:{column}: "
