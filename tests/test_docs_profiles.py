"""docs/PROFILES.md runs as written: its YAML files are written, its commands succeed (issue 13 item 7)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_profiles_guide_examples_run(tmp_path: Path) -> None:
    text = (ROOT / "docs" / "PROFILES.md").read_text(encoding="utf-8")
    files = re.findall(r"```yaml file=(\S+)\n(.*?)```", text, re.S)
    assert files, "the guide has no example files"
    for name, body in files:
        (tmp_path / name).write_text(body, encoding="utf-8")
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    script = re.findall(r"```bash\n(.*?)```", text, re.S)[-1]
    env = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
    }
    res = subprocess.run(
        ["bash", "-e", "-c", script],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert "valid (my-tender 1.0.0" in res.stdout
    assert "~ parameter cloud_cover_max: effective 10 % -> 5 %" in res.stdout
    annex = (tmp_path / "annex" / "annex-my-tender-1.0.0.md").read_text(encoding="utf-8")
    assert "ITT §5.3 fixes 5 % per image" in annex  # the justification is printed
    rmsey = next(line for line in annex.splitlines() if line.startswith("| `JRC-12.7-RMSEY`"))
    assert "≤ 0.5 m" in rmsey
