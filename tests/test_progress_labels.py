"""The scan progress line labels every number with its own unit (issue 13 item 8).

Before: two rich tasks shared the columns and printed ``2/3 files 2/3 bytes 5 bytes/s``.
"""

from __future__ import annotations

import io
import re

from rich.console import Console

from orthospec.raster.parallel import ImageReport, RichProgress


def test_rich_progress_line_has_files_bytes_and_rate_each_with_its_unit() -> None:
    buf = io.StringIO()
    console = Console(file=buf, width=160, force_terminal=False, color_system=None)
    p = RichProgress(console=console)
    p.start(3, 3 * 1_000_000)
    for _ in range(2):
        p.advance(ImageReport(path="images/a.tif", bytes=1_000_000))
    console.print(p._p.get_renderable())
    p.close()
    lines = [ln for ln in buf.getvalue().splitlines() if ln.strip()]
    line = lines[-1]
    assert line.lstrip().startswith("scanning")
    assert re.search(r"\b2/3 files\b", line), line  # files counted in files
    assert re.search(r"\b2\.0/3\.0 MB\b", line), line  # bytes counted in bytes (2 of 3 MB read)
    assert line.count("files") == 1 and "bytes" not in line.replace("bytes/s", ""), line
    assert re.search(r"\d (bytes|kB|MB|GB)/s|\?", line), line  # a rate with its own unit
    assert not re.search(r"\d+/\d+ bytes", line), line  # no file counts labelled as bytes
