"""Audit continuity the contractor cannot rename (issue 25 item 6).

Observed: renaming ``project.id`` in a redelivery dropped the Tightened state the ledger recorded, so
the next external-QC sample shrank to the normal share and left out the suspect items. The audit
trail is now keyed by what the checker states (``checker.project`` in the checker file) and by
content continuity (the redelivery shares most of its files with a recorded run), and only failing
both by the manifest's project id. Real SQLite ledgers, real CLI runs on small deliveries.
"""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner
from tests.conftest import MANIFEST

from orthospec.cli.main import cli
from orthospec.ledger import open_ledger

HEADER = "image_id,file,block,roll,flying_height,std_dn,exposure_x,exposure_y\n"
CHECKER = """\
orthospec_checker: 1
checker: {name: A. Checker (fictional), role: external QC%s}
delivery: {id: D1}
parameters: {tolerance_xy: {value: 0.5, unit: m}}
manual_checks:
  - {check: R-VIS, item: "*", date: 2026-01-01, verdict: pass, note: visual check done}
waivers:
  - {rule: R-ROLL, items: [I3], justification: turbulence over the ridge, approver: Chief}
"""


def run(*args: object):
    return CliRunner().invoke(cli(), [str(a) for a in args])


def images(bad: int | None) -> str:
    """30 images; image ``bad`` rolls 5 deg (over the mini profile's limit): 1 in 30 fails, within the
    §12.3 5 % share, so the run is accepted and the family turns tightened."""
    return (
        HEADER
        + "\n".join(
            f"I{i},f{i}.tif,B1,{5 if i == bad else 0.5},1000,30,{i * 100},{(i % 5) * 100}"
            for i in range(30)
        )
        + "\n"
    )


def documents(tag: str) -> dict[str, str]:
    """Files the delivery carries besides its tables (reports, certificates): what a redelivery that
    only fixes a few images ships again unchanged."""
    return {f"docs/report-{i}.txt": f"flight report {i} {tag}\n" for i in range(12)}


def checker_file(tmp_path: Path, project: str | None) -> Path:
    p = tmp_path / ("checker-stated.yaml" if project else "checker.yaml")
    p.write_text(CHECKER % (f", project: '{project}'" if project else ""), encoding="utf-8")
    return p


def first_run(
    make_delivery, mini_profile: Path, tmp_path: Path, *, project: str | None = None
) -> Path:
    root = make_delivery("round1", images=images(bad=7), extra=documents("v1"))
    ledger = tmp_path / "ledger.sqlite"
    res = run(
        "check",
        root,
        "-p",
        mini_profile,
        "--out",
        tmp_path / "o1",
        "--ledger",
        ledger,
        "--date",
        "2026-01-01",
        "--format",
        "json",
        "--checker",
        checker_file(tmp_path, project),
    )
    assert res.exit_code == 0, res.output
    with open_ledger(ledger, create=False) as led:
        assert led.audit_states(project or "P1")["§5.2.4"].state == "tightened"
    return ledger


def sample(root: Path, mini_profile: Path, ledger: Path, out: Path, *extra: object):
    res = run(
        "sample",
        root,
        "-p",
        mini_profile,
        "--seed",
        3,
        "--fraction",
        0.1,
        "--ledger",
        ledger,
        "--out",
        out,
        *extra,
    )
    assert res.exit_code == 0, res.output
    return res.output, out.read_text(encoding="utf-8").splitlines()[1:]


def renamed(text: str) -> str:
    return text.replace("project: {id: P1,", "project: {id: P1-RENAMED,").replace(
        "id: D1\n", "id: D2\n"
    )


def test_renamed_project_id_keeps_the_tightened_sample_by_content_continuity(
    make_delivery, mini_profile, tmp_path
):
    ledger = first_run(make_delivery, mini_profile, tmp_path)
    # the redelivery: image 7 re-flown, the rest shipped again, project.id renamed by the contractor
    same = make_delivery("same-name", images=images(bad=None), extra=documents("v1"))
    other = make_delivery(
        "other-name", manifest=renamed(MANIFEST), images=images(bad=None), extra=documents("v1")
    )
    said, kept = sample(same, mini_profile, ledger, tmp_path / "same.csv")
    told, got = sample(other, mini_profile, ledger, tmp_path / "renamed.csv")
    assert "audit level tightened" in said, said
    assert "audit level tightened" in told, told  # before: "audit level normal", 3 of 30
    assert got == kept and any(line.startswith("I7,") for line in got)
    normal = run(
        "sample",
        other,
        "-p",
        mini_profile,
        "--seed",
        3,
        "--fraction",
        0.1,
        "--out",
        tmp_path / "n.csv",
    )
    assert "selected 3 of 30 images" in normal.output, normal.output  # the share without the ledger
    assert len(got) > len((tmp_path / "n.csv").read_text().splitlines()[1:])
    # recorded, the renamed redelivery joins the same audit trail and is its second round
    res = run(
        "check",
        other,
        "-p",
        mini_profile,
        "--out",
        tmp_path / "o2",
        "--ledger",
        ledger,
        "--date",
        "2026-02-01",
        "--format",
        "json",
        "--checker",
        _rebound(checker_file(tmp_path, None), "D2"),
    )
    assert res.exit_code == 0, res.output
    with open_ledger(ledger, create=False) as led:
        first, second = led.runs()
        assert (first.project_id, second.project_id) == ("P1", "P1-RENAMED")
        assert second.audit_key == first.audit_key == "P1" and second.continues_run == first.id
        assert [(e.kind, e.round) for e in led.history("P1-RENAMED").entries] == [
            ("delivery", 1),
            ("redelivery", 2),
        ]


def _rebound(checker: Path, delivery_id: str) -> Path:
    out = checker.with_name(f"{checker.stem}-{delivery_id}.yaml")
    out.write_text(
        checker.read_text(encoding="utf-8").replace("id: D1}", f"id: {delivery_id}}}"),
        encoding="utf-8",
    )
    return out


def test_the_project_the_checker_states_keys_the_trail_whatever_the_content(
    make_delivery, mini_profile, tmp_path
):
    stated = "ITT 2026/CAP-ORTHO lot 2"
    ledger = first_run(make_delivery, mini_profile, tmp_path, project=stated)
    with open_ledger(ledger, create=False) as led:
        assert [r.audit_key for r in led.runs()] == [stated]
    # every file new (re-processed, re-written reports) and project.id renamed: nothing but the
    # checker's statement ties the redelivery to the trail
    rework = make_delivery(
        "rework", manifest=renamed(MANIFEST), images=images(bad=None), extra=documents("v2")
    )
    told, got = sample(
        rework,
        mini_profile,
        ledger,
        tmp_path / "stated.csv",
        "--checker",
        checker_file(tmp_path, stated),
    )
    assert "audit level tightened" in told, told
    assert any(line.startswith("I7,") for line in got)
    # without the checker's statement only the contractor's project id is left to go by
    bare, _ = sample(rework, mini_profile, ledger, tmp_path / "bare.csv")
    assert "audit level normal" in bare, bare
