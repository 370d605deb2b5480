"""Resource limits set through ``ORTHOSPEC_MAX_*`` environment variables: one parser for all.

The YAML, CSV and raster guards (yamlio.py, delivery/reader.py, raster/reading.py) each have
defaults far above any real delivery; an operator may raise or lower them per process.
"""

from __future__ import annotations

import os

from .errors import OrthospecError


def env_limit(name: str, default: int, *, error: type[OrthospecError] = OrthospecError) -> int:
    """The positive whole number in environment variable ``name``; ``default`` when unset or <= 0."""
    try:
        value = int(os.environ.get(name, "") or default)
    except ValueError:
        raise error(f"environment variable {name}: expected a whole number") from None
    return value if value > 0 else default
