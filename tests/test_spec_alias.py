"""The profile package's former name still imports (plugins written against ``orthospec.spec``)."""

from __future__ import annotations

import importlib


def test_old_module_names_are_the_new_modules() -> None:
    import orthospec.spec.loader as old_loader
    from orthospec.spec.operators import __name__ as old_name

    import orthospec.profile.loader as new_loader

    assert old_loader is new_loader
    assert old_name == "orthospec.profile.operators"
    assert importlib.import_module("orthospec.spec.models") is importlib.import_module(
        "orthospec.profile.models"
    )
