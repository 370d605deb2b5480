"""orthospec: decide whether an orthoimagery delivery meets its standard, clause by clause.

The public API::

    from orthospec import check, load_profile, open_delivery
    result = check("delivery/", "jrc-v3", date="2026-11-21")
    result.document["verdict"]   # "accepted" | "rejected"
"""

from __future__ import annotations

__version__ = "0.1.0"

from .api import CheckResult, check
from .delivery.reader import Delivery, open_delivery
from .errors import (
    DeliveryError,
    ExpressionError,
    LedgerError,
    MeasureError,
    OrthospecError,
    ReportError,
    SpecError,
    UnitError,
)
from .spec.loader import ResolvedProfile, load_profile, validate_file

__all__ = [
    "CheckResult",
    "Delivery",
    "DeliveryError",
    "ExpressionError",
    "LedgerError",
    "MeasureError",
    "OrthospecError",
    "ReportError",
    "ResolvedProfile",
    "SpecError",
    "UnitError",
    "__version__",
    "check",
    "load_profile",
    "open_delivery",
    "validate_file",
]
