"""No table keyed by a matcher's name outside its own package (issue 25, item 8).

What a method needs (its parameters, its ``adaptive`` set, its variants) belongs to its matcher's class; a dict
keyed by method names, or a branch on ``method == "frame"``, elsewhere in the library is a second place that must
follow every matcher. Allowed: the registry's table itself (:mod:`cvstereo.matchers._registry`, where names are
defined) and the thesis' published tables (:mod:`cvstereo.evaluation.thesis`: numbers of the thesis, keyed as it
published them).
"""

from __future__ import annotations

import ast
from pathlib import Path

from cvstereo.matchers._registry import BUILTIN_METHODS

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "cvstereo"

#: Files whose name tables are the point: the registry's table, the thesis' published figures.
ALLOWED = {"cvstereo/matchers/_registry.py", "cvstereo/evaluation/thesis.py"}

#: method -> the folder of its package, where its own names may key anything.
HOMES = {name: target.partition(":")[0].replace(".", "/") for name, target in BUILTIN_METHODS.items()}


def _names(node: ast.AST) -> list[str]:
    """The method names a node spells as string constants: itself, or the elements of a tuple, list or set."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in HOMES:
        return [node.value]
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [n for elt in node.elts for n in _names(elt)]
    return []


def name_tables(source: str, path: str) -> list[str]:
    """``path:line: method`` for every dict key, ``dict(name=...)`` keyword, comparison or ``case`` that spells a
    method name in a file outside that method's package (``path`` relative to the repository, with ``/``)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        spelled: list[str] = []
        if isinstance(node, ast.Dict):
            spelled = [n for key in node.keys if key is not None for n in _names(key)]
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict":
            spelled = [kw.arg for kw in node.keywords if kw.arg in HOMES]
        elif isinstance(node, ast.Compare):
            spelled = [n for side in (node.left, *node.comparators) for n in _names(side)]
        elif isinstance(node, ast.MatchValue):
            spelled = _names(node.value)
        found += [(node.lineno, name) for name in spelled
                  if not (path.startswith(HOMES[name] + "/") or path == HOMES[name] + ".py")]
    return [f"{path}:{line}: {name}" for line, name in sorted(found, key=lambda item: item[0])]


def test_the_library_keys_nothing_by_a_method_name_outside_its_package():
    found = []
    for file in sorted(LIBRARY.rglob("*.py")):
        rel = file.relative_to(ROOT).as_posix()
        if rel not in ALLOWED:
            found += name_tables(file.read_text(), rel)
    assert found == []


def test_the_check_finds_a_table_and_a_branch_and_spares_the_home_package():
    source = ('ADAPTIVE = {"frame": 1, ("event-time", "shared"): 2, "threshold": 3}\n'
              'if method == "event-area" or m in ("sgbm", "other"):\n    pass\n'
              'SETS = dict(fused=1, window_us=2)\n'
              'match method:\n    case "stereobm":\n        pass\n')
    assert name_tables(source, "cvstereo/matchers/sets.py") == [
        "cvstereo/matchers/sets.py:1: frame", "cvstereo/matchers/sets.py:1: event-time",
        "cvstereo/matchers/sets.py:2: event-area", "cvstereo/matchers/sets.py:2: sgbm",
        "cvstereo/matchers/sets.py:4: fused", "cvstereo/matchers/sets.py:6: stereobm",
    ]
    # Inside a matcher's own package its name is its own business (OpenCV's SGBM has a mode called "sgbm").
    assert name_tables('MODES = {"sgbm": 0}\n', "cvstereo/matchers/opencv/matcher.py") == []
    assert name_tables('MODES = {"sgbm": 0}\n', "cvstereo/matchers/frame/matcher.py") == [
        "cvstereo/matchers/frame/matcher.py:1: sgbm"]


def test_the_check_fails_on_the_tables_this_test_replaced():
    # The sets module before issue 25 item 8 held the adaptive set keyed by method name.
    old = 'ADAPTIVE: dict = {\n    "frame": AdaptiveDefaults(variant="separate"),\n    "sgbm": AdaptiveDefaults(),\n}\n'
    assert name_tables(old, "cvstereo/matchers/sets.py") == [
        "cvstereo/matchers/sets.py:1: frame", "cvstereo/matchers/sets.py:1: sgbm"]
