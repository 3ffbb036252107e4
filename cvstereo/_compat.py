"""The import paths of cvstereo 0.2 that name moved modules, kept working through 0.x.

0.3 arranged the modules in packages that show the architecture (:mod:`cvstereo.model`,
:mod:`cvstereo.frames`, :mod:`cvstereo.matchers`, :mod:`cvstereo.geometry`, :mod:`cvstereo.evaluation`, ...;
``CHANGELOG.md`` lists every move). One table, :data:`MOVED`, maps each old module name to the module that holds
its code now, and one finder at the end of :data:`sys.meta_path` answers an import of an old name with the new
module object itself: ``import cvstereo.depth`` gives :mod:`cvstereo.geometry.depth`, so every class is the same
object under both names (``isinstance`` holds, pickles made under an old name load) and no shim file repeats a
module's names. The finder is asked only for names no real module has, so it never hides a module.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys

__all__ = ["MOVED", "install"]

#: old module name (cvstereo 0.2) -> the module that holds its code now.
MOVED: dict[str, str] = {}


class _AliasLoader(importlib.abc.Loader):
    """Loads an old name as the module it moved to: the same module object, not a copy."""

    def __init__(self, target: str):
        self.target = target

    def create_module(self, spec):
        # The import system keeps the module's own __name__, __spec__ and __file__ (it sets them only where
        # missing), so the module stays what it is and is merely also known under the old name.
        return importlib.import_module(self.target)

    def exec_module(self, module) -> None:
        """Nothing to run: the module ran when it was imported under its own name."""


class _AliasFinder(importlib.abc.MetaPathFinder):
    """Finds the old module names of :data:`MOVED`; every other name is left to the finders before it."""

    def find_spec(self, fullname, path=None, target=None):
        new = MOVED.get(fullname)
        return None if new is None else importlib.util.spec_from_loader(fullname, _AliasLoader(new))


def install() -> None:
    """Put the finder of old names at the end of :data:`sys.meta_path` (once)."""
    if not any(isinstance(finder, _AliasFinder) for finder in sys.meta_path):
        sys.meta_path.append(_AliasFinder())
