"""The verdict after sign-off: manual verdicts given at ``signoff --manual`` applied to a run.

The automatic verdict of a run never changes (it is what ``check`` wrote and the chain hashes).
A report of a signed run shows, beside it, the records with the signed manual verdicts applied,
the counts recomputed and a *verdict after sign-off*, with who decided what and when.

The after-sign-off verdict is conservative, because a wrong ACCEPTED is the worst error: it is
ACCEPTED only when the run was accepted and no manual check was signed failing with a rejecting
consequence, or when the run was rejected and every record that could reject it (a mandatory
rule, or any rule under ``--fail-on warn``, not passing, with a rejecting consequence) belongs to
a manual check that was signed ``pass``. Otherwise it is REJECTED - or INCOMPLETE when what is
still open is only the checker's (consequence ``incomplete``, or a manual check still unsigned).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from .. import verdicts as V

__all__ = ["after_signoff", "apply_manual"]

_REJECTING = tuple(sorted(V.REJECTING))


def decisions(signoffs: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """rule -> {verdict, by, role, date}; a later sign-off overrides an earlier one."""
    out: dict[str, dict[str, Any]] = {}
    for s in signoffs:
        for rule, verdict in sorted((s.get("manual") or {}).items()):
            out[rule] = {"rule": rule, "verdict": verdict, "by": s.get("by"), "role": s.get("role"),
                         "date": s.get("date")}
    return out


def apply_manual(records: Sequence[Mapping[str, Any]], decided: Mapping[str, Mapping[str, Any]],
                 ) -> list[dict[str, Any]]:
    """Records with the signed manual verdicts applied (a signed fail of a recommended rule warns)."""
    out = []
    for r in records:
        d = decided.get(r["rule"])
        if d is None or not r.get("manual") or r["verdict"] == V.NOT_APPLICABLE:
            out.append(dict(r))
            continue
        v = d["verdict"]
        if v == V.FAIL and r.get("level") == "recommended":
            v = V.WARN
        out.append(
            {
                **r,
                "verdict": v,
                "signed_verdict": d["verdict"],
                "message": f"signed {d['verdict']} by {d['by']} ({d['role']}) on {d['date']}",
            }
        )
    return out


def _open(r: Mapping[str, Any], fail_on: str) -> bool:
    """The record keeps the run from acceptance (it rejects, or leaves the check incomplete)."""
    bad = V.FAILING | ({V.WARN} if fail_on == V.WARN else set())
    if r.get("level") == "recommended" and fail_on != V.WARN:
        return False
    return r["verdict"] in bad and r.get("consequence") in (*_REJECTING, V.INCOMPLETE)


def _checkers(r: Mapping[str, Any]) -> bool:
    """An open record that is the checker's to complete (engine/incomplete.py), not a rejection."""
    from ..engine.incomplete import checker_measure

    return (
        r.get("consequence") == V.INCOMPLETE
        or bool(r.get("manual") and r["verdict"] == V.MISSING)
        or (r["verdict"] == V.MISSING and checker_measure(str(r.get("measure") or "")))
    )


def _blocking(r: Mapping[str, Any], fail_on: str) -> bool:
    return _open(r, fail_on) and not _checkers(r)


def after_signoff(
    doc: Mapping[str, Any], signoffs: Sequence[Mapping[str, Any]]
) -> dict[str, Any] | None:
    """{verdict, summary, decisions, basis} for a run with manual verdicts signed; None without."""
    decided = decisions(signoffs)
    if not decided:
        return None
    from ..qcr import all_records  # the QCR model is only needed once a run has signed verdicts

    fail_on = str(doc.get("fail_on", V.FAIL))
    records = list(all_records(doc))
    applied = apply_manual(records, decided)
    summary = dict(doc.get("summary") or {})
    for k in V.VERDICTS:
        summary[k] = sum(r["verdict"] == k for r in applied)
    signed_fail = any(r.get("signed_verdict") == V.FAIL and _blocking(r, fail_on) for r in applied)
    if signed_fail:
        verdict, basis = V.REJECTED, "a manual check that can reject was signed fail"
    elif doc.get("verdict") == V.ACCEPTED:
        verdict, basis = V.ACCEPTED, "the run was accepted and no manual check was signed failing"
    else:
        open_ = [
            r
            for r in records
            if _open(r, fail_on)
            and not (r.get("manual") and (decided.get(r["rule"]) or {}).get("verdict") == V.PASS)
        ]
        rejecting = [r for r in open_ if not _checkers(r)]
        if rejecting:
            rules = sorted({r["rule"] for r in rejecting})
            verdict = V.REJECTED
            basis = (
                f"{len(rejecting)} rejecting record(s) are not manual checks signed pass "
                f"({', '.join(rules[:4])}{', …' if len(rules) > 4 else ''})"
            )
        elif open_:
            rules = sorted({r["rule"] for r in open_})
            verdict = V.INCOMPLETE
            basis = (
                f"{len(open_)} record(s) are still the checker's to complete "
                f"({', '.join(rules[:4])}{', …' if len(rules) > 4 else ''})"
            )
        else:
            verdict, basis = V.ACCEPTED, "every rejecting record was a manual check signed pass"
    counts: dict[str, int] = {}
    for r in records:
        if r.get("manual") and r["rule"] in decided and r["verdict"] != V.NOT_APPLICABLE:
            counts[r["rule"]] = counts.get(r["rule"], 0) + 1
    rows = [{**d, "records": counts.get(rule, 0)} for rule, d in sorted(decided.items())]
    return {"verdict": verdict, "basis": basis, "summary": summary, "decisions": rows}
