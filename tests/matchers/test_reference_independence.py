"""The references share no compiled code with the fast path: no reference module imports, directly, a module that
holds a numba kernel (issue 25, item 4).

A reference that called the fast path's kernels (support counting, the left-right check, the merge order, the
Gaussian) would agree with it by construction, and a bug there would pass every fast == reference test. The check
walks the syntax tree of every reference module under ``cvstereo/matchers`` (``reference*.py``), resolves each
import to its source file without running it, and looks in that file for numba's ``njit`` / ``jit`` (as a
decorator, or called to compile a function). Constants and parameter classes the two paths share live in modules
without kernels (e.g. :mod:`cvstereo.matchers._shared.consistency`, :mod:`cvstereo.frames.dynamic_limits`).
"""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest

import cvstereo.matchers

MATCHERS = Path(cvstereo.matchers.__file__).parent
#: numba's compiling decorators, by the names a module may call them.
COMPILERS = {"njit", "jit"}


def reference_modules() -> list[Path]:
    """Every reference module of the matchers: ``reference*.py`` anywhere under cvstereo/matchers."""
    return sorted(MATCHERS.rglob("reference*.py"))


def imported_modules(source: str, package: str) -> set[str]:
    """The dotted names of the modules ``source`` imports anywhere (top level or in a function), relative
    imports resolved against ``package``; ``from m import name`` counts ``m`` and, where ``m.name`` is itself a
    module, that module too."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), package) if node.level \
                else node.module
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names if _spec(f"{base}.{alias.name}"))
    return found


def _spec(name: str):
    try:
        return importlib.util.find_spec(name)
    except (ImportError, ValueError):  # a name inside a module, not a submodule
        return None


def holds_kernel(source: str) -> bool:
    """Whether a module's source compiles a function with numba: ``njit``/``jit`` imported from numba and used, or
    ``numba.njit`` / ``numba.jit`` referenced."""
    tree = ast.parse(source)
    from_numba = {alias.asname or alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
                  and (node.module or "").split(".")[0] == "numba" for alias in node.names
                  if alias.name in COMPILERS}
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id in from_numba:
            return True
        if (isinstance(node, ast.Attribute) and node.attr in COMPILERS and isinstance(node.value, ast.Name)
                and node.value.id == "numba"):
            return True
    return False


def kernel_imports(path: Path, source: str | None = None) -> list[str]:
    """The modules of this package that the reference module at ``path`` imports directly and that hold a numba
    kernel (``source``: its text, read from ``path`` by default)."""
    source = path.read_text() if source is None else source
    package = ".".join(path.relative_to(MATCHERS.parents[1]).with_suffix("").parts[:-1])
    bad = []
    for name in sorted(imported_modules(source, package)):
        if not name.startswith("cvstereo."):
            continue  # third-party code (numpy, OpenCV) is not the fast path's
        spec = _spec(name)
        if spec is not None and spec.origin and spec.origin.endswith(".py") and holds_kernel(
                Path(spec.origin).read_text()):
            bad.append(name)
    return bad


def test_the_matchers_have_their_references():
    # The walk below must see the modules it is about (a renamed folder would make the next test pass vacuously).
    names = {p.relative_to(MATCHERS).as_posix() for p in reference_modules()}
    assert {"frame/reference.py", "frame_area/reference.py", "event_time/reference.py", "event_area/reference.py",
            "event_vector/reference.py", "fused/reference.py", "_shared/reference_frames.py",
            "_shared/reference_windows.py", "_shared/reference_checks.py"} <= names


@pytest.mark.parametrize("path", reference_modules(), ids=lambda p: p.relative_to(MATCHERS).as_posix())
def test_no_reference_imports_a_module_holding_a_kernel(path):
    assert kernel_imports(path) == [], f"{path.relative_to(MATCHERS)} imports compiled kernels' modules"


# What the references imported before they were made independent (fb04c6d): each line names a module that holds
# a kernel, and the check must refuse it.
OLD_IMPORTS = {
    "frame/reference.py": ("from cvstereo.frames.accumulate import filtered_unit, gaussian_filter, signed_frame\n"
                           "from cvstereo.matchers._shared.support import supported\n",
                           ["cvstereo.frames.accumulate", "cvstereo.matchers._shared.support"]),
    "frame_area/reference.py": ("from cvstereo.matchers._shared.support import lr_consistent\n",
                                ["cvstereo.matchers._shared.support"]),
    "event_time/reference.py": ("from cvstereo.frames.dynamic import dynamic_unit\n", ["cvstereo.frames.dynamic"]),
    "_shared/reference_frames.py": ("from cvstereo.frames.dynamic import FORGET_TICKS, RENORM, update_kernel\n"
                                    "from .merge_order import merged_events\n"
                                    "def f():\n    from cvstereo.matchers._shared import sorted_runs\n",
                                    ["cvstereo.frames.dynamic", "cvstereo.matchers._shared.merge_order",
                                     "cvstereo.matchers._shared.sorted_runs"]),
}


@pytest.mark.parametrize("name", list(OLD_IMPORTS))
def test_the_check_refuses_the_old_shared_imports(name):
    source, expected = OLD_IMPORTS[name]
    assert kernel_imports(MATCHERS / name, source) == expected


@pytest.mark.parametrize(("source", "compiles"), [
    ("from numba import njit\n@njit(cache=True)\ndef f(): pass\n", True),
    ("import numba\n@numba.njit\ndef f(): pass\n", True),
    ("import numba\ng = numba.jit(nopython=True)(len)\n", True),
    ("from numba import njit as compiled\nh = compiled(inline='always')(abs)\n", True),
    ("import numba\nprint(numba.__version__)  # numba, but no kernel\n", False),
    ("def njit(f):\n    return f\n", False),
])
def test_a_kernel_is_recognised_by_numbas_compilers(source, compiles):
    assert holds_kernel(source) is compiles
