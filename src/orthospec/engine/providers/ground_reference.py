"""Ground reference and scanning records judged across tables (JRC §7.3, §6.2.2, §12.7).

* ``points.shared_ids`` (delivery): point identifiers used in both the GCP and the check point
  tables (§7.3 "point identifier (unique to project)"; each table's own ids are unique by the reader).
  A check point carrying a GCP's id is one point under two roles: its independence cannot be shown.
* ``scanner.schedule_gaps`` (delivery): ends of the scanning period without a geometric scanner test
  (§6.2.2 "performed before and at the end of the project"): 0 when a test (``scanner_tests.date``) is
  dated on or before the first ``images.scan_date`` and one on or after the last.
* ``gcp.source_kind`` (gcp): the kind of source of a GCP's coordinates (§7.1: survey, map,
  photogrammetric, orthoimage): ``gcps.source_type`` (a closed vocabulary) when given, else read from
  the words of the free-text ``gcps.source`` when they name exactly one kind ("GNSS RTK (SAPOS
  HEPS)" -> survey, "scaled from the 1:5,000 topographic map" -> map); unknown (missing) when they
  name none or several, so a rule for map-derived control is never switched off by wording.
* ``block.space_resection_images`` (block): images of a block produced by space resection (the
  manifest's ``blocks[].method``); §12.7 "in the case of orthoimages created by space resection (either
  per image or per photogramme), each will be treated as a block". Not applicable to other blocks.
"""

from __future__ import annotations

import datetime as dt
import itertools
from typing import Any

import pandas as pd

from ...delivery import vocabulary
from ...delivery.in_force import INTERNAL
from ...provenance import Evidence
from ..registry import Measured, ProviderContext, provider

#: words of a free-text GCP source that name its kind (§7.1, §7.3 "Source (GPS; photogrammetric mapping
#: service archive, geodetic survey, topographic map, etc.)"); whole words after vocabulary.key()
KIND_WORDS: dict[str, frozenset[str]] = {
    "survey": frozenset(
        {
            "survey",
            "surveyed",
            "gnss",
            "gps",
            "dgps",
            "rtk",
            "geodetic",
            "tachymeter",
            "levelling",
            "leveling",
            "total_station",
            "sapos",
            "cors",
            "vrs",
        }
    ),
    "map": frozenset({"map", "maps", "cadastral_map", "topographic_map", "digitised", "digitized"}),
    "photogrammetric": frozenset(
        {"stereo", "stereoscopic", "photogrammetric", "photogrammetry", "aerotriangulation"}
    ),
    "orthoimage": frozenset(
        {"orthoimage", "orthoimages", "orthophoto", "orthophotos", "dsm", "dtm"}
    ),
}


def _one(
    name: str,
    unit: str,
    item: str,
    value: Any,
    ev: tuple[Evidence, ...],
    note: str,
    na: str | None = None,
) -> Measured:
    s = pd.Series
    return Measured(
        name,
        "delivery",
        unit,
        s({item: value}, dtype=object),
        s({item: ev}, dtype=object),
        notes=s({item: note}, dtype=object),
        na=s({item: na}, dtype=object) if na else None,
    )


@provider(scope="delivery", measures={"points.shared_ids": "1"})
def shared_point_ids(ctx: ProviderContext) -> list[Measured]:
    """Identifiers that name both a GCP and one of the contractor's check points: the delivery's own
    table (``internal_checkpoints`` when the checker measured its own points, whose names are the
    checker's and never reject the contractor's products)."""
    d = ctx.delivery
    gcps = d.table("gcps")
    own = d.table(INTERNAL)
    cp_tables = (
        [own] if own is not None else [t for t in (d.table("checkpoints"),) if t is not None]
    )
    name = "points.shared_ids"
    if gcps is None or not cp_tables:
        missing = "gcps" if gcps is None else "checkpoints"
        return [
            _one(
                name,
                "1",
                d.id,
                None,
                (d.manifest_evidence("tables"),),
                "",
                na=f"no {missing} table: no identifier can be shared",
            )
        ]
    g = gcps.ids.astype(str)
    both: set[str] = set()
    ev_cps: list[Evidence] = []
    n_cps = 0
    for cps in cp_tables:
        c = cps.ids.astype(str)
        n_cps += len(c)
        shared = set(g) & set(c)
        both |= shared
        ev_cps.append(
            Evidence(
                cps.file,
                cps.sha256,
                tuple(int(r) for r in cps.df["_row"][c.isin(shared).to_numpy()]),
            )
        )
    ids = sorted(both)
    ev = (
        Evidence(
            gcps.file, gcps.sha256, tuple(int(r) for r in gcps.df["_row"][g.isin(ids).to_numpy()])
        ),
        *ev_cps,
    )
    note = (
        f"{len(ids)} identifier(s) name a GCP and a check point: {', '.join(ids[:10])}"
        + (f" and {len(ids) - 10} more" if len(ids) > 10 else "")
        if ids
        else f"the {len(g)} GCP and {n_cps} check point identifiers are distinct"
    )
    return [_one(name, "1", d.id, float(len(ids)), ev, note)]


def _days(values: list[Any]) -> list[dt.date]:
    out = []
    for v in values:
        if v is None:
            continue
        try:
            out.append(dt.date.fromisoformat(str(v)[:10]))
        except ValueError:
            continue
    return out


@provider(scope="delivery", measures={"scanner.schedule_gaps": "1"})
def scanner_schedule(ctx: ProviderContext) -> list[Measured]:
    """Ends of the scanning period (first and last scan date) without a scanner test."""
    d = ctx.delivery
    name = "scanner.schedule_gaps"
    tests, imgs = d.table("scanner_tests"), d.table("images")
    ev: tuple[Evidence, ...] = ()
    if tests is not None:
        ev += (tests.evidence(tests.df["_row"])[0],)
    if imgs is not None:
        ev += (imgs.evidence(imgs.df["_row"])[0],)
    scans = (
        _days(imgs.df["scan_date"].tolist()) if imgs is not None and "scan_date" in imgs.df else []
    )
    dated = _days(tests.df["date"].tolist()) if tests is not None and "date" in tests.df else []
    if not scans:
        return [
            _one(
                name,
                "1",
                d.id,
                None,
                ev,
                "no images.scan_date: the scanning period is not recorded",
            )
        ]
    first, last = min(scans), max(scans)
    gaps = []
    if not any(t <= first for t in dated):
        gaps.append(f"no test on or before the first scan ({first})")
    if not any(t >= last for t in dated):
        gaps.append(f"no test on or after the last scan ({last})")
    shown = ", ".join(str(t) for t in sorted(dated)) or "none"
    note = f"scanning {first} to {last}; scanner tests dated {shown}" + (
        ": " + "; ".join(gaps) if gaps else ""
    )
    return [_one(name, "1", d.id, float(len(gaps)), ev, note)]


def _norm(v: Any) -> str | None:
    t = str(v).strip().lower().replace(" ", "_").replace("-", "_") if v is not None else ""
    return t or None


@provider(scope="block", measures={"block.space_resection_images": "1"})
def space_resection_blocks(ctx: ProviderContext) -> list[Measured]:
    """Images of each block produced by space resection (each should be a block of its own)."""
    d = ctx.delivery
    name = "block.space_resection_images"
    imgs = d.table("images")
    counts: dict[str, list[int]] = {}
    if imgs is not None:
        for block, row in zip(imgs.df["block"].astype(str), imgs.df["_row"].tolist(), strict=True):
            counts.setdefault(block, []).append(int(row))
    vals: dict[str, Any] = {}
    notes: dict[str, str] = {}
    na: dict[str, str] = {}
    ev: dict[str, tuple[Evidence, ...]] = {}
    for i, b in enumerate(d.manifest.blocks):
        ev[b.id] = (d.manifest_evidence(f"blocks[{i}].method"),)
        if _norm(b.method) != "space_resection":
            na[b.id] = (
                f"block {b.id} is not produced by space resection (blocks[].method: {b.method or 'not given'})"
            )
            continue
        rows = counts.get(b.id, [])
        if imgs is not None:
            ev[b.id] += (Evidence(imgs.file, imgs.sha256, tuple(rows)),)
        vals[b.id] = float(len(rows))
        notes[b.id] = f"{len(rows)} image(s) in block {b.id}, produced by space resection"
    s = pd.Series
    ids = [b.id for b in d.manifest.blocks]
    return [
        Measured(
            name,
            "block",
            "1",
            s({b: vals.get(b) for b in ids}, dtype=object),
            s(ev, dtype=object),
            notes=s(notes, dtype=object),
            na=s(na, dtype=object) if na else None,
        )
    ]


def kind_of_text(text: Any) -> str | None:
    """The one source kind the words of ``text`` name, else None (none or several)."""
    if text is None or not str(text).strip():
        return None
    words = [
        w
        for w in vocabulary.key(
            str(text).replace("(", " ").replace(")", " ").replace(",", " ")
        ).split("_")
        if w
    ]
    grams = set(words) | {f"{a}_{b}" for a, b in itertools.pairwise(words)}
    kinds = {k for k, ws in KIND_WORDS.items() if grams & ws}
    return kinds.pop() if len(kinds) == 1 else None


@provider(scope="gcp", measures={"gcp.source_kind": "text"})
def gcp_source_kind(ctx: ProviderContext) -> list[Measured]:
    """Each GCP's kind of source: the closed source_type, else read from the free-text source."""
    d = ctx.delivery
    t = d.table("gcps")
    name = "gcp.source_kind"
    if t is None:
        return [
            Measured(
                name,
                "gcp",
                "text",
                pd.Series(dtype=object),
                pd.Series(dtype=object),
                notes=pd.Series({"*": "no gcps table"}, dtype=object),
            )
        ]
    ids = t.ids.astype(str).tolist()
    typed = t.df["source_type"].tolist() if "source_type" in t.df else [None] * len(ids)
    text = t.df["source"].tolist() if "source" in t.df else [None] * len(ids)
    vals: dict[str, Any] = {}
    notes: dict[str, str] = {}
    for i, st, tx in zip(ids, typed, text, strict=True):
        if st is not None:
            vals[i], notes[i] = st, f"source_type: {st}"
            continue
        k = kind_of_text(tx)
        vals[i] = k
        notes[i] = (
            f"read from the source text {str(tx)[:60]!r}: {k}"
            if k
            else "no source_type, and the source text names no single kind (survey, map, photogrammetric, "
            f"orthoimage): {str(tx)[:60]!r}"
            if tx is not None
            else "no source_type or source given"
        )
    ev = pd.Series(
        {
            i: (Evidence(t.file, t.sha256, (int(r),)),)
            for i, r in zip(ids, t.df["_row"].tolist(), strict=True)
        },
        dtype=object,
    )
    return [
        Measured(
            name,
            "gcp",
            "text",
            pd.Series(vals, dtype=object),
            ev,
            notes=pd.Series(notes, dtype=object),
        )
    ]
