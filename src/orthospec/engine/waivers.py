"""Waivers: which are in force (the checker's side) and which are only requested (the contractor's).

The delivery is evidence, never authority (JRC §2: the contractor's internal QC is checked by an
independent external QC). A waiver is in force only when the tender profile's ``waivers:`` or
the checker's file (``check --checker FILE``) grants it; ``waivers:`` in the contractor's
delivery.yaml are *requests*: they never change a verdict, the record carries them as
``waiver_requested`` and the report lists them as requested by the contractor, not granted.

A granted waiver turns ``fail``, ``warn`` or ``missing`` into ``waived`` (the original verdict is
kept beside it); it never touches ``error`` (a broken check is not waivable) nor a pass.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import verdicts as V
from ..delivery.reader import MANIFEST, Delivery

if TYPE_CHECKING:
    from ..delivery.checker import Checker
    from ..profile.loader import ResolvedProfile
    from .context import RuleResult

WAIVABLE = (V.CODE[V.FAIL], V.CODE[V.WARN], V.CODE[V.MISSING])
NOT_GRANTED = "requested by the contractor, not granted"


def granted(profile: ResolvedProfile, checker: Checker | None) -> list[dict[str, Any]]:
    """Waivers in force, in order: the tender profile's, then the checker file's.

    Each carries ``declared_in`` (``profile`` or ``checker``) and ``granted_by`` (who, on the
    buyer's side, stands behind it).
    """
    out = [
        {
            **w.model_dump(mode="json"),
            "declared_in": "profile",
            "granted_by": f"tender profile {profile.id} {profile.version}",
        }
        for w in profile.waivers
    ]
    if checker is not None:
        out += [
            {
                **w.model_dump(mode="json", exclude_none=True),
                "declared_in": "checker",
                "checker_file": checker.name,
                "granted_by": checker.who(),
            }
            for w in checker.model.waivers
        ]
    return out


def requested(delivery: Delivery) -> list[dict[str, Any]]:
    """The contractor's waiver requests from delivery.yaml (never in force)."""
    who = delivery.manifest.contractor.name
    return [
        {
            **w.model_dump(mode="json", exclude_none=True),
            "declared_in": MANIFEST,
            "requested_by": who,
        }
        for w in delivery.manifest.waivers
    ]


def _match(items: np.ndarray, wanted: Iterable[str]) -> np.ndarray:
    wanted = [str(x) for x in wanted]
    if "*" in wanted:
        return np.ones(len(items), dtype=bool)
    return np.isin(items.astype(str), wanted)


def apply_granted(results: list[RuleResult], waivers: list[dict[str, Any]]) -> set[int]:
    """Waive the items the granted ``waivers`` name; return the indices of the waivers used."""
    by_rule: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    for i, w in enumerate(waivers):
        by_rule.setdefault(w["rule"], []).append((i, w))
    used: set[int] = set()
    waived = V.CODE[V.WAIVED]
    for r in results:
        for idx, w in by_rule.get(r.rule.id, ()):
            target = _match(r.items, w["items"]) & np.isin(r.verdict, WAIVABLE)
            if not target.any():
                continue
            used.add(idx)
            if r.original is None:
                r.original = r.verdict.copy()
            for it in r.items[target]:
                r.waivers[str(it)] = w
            r.verdict[target] = waived
    return used


def unused(waivers: list[dict[str, Any]], used: set[int]) -> list[dict[str, Any]]:
    """Granted waivers that matched nothing waivable (listed in the QCR as unused)."""
    return [w for i, w in enumerate(waivers) if i not in used]


def mark_requested(
    results: list[RuleResult], requests: list[dict[str, Any]]
) -> list[dict[str, Any]]:
    """Attach each request to the records it names (``RuleResult.requested``) and summarise them.

    The summary says, per request, the items it matched with their verdict in force, and whether
    the checker's side granted it (the item is ``waived`` by a granted waiver) or not.
    """
    by_rule: dict[str, list[dict[str, Any]]] = {}
    for w in requests:
        by_rule.setdefault(w["rule"], []).append(w)
    matched: dict[int, list[dict[str, str]]] = {id(w): [] for w in requests}
    for r in results:
        for w in by_rule.get(r.rule.id, ()):
            for i in np.flatnonzero(_match(r.items, w["items"])):
                item = str(r.items[i])
                r.requested[item] = w
                matched[id(w)].append({"item": item, "verdict": V.VERDICTS[int(r.verdict[i])]})
    out = []
    for w in requests:
        hits = matched[id(w)]
        grants = sorted({h["verdict"] for h in hits} & {V.WAIVED})
        out.append(
            {
                **w,
                "matched": hits,
                "status": "waived by a granted waiver (profile or checker)"
                if grants
                else NOT_GRANTED,
            }
        )
    return out
