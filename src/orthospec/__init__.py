"""orthospec: decide whether an orthoimagery delivery meets its standard, clause by clause."""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
