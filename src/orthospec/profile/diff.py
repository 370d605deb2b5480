"""Compare two resolved profiles: what a tender changed relative to its base."""

from __future__ import annotations

from typing import Any

from .changes import weakening_changes
from .loader import ResolvedProfile


def _flat(d: Any, prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    if isinstance(d, dict):
        for k, v in d.items():
            out.update(_flat(v, f"{prefix}.{k}" if prefix else str(k)))
    else:
        out[prefix] = d
    return out


def _section(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    changed = {}
    for k in sorted(set(a) & set(b)):
        fa, fb = _flat(a[k]), _flat(b[k])
        diffs = {
            f: (fa.get(f), fb.get(f)) for f in sorted(set(fa) | set(fb)) if fa.get(f) != fb.get(f)
        }
        if diffs:
            changed[k] = diffs
    return {
        "added": sorted(set(b) - set(a)),
        "removed": sorted(set(a) - set(b)),
        "changed": changed,
    }


def weakened(a: ResolvedProfile, b: ResolvedProfile) -> list[dict[str, Any]]:
    """Mandatory rules of ``a`` that ``b`` removed or changed so they check less, with the
    justification ``b`` records for each (None when ``b`` does not extend ``a``: then nobody gave one).

    Computed from the two resolved profiles, so it holds for any pair, not only a tender and its base.
    """
    said = {w.id: w.justification for w in b.weakened}
    out = []
    for r in a.rules:
        if r.level != "mandatory":
            continue
        try:
            after = b.rule(r.id)
        except KeyError:
            after = None
        changes = weakening_changes(r, after)
        if changes:
            out.append(
                {"id": r.id, "title": r.title, "changes": changes, "justification": said.get(r.id)}
            )
    return out


def diff_profiles(a: ResolvedProfile, b: ResolvedProfile) -> dict[str, Any]:
    """What changed from ``a`` to ``b``: parameters and rules added, removed and changed, and the
    mandatory rules of ``a`` that ``b`` weakened (``weakened``, see :func:`weakened`)."""
    ra = {r["id"]: r for r in a.canonical["rules"]}
    rb = {r["id"]: r for r in b.canonical["rules"]}
    return {
        "a": f"{a.id} {a.version}",
        "b": f"{b.id} {b.version}",
        "sha256": [a.sha256, b.sha256],
        "parameters": _section(a.canonical["parameters"], b.canonical["parameters"]),
        "rules": _section(ra, rb),
        "weakened": weakened(a, b),
    }
