"""Real deliveries in (issue 27): ``orthospec init DIR --from SOURCE`` drafts a delivery from a folder
of orthophotos, tile index, XML metadata and survey spreadsheets as they arrive (docs/INGEST.md).

Layer: above ``raster`` (images are read by ``raster.facts.read_facts``) and the engine, below
``api``; the CLI (cli/cmd_init.py) calls :func:`make_draft`.
"""

from __future__ import annotations

from .draft import Draft, Options, make_draft

__all__ = ["Draft", "Options", "make_draft"]
