"""Moved to :mod:`orthospec.yamlio` (a foundation module: delivery/ reads the manifest with it too,
and delivery/ sits below spec/). Kept as a re-export until every importer uses the new home."""

from __future__ import annotations

from ..yamlio import Located, Path_, YamlError, YamlLimits, load_file, load_text

__all__ = ["Located", "Path_", "YamlError", "YamlLimits", "load_file", "load_text"]
