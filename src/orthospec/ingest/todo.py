"""TODO.md of a draft: what the files could not tell, each with the rules that stay ``missing``.

Read from the profile alone (as ``orthospec init`` reads it for its template, profile/template.py):
for every rule that can apply to the draft's sensor, the delivery facts it reads (its measure,
its ``when``, the names in its threshold) and, for measures computed from tables, the tables
behind them (``spec.template.rule_inputs``, which ``orthospec init`` uses for its template too). A
rule reading a fact the draft leaves empty is listed under that
fact's entry; the map rule -> line is written beside TODO.md (``draft.todo_rules``) and the
evaluator appends "see TODO.md line N" to every ``missing`` record (engine/evaluator.py). A rule
the map does not name cites the last entry, which says to read the record's own message.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..delivery.convention import table_specs
from ..profile.applicability import cannot_apply
from ..profile.template import rule_inputs

#: what a TODO entry says about a manifest field (why the files cannot tell)
MANIFEST_HELP = {
    "id": "the delivery's identifier (the metadata states none)",
    "project.id": "the project id, the same across redeliveries",
    "dates.delivered": "the date the delivery was handed over",
    "operator.name": "who produced the delivery's QC record (JRC §2.4)",
    "contractor.name": "the contractor (the metadata names no originator)",
    "product.gsd": "the delivered pixel size the contract fixes (the metadata states none; the images' "
    "own pixel size is measured by the check, never copied here)",
    "product.mosaic": "whether the product is a mosaic (no seamlines delivered)",
    "product.dem_delivered": "whether a DEM is delivered",
    "product.accuracy_statement": "the producer's statement of positional accuracy",
    "sensor.digital": "digital or film sensor (the metadata names no camera the draft knows)",
    "project.crs": "the CRS the delivery's coordinates are written in (the metadata states none)",
    "project.area_of_interest": "the area the images must cover",
    "vectors.seamlines": "the mosaic's seamline polygons (not in the files)",
    "edge_targets": "edge targets for the sharpness measurement (JRC §6.3; CEOS)",
    "blocks.reported": "the RMSE per block the contractor's QC report states (blocks[].reported)",
    "blocks.method": "how each block was oriented: aerotriangulation, space_resection, rpc... (blocks[].method)",
    "product.orthorectification": "how the orthoimages were produced (the files do not say)",
}


@dataclass
class Entry:
    key: tuple[str, ...]
    title: str
    why: str
    rules: list[str] = field(default_factory=list)
    #: rules the draft's sensor excludes (not listed; mapped, in case the engine still reports them)
    hidden: list[str] = field(default_factory=list)
    line: int = 0


@dataclass
class DraftState:
    """What the draft fills: manifest paths with a value, tables declared with their filled columns."""

    filled: set[str]
    tables: dict[str, set[str]]
    blocks: bool
    sensor: str
    digital: bool | None
    #: table -> why the files gave it but the draft could not declare it (e.g. points without blocks)
    withheld: dict[str, str] = field(default_factory=dict)
    #: parameters the draft's profile leaves to the ITT (the checker's to state)
    itt_params: set[str] = field(default_factory=set)


def _empty(inp: tuple[str, ...], st: DraftState) -> bool:
    kind = inp[0]
    if kind == "manifest":
        path = inp[1]
        if path.startswith("tables."):
            return path.split(".", 1)[1] not in st.tables
        if path in ("sensor.type",):
            return False
        return not any(f == path or f.startswith(path + ".") for f in st.filled)
    if kind == "table":
        return inp[1] not in st.tables
    if kind == "column":
        return inp[1] not in st.tables or inp[2] not in st.tables[inp[1]]
    if kind == "blocks":
        return not st.blocks
    if kind == "param":
        return inp[1] in st.itt_params
    return kind == "checker"


def entries(profile: Any, st: DraftState) -> list[Entry]:
    """TODO entries in a stable order (manifest fields, blocks, tables, columns, the checker's)."""
    params = set(profile.parameters)
    found: dict[tuple[str, ...], Entry] = {}
    specs = table_specs()
    for rule in profile.rules:
        hidden = cannot_apply(rule, {st.sensor}, st.digital) is not None
        for inp in rule_inputs(rule, params):
            if not _empty(inp, st):
                continue
            if inp[0] == "column" and inp[1] not in st.tables:
                inp = ("table", inp[1])
            e = found.get(inp)
            if e is None:
                e = found[inp] = _entry(inp, st, specs, profile)
            (e.hidden if hidden else e.rules).append(rule.id)
            break  # one entry per rule: the first empty fact it reads
    order = {"manifest": 0, "blocks": 1, "table": 2, "column": 3, "param": 4, "checker": 5}
    ranked = sorted(found.values(), key=lambda e: (order[e.key[0]], e.key))
    out = [e for e in ranked if e.rules]
    out.append(
        Entry(
            ("other",),
            "anything else a record reports `missing`",
            "a value the check could not measure from the files (a broken image, a rule whose "
            "inputs are present but incomplete): the record's own message says which file and row",
        )
    )
    return out + [e for e in ranked if not e.rules]  # read only by rules of the other sensor type


def _entry(inp: tuple[str, ...], st: DraftState, specs: dict[str, Any], profile: Any) -> Entry:
    kind = inp[0]
    if kind == "manifest" and inp[1].startswith("documents."):
        return Entry(
            inp,
            f"delivery.yaml `{inp[1]}`",
            "a report the profile asks for; no file of the source is known to be it: name it under "
            "`documents:` (INGEST.md lists the files not read)",
        )
    if inp == ("manifest", "vectors.seamlines.image_id"):
        return Entry(
            inp,
            "attribute `image_id` of the seamline polygons (the file delivery.yaml `vectors.seamlines` "
            "names)",
            "each polygon names the image its pixels come from (JRC Table 11, area "
            "selection); the source's seamlines carry no such attribute: add it in a GIS",
        )
    if kind == "manifest":
        return Entry(
            inp, f"delivery.yaml `{inp[1]}`", MANIFEST_HELP.get(inp[1], "not stated by the files")
        )
    if kind == "blocks":
        return Entry(
            inp,
            "blocks (delivery.yaml `blocks:` and the `block` column of the tables)",
            "the files give no block outlines: run `init` again with `--blocks FILE` (a vector file "
            "of the block outlines) or write the blocks and each point's block by hand",
        )
    if kind == "table":
        why = st.withheld.get(inp[1]) or "not in the files"
        return Entry(
            inp, f"table `{inp[1]}` (tables/{inp[1]}.csv): {specs[inp[1]].description}", why
        )
    if kind == "column":
        cs = specs[inp[1]].columns[inp[2]]
        return Entry(
            inp, f"column `{inp[2]}` of tables/{inp[1]}.csv", f"{cs.description} Not in the files."
        )
    if kind == "param":
        p = profile.parameters.get(inp[1])
        desc = p.description if p is not None else ""
        return Entry(
            inp,
            f"for the checker: ITT parameter `{inp[1]}`",
            f"{desc} Stated in the checker's file (`parameters:`), by `--param` or a tender profile; "
            "never by the delivery.",
        )
    what = {
        "manual_checks": "manual checks: the checker's verdicts (`manual_checks:` in the checker's file)",
        "blocks": "block outlines in force (`blocks:` in the checker's file)",
        "area_of_interest": "the area of interest (`area_of_interest:` in the checker's file)",
    }
    return Entry(
        inp,
        f"for the checker: {what.get(inp[1], inp[1])}",
        "the external QC's part (JRC §2, §12), outside the delivery",
    )


def render(entries_: list[Entry], *, head: list[str]) -> tuple[str, dict[str, list[Any]]]:
    """TODO.md text and the rule -> [line, title] map (``*``: the "anything else" entry)."""
    lines = list(head)
    rules: dict[str, list[Any]] = {}
    other = next(e for e in entries_ if e.key == ("other",))
    headed = False
    for e in entries_:
        if not e.rules and e.key != ("other",) and not headed:
            lines += [
                "",
                "## Read only by rules of the other sensor type (not applicable to this draft)",
                "",
            ]
            headed = True
        e.line = len(lines) + 1
        lines.append(f"- [ ] {e.title}: {e.why}")
        if e.rules:
            shown = ", ".join(sorted(set(e.rules)))
            lines.append(f"  Rules `missing` until it is filled ({len(set(e.rules))}): {shown}")
        for r in e.rules + e.hidden:
            rules.setdefault(r, [e.line, _plain(e.title)])
    rules["*"] = [other.line, _plain(other.title)]
    return "\n".join(lines) + "\n", dict(sorted(rules.items()))


def _plain(s: str) -> str:
    return s.replace("`", "")
