"""orthospec: decide whether an orthoimagery delivery meets its standard, clause by clause.

The public API::

    from orthospec import check, load_profile, open_delivery
    result = check("delivery/", "jrc-v3", date="2026-11-21")
    result.document["verdict"]   # "accepted" | "rejected"
"""

from __future__ import annotations

__version__ = "0.1.0"

# Names load on first use: worker processes that import orthospec.raster.* must not pay for
# the whole engine (pydantic models, pint, the CLI) at start-up.
_LAZY = {
    "CheckOptions": "api", "CheckResult": "api", "check": "api",
    "Delivery": "delivery.reader", "open_delivery": "delivery.reader",
    "DeliveryError": "errors", "ExpressionError": "errors", "LedgerError": "errors",
    "MeasureError": "errors", "OrthospecError": "errors", "ReportError": "errors",
    "SpecError": "errors", "UnitError": "errors",
    "ResolvedProfile": "spec.loader", "load_profile": "spec.loader", "validate_file": "spec.loader",
}


def __getattr__(name: str) -> object:
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'orthospec' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "CheckOptions",
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
