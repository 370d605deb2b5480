"""Every per-row check is linear in the table sizes (issue 28 item 7).

A contractor's images table may name one file on many rows (padding, or a table generated badly):
1,500 rows naming one file took 34 s before (the shared-file grouping was cubic: each row listed
every other row of its group, then searched that list for each of them). The table is read, every
file scanned once, and the same-file / same-content notes stay short (capped names and a count).
"""

from __future__ import annotations

import csv
import shutil
import time
from pathlib import Path

from tests.test_redteam_fixes import CHECKERS, EXAMPLES, _evaluator

from orthospec.engine.providers.rasters import NAMES_SHOWN

ROWS = 100_000
FILES = 3
SECONDS = 30.0


def _padded(tmp_path: Path, n: int) -> tuple[Path, list[str]]:
    """aerial-fail with an images table of ``n`` rows naming its first FILES files in turn."""
    d = tmp_path / "padded"
    shutil.copytree(EXAMPLES / "aerial-fail", d)
    path = d / "tables" / "images.csv"
    with path.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        header, rows = list(reader.fieldnames or []), list(reader)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=header, lineterminator="\n")
        w.writeheader()
        for k in range(n):
            w.writerow(rows[k % FILES] | {"image_id": f"I{k:06d}"})
    return d, [rows[k]["file"] for k in range(FILES)]


def test_rows_naming_few_files_are_judged_in_linear_time(tmp_path: Path) -> None:
    d, files = _padded(tmp_path, ROWS)
    ev = _evaluator(d, CHECKERS / "aerial-fail")
    start = time.perf_counter()
    own = ev.ctx.cache.get("raster.file_unique")
    content = ev.ctx.cache.get("raster.content_unique")
    seconds = time.perf_counter() - start
    assert seconds < SECONDS, f"{ROWS} rows naming {FILES} files took {seconds:.1f} s"
    for m in (own, content):
        assert len(m.values) == ROWS and not any(v is not False for v in m.values.tolist())
        note = m.notes["I000000"]  # the first row: the next rows naming its file, then a count
        shown = [f"I{k:06d}" for k in range(FILES, FILES * (NAMES_SHOWN + 1), FILES)]
        assert note == (
            f"names the same file {files[0]} as image(s) {', '.join(shown)} "
            f"and {ROWS // FILES + 1 - 1 - NAMES_SHOWN} more"
        )
        assert max(len(t) for t in m.notes.tolist()) < 300  # capped: never 10^5 names in one note
