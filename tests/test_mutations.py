"""Mutation suite: every mandatory automatic rule of every shipped profile can reject a delivery.

Why: a mandatory rule that a planted violation cannot turn into REJECTED is a rule an auditor cannot
trust (issue 12). One data table, ``tests/data/mutations.yaml``, drives the suite: each case names a
rule, the item it must fail on and the mutation that plants the violation into a copy of an example
delivery (edit a CSV cell, drop rows, change a manifest key, replace an image). Cases of one group
share one copied delivery and one check run (their mutations touch different items), which keeps the
suite fast. Rules that cannot be planted are listed in the same table with their reason, and
``test_every_mandatory_automatic_rule_has_a_case`` fails when a new mandatory automatic rule has
neither, so the table cannot fall behind the profiles.

Each case asserts three things: in the unmutated delivery the rule does not fail on the item (so the
mutation, not the example, causes the finding), after the mutation the delivery is rejected (the
exit code of ``orthospec check`` is 1), and the rule is among the mandatory fail/missing/error records
for that item. A rule whose consequence is ``incomplete`` (the checker's fault, issue 26) is planted as
such (``expect: incomplete``): the delivery is never accepted, the verdict is ``incomplete`` (exit 3)
and ``rollup.incomplete`` names the item and the rule. The coverage line ("mutation coverage: N/M
...") is printed at the end of the run.
"""

from __future__ import annotations

import csv
import functools
import io
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rasterio
import yaml
from rasterio.transform import Affine
from tests.checking import CHECKERS, DATE, EXAMPLES, ROOT, check_with, records, resigned

from mutation_coverage import PLUGIN_NAME, CoverageReport, mandatory_automatic
from orthospec.errors import OrthospecError
from orthospec.profile.loader import ResolvedProfile, load_profile

TABLE = yaml.safe_load(
    (Path(__file__).parent / "data" / "mutations.yaml").read_text(encoding="utf-8")
)
SHIPPED = {name: ROOT / "specs" / f"{name}.yaml" for name in TABLE["profiles"]}
BAD = ("fail", "missing", "error")


# ---------------------------------------------------------------- the table
def _cases() -> list[dict[str, Any]]:
    out = []
    for g in TABLE["groups"]:
        for c in g["cases"]:
            out.append(
                {
                    **c,
                    "group": g["id"],
                    "profile": g["profile"],
                    "example": g["example"],
                    "params": g.get("params") or {},
                }
            )
    return out


CASES = _cases()
GROUPS = {g["id"]: g for g in TABLE["groups"]}
EXCEPTIONS = {(e["profile"], e["rule"]): e["reason"] for e in TABLE.get("exceptions") or []}


# ---------------------------------------------------------------- mutations
def _read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(encoding="utf-8", newline="") as fh:
        reader = csv.DictReader(fh)
        return list(reader.fieldnames or []), list(reader)


def _write_csv(path: Path, columns: list[str], rows: list[dict[str, str]]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    path.write_text(buf.getvalue(), encoding="utf-8")


def _match(row: dict[str, str], where: dict[str, Any] | None) -> bool:
    return all(row.get(k) == str(v) for k, v in (where or {}).items())


def _table_path(root: Path, table: str) -> Path:
    manifest = yaml.safe_load((root / "delivery.yaml").read_text(encoding="utf-8"))
    return root / manifest["tables"][table]


def _mutate_csv(root: Path, m: dict[str, Any]) -> None:
    _edit_csv(_table_path(root, m["table"]), m)


def _mutate_checker_csv(root: Path, m: dict[str, Any]) -> None:
    """Edit a table of the checker folder (the external QC's measurements, e.g. its check points)."""
    _edit_csv(_own_checker(root) / "tables" / f"{m['table']}.csv", m)


def _delete_checker_file(root: Path, m: dict[str, Any]) -> None:
    (_own_checker(root) / m["path"]).unlink()


def _mutate_checker_grid(root: Path, m: dict[str, Any]) -> None:
    """Change the marks of every cell of one image in the checker's inspection grid (as in QGIS)."""
    from pyogrio import raw

    from orthospec.inspection.grid import mark_cells

    path = _own_checker(root) / "inspection.gpkg"
    _, _, _, (ids, images) = raw.read(path, layer="cells", columns=["cell_id", "image_id"])
    hits = [c for c, i in zip(ids.tolist(), images.tolist(), strict=True) if i == m["image"]]
    assert hits, f"no cell of image {m['image']} in the grid"
    mark_cells(path, {c: m["set"] for c in hits})


def _own_checker(root: Path) -> Path:
    """The checker folder of a copied example, copied beside it on its first mutation."""
    mutated = root.parent / "checker"
    if not mutated.is_dir():
        shutil.copytree(CHECKERS / root.name, mutated)
    return mutated


def _edit_csv(path: Path, m: dict[str, Any]) -> None:
    columns, rows = _read_csv(path)
    hit = [r for r in rows if _match(r, m.get("where"))]
    assert hit, f"mutation matches no row: {m}"
    if "keep" in m:  # drop matching rows beyond the first `keep`
        drop = {id(r) for r in hit[m["keep"] :]}
        rows = [r for r in rows if id(r) not in drop]
    for col, value in (m.get("set") or {}).items():
        if col not in columns:
            columns.append(col)
            for r in rows:
                r.setdefault(col, "")
        for r in hit:
            r[col] = "" if value is None else str(value)
    for col, ref in (m.get("debias") or {}).items():  # remove the mean error of the matching rows
        mean = sum(float(r[col]) - float(r[ref]) for r in hit) / len(hit)
        for r in hit:
            r[col] = f"{float(r[col]) - mean:.3f}"
    for col, (ref, factor) in (
        m.get("scale_error") or {}
    ).items():  # col = ref + factor x (col - ref)
        for r in hit:
            r[col] = f"{float(r[ref]) + float(factor) * (float(r[col]) - float(r[ref])):.3f}"
    for col, delta in (m.get("add") or {}).items():  # after debias and scale_error
        for r in hit:
            r[col] = f"{float(r[col]) + float(delta):.3f}"
    _write_csv(path, columns, rows)


def _set_path(doc: Any, dotted: str, value: Any, *, delete: bool = False) -> None:
    keys = dotted.split(".")
    for k in keys[:-1]:
        doc = doc[int(k)] if isinstance(doc, list) else doc.setdefault(k, {})
    last = keys[-1]
    if isinstance(doc, list):
        if delete:
            del doc[int(last)]
        else:
            doc[int(last)] = value
    elif delete:
        doc.pop(last, None)
    else:
        doc[last] = value


def _mutate_manifest(root: Path, m: dict[str, Any]) -> None:
    path = root / "delivery.yaml"
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    for dotted, value in (m.get("set") or {}).items():
        _set_path(doc, dotted, value)
    for dotted in m.get("delete") or []:
        _set_path(doc, dotted, None, delete=True)
    for dotted, n in (m.get("copy_blocks") or {}).items():  # append n copies of a block, new ids
        src = next(b for b in doc["blocks"] if b["id"] == dotted)
        for i in range(n):
            # without an outline: copies of B01's polygon would overlap B01 (refused at read, red team R17)
            doc["blocks"].append(
                {**src, "id": f"{dotted}-X{i + 1:02d}", "reported": {}, "polygon": None}
            )
    path.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8")


def _mutate_raster(root: Path, m: dict[str, Any]) -> None:
    path = root / m["file"]
    if m.get("truncate"):
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 3])
        return
    with rasterio.open(path) as src:
        profile, arr = src.profile, src.read()
    if "pixel_size" in m:
        t = profile["transform"]
        profile["transform"] = Affine(m["pixel_size"], 0.0, t.c, 0.0, -m["pixel_size"], t.f)
    if "shift" in m:  # the same pixels georeferenced elsewhere (map units east, north)
        t = profile["transform"]
        profile["transform"] = Affine(t.a, t.b, t.c + m["shift"][0], t.d, t.e, t.f + m["shift"][1])
    if "crs" in m:
        profile["crs"] = m["crs"]
    if "driver" in m:  # another format, same name: what a mislabelled file looks like
        profile = {
            k: v
            for k, v in profile.items()
            if k in ("width", "height", "count", "dtype", "crs", "transform")
        }
        profile["driver"] = m["driver"]
    if "fill" in m:
        arr = np.full_like(arr, m["fill"])
    path.unlink()
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(arr)


def _delete_file(root: Path, m: dict[str, Any]) -> None:
    (root / m["path"]).unlink()


def _write_file(root: Path, m: dict[str, Any]) -> None:
    path = root / m["path"]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(m["text"], encoding="utf-8")


def _derive_table(root: Path, m: dict[str, Any]) -> None:
    """A new table with one row per row of an existing one: copied id columns plus constant values."""
    _, rows = _read_csv(_table_path(root, m["from"]))
    columns = [*m["copy"], *m["set"]]
    out = [
        {
            **{c: r[c] for c in m["copy"]},
            **{k: "" if v is None else str(v) for k, v in m["set"].items()},
        }
        for r in rows
    ]
    _write_csv(root / m["path"], columns, out)
    _mutate_manifest(root, {"set": {f"tables.{m['table']}": m["path"]}})


def _signed(root: Path) -> Path:
    """The checker signs what it receives: a copied (planted) example gets its pins re-signed (the
    test is about the rule catching the defect, not the checker file's binding)."""
    if root.parent == EXAMPLES:  # the shipped example, unchanged: its own checker folder
        return checker_for(root)
    return resigned(checker_for(root), root, root.parent / "signed")


def checker_for(root: Path) -> Path:
    """The checker folder for a copied example: a mutated copy beside the delivery, else the shipped one."""
    mutated = root.parent / "checker"
    return mutated if mutated.is_dir() else CHECKERS / root.name


def _mutate_checker(root: Path, m: dict[str, Any]) -> None:
    """Change the external QC's verdicts (the checker's file, outside the delivery) for matching entries."""
    path = _own_checker(root) / "checker.yaml"
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    hits = [e for e in doc["manual_checks"] if all(e.get(k) == v for k, v in m["where"].items())]
    assert hits, f"no checker entry matches {m['where']}"
    for e in hits:
        e.update(m["set"])
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")


OPS = {
    "checker": _mutate_checker,
    "derive": _derive_table,
    "csv": _mutate_csv,
    "manifest": _mutate_manifest,
    "raster": _mutate_raster,
    "delete": _delete_file,
    "write": _write_file,
    "checker_csv": _mutate_checker_csv,
    "checker_delete": _delete_checker_file,
    "checker_grid": _mutate_checker_grid,
}


def apply_mutations(root: Path, mutations: list[dict[str, Any]]) -> None:
    for m in mutations:
        ((op, spec),) = m.items()
        OPS[op](root, spec)


# ---------------------------------------------------------------- runs (cached per module)
@functools.cache
def _profile(name: str) -> ResolvedProfile:
    return load_profile(SHIPPED[name])


def _run(
    root: Path, profile: str, params: dict[str, Any], cache: Path | None = None
) -> dict[str, Any]:
    """One check through the library; ``cache`` is orthospec's raster result cache (by SHA-256), so
    the unchanged images of a copied delivery are not scanned again. The example's checker file signs
    its manual checks, so the baseline is accepted and only the planted violation can reject."""
    res = check_with(
        root,
        _profile(profile),
        params={k: str(v) for k, v in params.items()},
        date=DATE,
        checker=_signed(root),
        options={"workers": 1, "cache_dir": str(cache) if cache else None},
    )
    return res.document


@pytest.fixture(scope="module")
def raster_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("raster-cache")


def _bad(doc: dict[str, Any]) -> dict[tuple[str, str], str]:
    return {
        (r["rule"], r["item"]): r["verdict"]
        for r in records(doc)
        if r["verdict"] in BAD and r["level"] == "mandatory"
    }


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory, raster_cache: Path) -> Iterator[dict[str, Any]]:
    """Lazily computed baseline and mutated runs: {("base", profile, example, params): doc, group: doc}."""
    cache: dict[Any, Any] = {}

    def get(key: Any) -> Any:
        if key in cache:
            return cache[key]
        if key[0] == "base":
            _, profile, example, params, group = key
            root = EXAMPLES / example
            if group:  # the group prepares the example (e.g. adds a statement) before both runs
                root = tmp_path_factory.mktemp(f"{group}-base") / example
                shutil.copytree(EXAMPLES / example, root)
                apply_mutations(root, GROUPS[group]["prepare"])
            cache[key] = _run(root, profile, dict(params), raster_cache)
        else:
            g = GROUPS[key]
            root = tmp_path_factory.mktemp(key) / g["example"]
            shutil.copytree(EXAMPLES / g["example"], root)
            apply_mutations(root, g.get("prepare") or [])
            for c in g["cases"]:
                apply_mutations(root, c["mutations"])
            try:
                cache[key] = _run(root, g["profile"], g.get("params") or {}, raster_cache)
            except OrthospecError as exc:  # refused input: exit 2, never ACCEPTED
                cache[key] = exc
        return cache[key]

    yield get  # type: ignore[misc]


# ---------------------------------------------------------------- tests
@pytest.mark.parametrize("case", CASES, ids=[f"{c['profile']}:{c['rule']}" for c in CASES])
def test_planted_violation_rejects_for_the_rule(runs: Any, case: dict[str, Any]) -> None:
    prepared = case["group"] if GROUPS[case["group"]].get("prepare") else None
    base = runs(
        ("base", case["profile"], case["example"], tuple(sorted(case["params"].items())), prepared)
    )
    key = (case["rule"], str(case["item"]))
    if (
        case.get("baseline") == "missing"
    ):  # no evidence in the example: the mutation plants failing evidence
        assert _bad(base).get(key) == "missing", _bad(base).get(key)
        case = {**case, "verdict": "fail"}
    else:
        assert key not in _bad(base), (
            f"the unmutated {case['example']} already fails {key}: not a planted case"
        )
    doc = runs(case["group"])
    if "refused" in case:  # the delivery convention itself refuses the violation (exit 2)
        assert isinstance(doc, OrthospecError), (
            f"expected the delivery to be refused, got {doc['verdict']}"
        )
        assert case["refused"] in str(doc), str(doc)
        return
    assert not isinstance(doc, OrthospecError), str(doc)
    if case.get("expect") == "incomplete":
        assert doc["verdict"] == "incomplete", doc["rollup"]
        said = [
            t
            for t in doc["rollup"]["incomplete"]
            if t.startswith(f"{case['item']}:") and case["rule"] in t
        ]
        assert said, (
            f"rollup.incomplete names no {case['item']} for {case['rule']}",
            doc["rollup"]["incomplete"],
        )
    else:
        assert doc["verdict"] == "rejected", doc["rollup"]
    bad = _bad(doc)
    assert key in bad, (
        f"{case['rule']} does not fail on {case['item']} after the mutation; mandatory "
        f"findings: {sorted({r for r, _ in bad})}"
    )
    if case.get("verdict"):
        assert bad[key] == case["verdict"], (key, bad[key])


@pytest.mark.parametrize("profile", sorted(SHIPPED))
def test_every_mandatory_automatic_rule_has_a_case(profile: str) -> None:
    """A new mandatory automatic rule must get a case or a listed reason (issue 12 item 7); a rule
    whose consequence is incomplete is planted as such, and only such a rule."""
    rules = mandatory_automatic(profile)
    cased = {c["rule"] for c in CASES if c["profile"] == profile}
    excepted = {r for p, r in EXCEPTIONS if p == profile}
    assert not (rules - cased - excepted), (
        f"mandatory automatic rules without a mutation case: {sorted(rules - cased - excepted)}"
    )
    assert not (cased & excepted), f"both planted and excepted: {sorted(cased & excepted)}"
    stale = (cased | excepted) - rules
    assert not stale, (
        f"table names rules that are not mandatory automatic rules of {profile}: {sorted(stale)}"
    )
    assert all(len(EXCEPTIONS[(profile, r)]) > 20 for r in excepted), (
        "each exception needs a reason"
    )
    spec = yaml.safe_load(SHIPPED[profile].read_text(encoding="utf-8"))["rules"]
    incomplete = {r["id"] for r in spec if r.get("consequence") == "incomplete"}
    for c in (c for c in CASES if c["profile"] == profile):
        assert (c.get("expect") == "incomplete") == (c["rule"] in incomplete), (
            f"{c['rule']}: consequence {'incomplete' if c['rule'] in incomplete else 'rejecting'} but the case "
            f"expects {c.get('expect', 'rejected')}"
        )
    for g in (g for g in TABLE["groups"] if g["profile"] == profile):
        kinds = {c.get("expect", "rejected") for c in g["cases"]}
        assert len(kinds) == 1, (
            f"group {g['id']} mixes incomplete and rejecting cases: each must set the verdict"
        )


@pytest.fixture(scope="module", autouse=True)
def _report_coverage(request: pytest.FixtureRequest) -> None:
    """Print the coverage line at the end of a plain run (under xdist tests/conftest.py registers it)."""
    pm = request.config.pluginmanager
    if not pm.has_plugin(PLUGIN_NAME):
        pm.register(CoverageReport(), PLUGIN_NAME)


def test_uniform_shift_under_the_tolerance_raises_a_visible_finding(
    tmp_path: Path, raster_cache: Path
) -> None:
    """Issue 12 item 5: B01 shifted by 0.45 m in x under the 0.5 m tolerance. RMSEx still passes, the
    §12.4 systematic-error guard warns (default level) and rejects the block once a tender makes it
    mandatory. The t value is recomputed here from the mutated CSV (one-sample t, s with n-1)."""
    root = tmp_path / "aerial-pass"
    shutil.copytree(EXAMPLES / "aerial-pass", root)
    apply_mutations(
        root,
        [
            {
                "checker_csv": {
                    "table": "checkpoints",
                    "where": {"block": "B01"},
                    "debias": {"x": "x_ref"},
                    "scale_error": {"x": ["x_ref", 0.3]},
                    "add": {"x": 0.45},
                }
            }
        ],
    )
    _, rows = _read_csv(checker_for(root) / "tables" / "checkpoints.csv")
    dx = np.array([float(r["x"]) - float(r["x_ref"]) for r in rows if r["block"] == "B01"])
    t_expected = abs(dx.mean()) / (dx.std(ddof=1) / np.sqrt(dx.size))
    assert 0.4 < dx.mean() < 0.5 and np.sqrt(np.mean(dx**2)) < 0.5 and t_expected > 10

    doc = _run(root, "jrc-v3", {}, raster_cache)
    rec = {(r["rule"], r["item"]): r for r in records(doc)}
    assert rec[("JRC-12.7-RMSEX", "B01")]["verdict"] == "pass"
    guard = rec[("JRC-12.4-SYSTEMATIC-X", "B01")]
    assert guard["verdict"] == "warn" and guard["measured"]["value"] == pytest.approx(
        t_expected, rel=1e-3
    )

    strict = _run(root, "jrc-v3", {"systematic_error_level": "mandatory"}, raster_cache)
    assert strict["verdict"] == "rejected" and "B01" in strict["rollup"]["rejected"]["block"]


#: Issue 12 "What was observed", each reproduced on a copy of aerial-pass (satellite-pass for a key
#: starting "satellite:") under jrc-v3: the mutation, the mandatory rules that must now find it (all
#: were ACCEPTED, exit 0, before) and the verdict the text supports - rejected for the contractor's
#: defects, incomplete for the checker's (too few or bad check points, issue 26).
OBSERVED = {
    "block B01 cut to 8 check points": (
        [{"checker_csv": {"table": "checkpoints", "where": {"block": "B01"}, "keep": 8}}],
        {("JRC-12.4-T12-MIN-CHECKPOINTS", "B01")},
        "incomplete",
    ),
    "2 of 30 images truncated (6.7 % > 5 %)": (
        [
            {"raster": {"file": "images/F01_0101.tif", "truncate": True}},
            {"raster": {"file": "images/F02_0203.tif", "truncate": True}},
        ],
        {
            ("JRC-9.2-T7-READABLE", "F01_0101"),
            ("JRC-9.2-T7-READABLE", "F02_0203"),
            ("JRC-12.3-IMAGE-FAIL-SHARE", "D-2026-014"),
        },
        "rejected",
    ),
    "a check point on a GCP and every check point at 1.0 m precision": (
        [
            {
                "checker_csv": {
                    "table": "checkpoints",
                    "where": {"point_id": "B02-C01"},
                    "set": {
                        "x_ref": 507802.959,
                        "y_ref": 5403235.439,
                        "x": 507803.05,
                        "y": 5403235.21,
                    },
                }
            },
            {"checker_csv": {"table": "checkpoints", "set": {"precision_xy": 1.0}}},
        ],
        {("JRC-12.5-INDEPENDENT-CHECKPOINTS", "B02"), ("JRC-DEF-CHECKPOINT-ACCURACY", "B01-C01")},
        "incomplete",
    ),
    # satellite-pass: 4 bands at 0.5 m from 1.24 m multispectral scenes, declared not pan-sharpened; the
    # §10.5 rules were gated on that flag (not applicable, ACCEPTED). Now derived.pansharpened decides.
    "satellite: pan-sharpened product declared pansharpened: false, §10.5.1 record failed": (
        [
            {"manifest": {"set": {"product.pansharpened": False}}},
            {
                "checker": {
                    "where": {"check": "JRC-10.5.1-SAME-MODEL-GCPS"},
                    "set": {"verdict": "fail"},
                }
            },
        ],
        {("JRC-10.5.1-SAME-MODEL-GCPS", "D-2026-031")},
        "rejected",
    ),
}


@pytest.mark.parametrize("case", sorted(OBSERVED))
def test_observed_wrong_acceptances_are_no_longer_accepted(
    tmp_path: Path, raster_cache: Path, case: str
) -> None:
    mutations, expected, verdict = OBSERVED[case]
    example = "satellite-pass" if case.startswith("satellite:") else "aerial-pass"
    root = tmp_path / example
    shutil.copytree(EXAMPLES / example, root)
    apply_mutations(root, mutations)
    doc = _run(root, "jrc-v3", {}, raster_cache)
    assert doc["verdict"] == verdict, case
    assert expected <= set(_bad(doc)), (case, sorted(set(_bad(doc))))
