"""The README walk-through runs as written (issue 13 item 7): the bash block, in a scratch folder."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def walkthrough() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"<!-- walkthrough:[^>]*-->\s*```bash\n(.*?)```", text, re.S)
    assert block, "README has no walk-through block"
    return block.group(1)


def test_readme_walkthrough_runs_as_written(tmp_path: Path) -> None:
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    env = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
        "COLUMNS": "120",
    }
    env.pop("ORTHOSPEC_LEDGER", None)
    res = subprocess.run(
        ["bash", "-e", "-o", "pipefail", "-c", walkthrough()],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    out = res.stdout
    assert re.search(
        r"B02: Block RMSEy within the tolerance: 0\.641 m > 0\.5 m", out.replace("\n", " ")
    )
    assert "recorded run #1" in out and "recorded run #2" in out
    assert re.search(r"signed run #2 as supervisor \(M\. Rossi, signed by key SHA256:\S+\)", out), (
        out
    )
    # the checker's own key was refused before the supervisor signed
    assert "cannot countersign it as supervisor" in res.stderr, res.stderr[-2000:]
    assert (
        len(re.findall(r"intact, 3 entries \(2 runs, 1 sign-offs\).*contains the head", out)) == 2
    ), out
    assert (tmp_path / "qc" / "signed-2" / "report.pdf").is_file()
    # nothing was written into the shipped deliveries
    assert not (ROOT / "examples" / "deliveries" / "aerial-fail" / "qc").exists()
