"""Former name of :mod:`orthospec.profile` (the profile language: loading, validation, diff).

Kept so that plugins written against ``orthospec.spec`` and ``orthospec.spec.<module>`` keep
working: every ``orthospec.spec.X`` import returns the very module ``orthospec.profile.X`` (one
module object, not a copy). New code imports :mod:`orthospec.profile`.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
from types import ModuleType

_NEW = "orthospec.profile"


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``orthospec.spec.X`` and hands back the module ``orthospec.profile.X``."""

    def find_spec(self, fullname: str, path: object = None, target: object = None
                  ) -> importlib.machinery.ModuleSpec | None:
        if fullname.startswith(__name__ + "."):
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        return importlib.import_module(_NEW + spec.name[len(__name__):])

    def exec_module(self, module: ModuleType) -> None:
        """The module was run under its own name already."""


if not any(isinstance(f, _Alias) for f in sys.meta_path):
    sys.meta_path.insert(0, _Alias())
