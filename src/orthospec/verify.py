"""Run a profile's own `tests:` (delivery + params + expected verdicts) so tender authors can test specs.

At the api level (it runs checks), not in spec/ (issue 15 item 2)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .api import check
from .errors import SpecError
from .profile.loader import load_profile


@dataclass(frozen=True)
class Expectation:
    what: str
    expected: str
    got: str


@dataclass
class Outcome:
    name: str
    checks: list[Expectation] = field(default_factory=list)


def verify_profile(ref: str | Path) -> list[Outcome]:
    prof = load_profile(ref)
    outcomes = []
    for i, t in enumerate(prof.tests):
        path = (prof.path.parent / t.delivery).resolve()
        name = t.description or f"tests[{i}] {Path(t.delivery).name}"
        if not path.is_dir():
            raise SpecError(f"{prof.path}: tests[{i}]: delivery folder {t.delivery!r} not found")
        checker = (prof.path.parent / t.checker).resolve() if t.checker else None
        if checker is not None and not (checker.is_file() or checker.is_dir()):
            raise SpecError(
                f"{prof.path}: tests[{i}]: checker folder or file {t.checker!r} not found"
            )
        res = check(
            path,
            prof,
            params={k: str(v) for k, v in t.params.items()},
            date="2000-01-01",
            checker=checker,
        )
        doc = res.document
        o = Outcome(name)
        if "verdict" in t.expect:
            o.checks.append(Expectation("verdict", str(t.expect["verdict"]), doc["verdict"]))
        got_rules = {r["rule"]: r["verdict"] for r in doc["rules"]}
        for rid, exp in sorted((t.expect.get("rules") or {}).items()):
            o.checks.append(Expectation(f"rule {rid}", str(exp), got_rules.get(rid, "absent")))
        outcomes.append(o)
    return outcomes
