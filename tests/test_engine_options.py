"""Typed options through the engine (issue 28 item 6): ``CheckOptions`` hands the engine one frozen
``EngineOptions`` (no string-keyed dict read by name), with the same behaviour."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from tests.checking import records

from orthospec.api import CheckOptions, check
from orthospec.engine.evaluator import Evaluator
from orthospec.engine.registry import EngineOptions


def test_check_options_become_typed_engine_options():
    opts = CheckOptions(
        workers=2,
        scheduler="tcp://x:1",
        progress=True,
        sample=("image", frozenset({"I1"})),
        cache_dir=Path("/tmp/c"),
        max_items=3,
    ).engine_options()
    assert opts == EngineOptions(
        workers=2,
        scheduler="tcp://x:1",
        progress=True,
        sample=("image", frozenset({"I1"})),
        cache_dir="/tmp/c",
    )
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.workers = 3  # type: ignore[misc]


def test_a_mapping_is_still_accepted_and_unknown_names_refused():
    assert EngineOptions.of(
        {"workers": 1, "cache_dir": Path("/tmp/c"), "scheduler": None}
    ) == EngineOptions(workers=1, cache_dir="/tmp/c")
    assert EngineOptions.of(None) == EngineOptions()
    with pytest.raises(ValueError, match="unknown engine option.*wokers"):
        EngineOptions.of({"wokers": 1})
    assert EngineOptions(workers=4).get("workers") == 4 and EngineOptions().get("nothing", 7) == 7


def test_the_evaluator_and_providers_read_the_typed_options(make_delivery, mini_profile):
    d = make_delivery()
    res = check(
        d,
        mini_profile,
        params=["tolerance_xy=0.5m"],
        options=CheckOptions(sample=("image", {"I1", "I3"})),
    )
    fh = {r["item"]: r for r in records(res.document) if r["rule"] == "R-FH"}
    assert fh["I2"]["verdict"] == "not_applicable" and fh["I2"]["reason"] == "outside_sample"
    from orthospec.delivery.reader import open_delivery
    from orthospec.engine.params import parse_cli_params, resolve_parameters
    from orthospec.profile.loader import load_profile

    prof = load_profile(mini_profile)
    dd = open_delivery(d)
    values = resolve_parameters(
        prof, {}, parse_cli_params(["tolerance_xy=0.5m"]), manifest=dd.flat_manifest()
    )
    ev = Evaluator(prof, dd, values, options={"sample": ("image", {"I1"})})
    assert isinstance(ev.ctx.options, EngineOptions)
    assert ev.ctx.cache.ctx.options is ev.ctx.options  # the providers read the same typed object
