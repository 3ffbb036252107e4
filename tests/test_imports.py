"""The import graph of both packages, read from the source (imports inside functions included): no cycle, and
no module of cvstereo imports calibration_free (the matchers are found through entry points)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cvstereo", "calibration_free")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """The modules of ``known`` that ``name`` imports anywhere in its source (``from a import b`` counts
    ``a.b`` where that is a module, else ``a``)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base for alias in node.names]
        else:
            continue
        for target in targets:
            # ``import a.b.c`` names a.b.c; keep the longest known prefix.
            parts = target.split(".")
            for k in range(len(parts), 0, -1):
                if ".".join(parts[:k]) in known:
                    out.add(".".join(parts[:k]))
                    break
    out.discard(name)
    return out


def import_graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imports_of(name, path, known) for name, path in mods.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt):], nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_the_walk_sees_imports_inside_functions_and_relative_ones(tmp_path):
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}}
    assert find_cycle(graph) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from cvstereo.io import npz\n    import calibration_free.reference\n")
    assert imports_of("cvstereo.x", src, {"cvstereo.io", "cvstereo.io.npz", "calibration_free.reference"}) == \
        {"cvstereo.io.npz", "calibration_free.reference"}


def test_no_import_cycle():
    graph = import_graph()
    assert len(graph) > 50 and graph["cvstereo.run"] >= {"cvstereo.matchers.registry"}
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph))


def test_cvstereo_never_imports_calibration_free():
    upward = {name: sorted(m for m in deps if m.split(".")[0] == "calibration_free")
              for name, deps in import_graph().items() if name.split(".")[0] == "cvstereo"}
    assert {name: deps for name, deps in upward.items() if deps} == {}


def test_references_import_no_kernel():
    # References are the independent twin of the fast kernels: they may share parameters, not code paths.
    graph = import_graph()
    fast = {f"cvstereo.matchers.{m}.matcher" for m in ("frame", "frame_area", "event_time", "event_area",
                                                       "event_vector", "fused")}
    fast |= {"cvstereo.matchers._shared.event_common", "cvstereo.matchers.fused._kernels"}
    assert fast <= set(graph)
    for name, deps in graph.items():
        if name.endswith(".reference") or name.startswith("cvstereo.matchers._shared.reference"):
            assert not deps & fast, f"{name} imports {sorted(deps & fast)}"


def test_no_module_imports_a_private_module_of_another_package():
    # A module or package whose name starts with "_" is its parent package's business; what other packages
    # need is public. (cvstereo._compat and _numba_cache are the package's own start-up, run by its __init__.)
    crossing = {}
    for name, deps in import_graph().items():
        for dep in deps:
            parts = dep.split(".")
            private = [k for k, part in enumerate(parts) if part.startswith("_") and not part.startswith("__")]
            if not private or dep in ("cvstereo._compat", "cvstereo._numba_cache"):
                continue
            owner = ".".join(parts[:private[0]])
            if not (name + ".").startswith(owner + "."):
                crossing.setdefault(name, []).append(dep)
    assert crossing == {}


def test_every_module_has_at_most_450_lines():
    long = {name: n for name, path in modules().items() if (n := len(path.read_text().splitlines())) > 450}
    assert long == {}
