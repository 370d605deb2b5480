"""Property (issue 25): for a random field among those the rules now compute from the files, an edited
declaration never turns a REJECTED planted example into ACCEPTED.

The planted examples: the two shipped failing examples, and shipped passing examples with one defect
planted in their files (rasters decimated to 1 m, georeferenced 20 km away, one scene's pixels under
another scene's georeference, a VHR scene with one GCP). Each is checked once as planted (REJECTED);
hypothesis then draws a field of tests/declared_fields.py (extensible: other helpers add theirs) and a
value, writes it into a copy of the planted delivery (every row of the column, or the manifest path)
and checks again with the same checker file. The raster result cache of the run is shared, so only
the declarations are re-read.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tests import test_redteam_measured as rt
from tests.checking import check_with, resigned
from tests.declared_fields import DECLARED_FIELDS

from orthospec.errors import OrthospecError

PLANTED: dict[str, tuple[str, Callable[[Path], None] | None]] = {
    "aerial-fail": ("aerial-fail", None),
    "satellite-fail": ("satellite-fail", None),
    "aerial-pass+decimated": ("aerial-pass", rt._decimate_to(1.0)),
    "aerial-pass+outside": ("aerial-pass", rt._shift_all(20_000.0)),
    "satellite-pass+copy": ("satellite-pass", rt._scene_under_other_georeference),
    "satellite-pass+one-gcp": ("satellite-pass", rt._one_gcp("S02_SC1")),
}


@pytest.fixture(scope="module")
def planted(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path, Path]]:
    """name -> (planted delivery, its checker file, the run's raster cache); each checked REJECTED once."""
    root = tmp_path_factory.mktemp("planted")
    cache = root / "raster-cache"
    out = {}
    for name, (example, edit) in PLANTED.items():
        d = root / name / example
        shutil.copytree(rt.EXAMPLES / example, d)
        if edit is not None:
            edit(d)
        checker = resigned(rt.CHECKERS / f"{example}.yaml", d, root / name / "checker.yaml")
        doc = yaml.safe_load(checker.read_text(encoding="utf-8"))
        items = rt._delivered_items(d)
        doc["manual_checks"] = [
            m for m in doc.get("manual_checks") or [] if m["item"] == "*" or m["item"] in items
        ]
        checker.write_text(
            yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8"
        )
        res = check_with(
            d, "jrc-v3", checker=checker, date=rt.DATE, options={"cache_dir": str(cache)}
        )
        assert not res.accepted, f"{name}: the planted example must be rejected to start with"
        out[name] = (d, checker, cache)
    return out


def _applicable(d: Path, field: Any) -> bool:
    return field.needs_table is None or (d / "tables" / f"{field.needs_table}.csv").is_file()


#: examples drawn per run (each is one check of a planted example: seconds); raise it for a deeper search
EXAMPLES = int(os.environ.get("ORTHOSPEC_PROPERTY_EXAMPLES", "16"))


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_an_edited_declaration_never_accepts_a_planted_example(
    planted: dict[str, tuple[Path, Path, Path]],
    tmp_path_factory: pytest.TempPathFactory,
    data: st.DataObject,
) -> None:
    name = data.draw(st.sampled_from(sorted(planted)), label="planted example")
    base, checker, cache = planted[name]
    fields = [f for f in DECLARED_FIELDS if _applicable(base, f)]
    field = data.draw(st.sampled_from(fields), label="declared field")
    value = data.draw(field.values, label=field.name)
    d = tmp_path_factory.mktemp("edited") / base.name
    shutil.copytree(base, d)
    field.write(d, value)
    try:
        res = check_with(
            d, "jrc-v3", checker=checker, date=rt.DATE, options={"cache_dir": str(cache)}
        )
    except OrthospecError:
        return  # refused (exit 2): never ACCEPTED
    assert not res.accepted, f"{name}: {field.name} = {value!r} turned REJECTED into ACCEPTED"


def test_every_declared_field_writes_something(tmp_path: Path) -> None:
    """Each registered field changes the delivery it is written into (so the property is not vacuous)."""
    import filecmp

    for field in DECLARED_FIELDS:
        example = "satellite-pass" if field.needs_table == "scenes" else "aerial-pass"
        d = tmp_path / field.name / example
        shutil.copytree(rt.EXAMPLES / example, d)
        value = field.sample
        field.write(d, value)
        changed = [
            f
            for f in (
                "delivery.yaml",
                *(f"tables/{t}" for t in ("images.csv", "scenes.csv", "cameras.csv")),
            )
            if (d / f).is_file()
            and not filecmp.cmp(d / f, rt.EXAMPLES / example / f, shallow=False)
        ]
        assert changed, field.name
