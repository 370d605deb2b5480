"""Example orthospec plugin: a measure, an output format and a profile (see pyproject.toml)."""

__version__ = "0.1.0"
