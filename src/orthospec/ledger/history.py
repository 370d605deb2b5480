"""History and diff over recorded runs: pure functions on what the store returns.

JRC §12.8: "Redelivery of products will be followed by a further independent check on a new
sample of the products. This procedure will continue until the products are finally acceptable."
A project's history is therefore a sequence of rounds: the first delivered content, then each
redelivery (new manifest or file checksums); a run over content already seen is a re-check.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..verdicts import FAILING, REJECTED, worst
from .runs import RunInfo, document_content_key, lineage

#: the kinds of run in a project's sequence (JRC §12.8)
DELIVERY, REDELIVERY, RECHECK = "delivery", "redelivery", "recheck"


@dataclass(frozen=True)
class HistoryEntry:
    run: RunInfo
    kind: str            # delivery | redelivery | recheck
    round: int           # 1 = first delivery, 2 = first redelivery, ...
    signoffs: int


@dataclass(frozen=True)
class History:
    project: str | None
    entries: tuple[HistoryEntry, ...]
    #: rule -> run id -> worst (effective) verdict of the rule in that run
    rules: dict[str, dict[int, str]]
    #: block -> run id -> "rejected" or the worst verdict of its block-scope records
    blocks: dict[str, dict[int, str]]


def rounds_of(runs: Iterable[tuple[str, str]]) -> list[tuple[str, int]]:
    """(kind, round) per (project id, content key), oldest first, counted per project.

    The one redelivery-round computation (issue 15): a run over content the project already had
    is a re-check of that content's round; new content (manifest or any file checksum differs,
    whatever the delivery id says) opens the next round.
    """
    seen: dict[str, dict[str, int]] = {}
    count: dict[str, int] = {}
    out = []
    for project, key in runs:
        keys = seen.setdefault(project, {})
        if key in keys:
            out.append((RECHECK, keys[key]))
            continue
        count[project] = count.get(project, 0) + 1
        keys[key] = count[project]
        out.append((DELIVERY if count[project] == 1 else REDELIVERY, count[project]))
    return out


def trails(runs: Sequence[RunInfo]) -> list[str]:
    """The audit trail of each run (:func:`.runs.lineage`), named by the audit key of its first run."""
    label: dict[int, str] = {}
    for r in runs:
        if r.id not in label:
            for x in lineage(runs, r.audit):
                label.setdefault(x.id, r.audit)
    return [label[r.id] for r in runs]


def rounds(runs: Sequence[RunInfo]) -> list[tuple[str, int]]:
    """(kind, round) per recorded run, oldest first, counted per audit trail (not per manifest
    project id: a renamed ``project.id`` does not start the rounds again, issue 25 item 6)."""
    return rounds_of(zip(trails(runs), (r.content_key for r in runs), strict=True))


def round_of_document(runs: Sequence[RunInfo], doc: Mapping[str, Any]) -> tuple[str, int]:
    """(kind, round) the QCR document ``doc`` gets when recorded after ``runs`` (its audit trail's)."""
    pairs = [("", r.content_key) for r in runs]
    return rounds_of([*pairs, ("", document_content_key(doc))])[-1]


def build_history(
    project: str | None,
    runs: Sequence[RunInfo],
    qcrs: Mapping[int, Sequence[Mapping[str, Any]]],
    manual: Mapping[int, Mapping[str, str]],
    signoffs: Mapping[int, int],
) -> History:
    """Assemble the per-run, per-rule and per-block views from stored rows."""
    entries = tuple(
        HistoryEntry(r, k, n, signoffs.get(r.id, 0))
        for r, (k, n) in zip(runs, rounds(runs), strict=True)
    )
    rules: dict[str, dict[int, set[str]]] = {}
    blocks: dict[str, dict[int, set[str]]] = {}
    for r in runs:
        over = manual.get(r.id, {})
        for q in qcrs.get(r.id, []):
            v = over.get(q["rule"], q["verdict"])
            rules.setdefault(q["rule"], {}).setdefault(r.id, set()).add(v)
            if q["scope"] == "block":
                blocks.setdefault(q["item"], {}).setdefault(r.id, set()).add(v)
        for b in (r.summary.get("rejected") or {}).get("block", []):
            blocks.setdefault(str(b), {}).setdefault(r.id, set()).add(REJECTED)
    rule_view = {k: {rid: worst(vs) for rid, vs in per.items()} for k, per in sorted(rules.items())}
    block_view = {
        k: {rid: (REJECTED if REJECTED in vs else worst(vs)) for rid, vs in per.items()}
        for k, per in sorted(blocks.items())
    }
    return History(project, entries, rule_view, block_view)


@dataclass(frozen=True)
class Change:
    rule: str
    item: str
    before: str | None  # None: the record did not exist in run A
    after: str | None
    status: str  # fixed | newly_failing | still_failing | changed | added | removed


@dataclass(frozen=True)
class Diff:
    run_a: int
    run_b: int
    changes: tuple[Change, ...]
    counts: dict[str, int] = field(default_factory=dict)


def classify(before: str | None, after: str | None) -> str | None:
    """The kind of change between two verdicts of one (rule, item); None when nothing changed."""
    if before == after and before not in FAILING:
        return None
    if before is None:
        return "newly_failing" if after in FAILING else "added"
    if after is None:
        return "removed"
    if before in FAILING and after in FAILING:
        return "still_failing"
    if before in FAILING:
        return "fixed"
    if after in FAILING:
        return "newly_failing"
    return "changed"


def diff_verdicts(
    run_a: int, run_b: int, a: Mapping[tuple[str, str], str], b: Mapping[tuple[str, str], str]
) -> Diff:
    """Compare two runs' (rule, item) -> verdict maps."""
    changes = []
    for key in sorted(set(a) | set(b)):
        status = classify(a.get(key), b.get(key))
        if status is not None:
            changes.append(Change(key[0], key[1], a.get(key), b.get(key), status))
    counts: dict[str, int] = {}
    for c in changes:
        counts[c.status] = counts.get(c.status, 0) + 1
    return Diff(run_a, run_b, tuple(changes), counts)


def history_rows(
    entries: Sequence[HistoryEntry], *, current_run: int | None = None
) -> list[dict[str, Any]]:
    """Plain rows of a project's sequence of runs, as reports show them (JRC §12.8)."""
    return [
        {
            "run": e.run.id,
            "round": e.round,
            "kind": e.kind,
            "date": e.run.date,
            "delivery": e.run.delivery_id,
            "verdict": e.run.verdict,
            "signoffs": e.signoffs,
            "profile": f"{e.run.profile_id} {e.run.profile_version}",
            "current": e.run.id == current_run,
        }
        for e in entries
    ]


def history_rows_before_recording(
    entries: Sequence[HistoryEntry], doc: Mapping[str, Any]
) -> list[dict[str, Any]]:
    """The project's recorded runs, then the row ``doc`` (checked now, recorded right after its
    reports are rendered) will have: the report archived at check time states the same round as
    ``orthospec report --ledger --run N`` later does."""
    rows = history_rows(entries)
    kind, n = round_of_document([e.run for e in entries], doc)
    rows.append(
        {
            "run": "new",
            "round": n,
            "kind": kind,
            "date": doc["date"],
            "delivery": doc["delivery"]["id"],
            "verdict": doc["verdict"],
            "signoffs": 0,
            "profile": f"{doc['profile']['id']} {doc['profile']['version']}",
            "current": True,
        }
    )
    return rows
