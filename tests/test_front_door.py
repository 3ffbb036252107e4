"""The front door (``import cvstereo as cvs``), the old import paths of 0.2, and the registry of a plain checkout."""

from __future__ import annotations

import ast
import importlib
import os
import pickle
import subprocess
import sys
import sysconfig
import tomllib
import types
from pathlib import Path

import numpy as np
import pytest

import cvstereo
from cvstereo._compat import MOVED

ROOT = Path(__file__).resolve().parents[1]

#: The import paths README.md documents (module, names): each must keep working through 0.x.
README_PATHS = [
    ("calibration_free", ["match", "create_matcher", "METHODS", "available_methods", "matcher_class"]),
    ("cvstereo.io", ["read_recording", "open_recording", "write_matches", "read_matches"]),
    ("cvstereo.evaluate", ["evaluate"]),
    ("cvstereo.matches", ["concat_matches"]),
    ("cvstereo.depth", ["DepthModel", "fit_depth_model"]),
    ("cvstereo.sweep", ["Grid", "run_sweep", "summary_markdown"]),
    ("cvstereo.calibration", ["load_calibration"]),
    ("cvstereo.rectify", ["Rectification"]),
    ("cvstereo.pointcloud", ["depth_per_match", "point_cloud", "write_ply"]),
    ("cvstereo.disparity_maps", ["window_disparity_images"]),
    ("cvstereo.depth_file", ["load_depth_model"]),
    ("cvstereo.registry", ["METHODS", "create_matcher", "matcher_class", "available_methods"]),
    ("cvstereo.pipeline", ["match"]),
    ("calibration_free.reference", ["frame_clusters_reference", "event_time_reference"]),
]


def _run(code: str, **kwargs) -> str:
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, **kwargs)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_every_front_door_name_resolves_to_the_object_of_its_module():
    for name, module in cvstereo._EXPORTS.items():
        value, defined = getattr(cvstereo, name), getattr(importlib.import_module(module), name)
        if name == "evaluate" and isinstance(value, types.ModuleType):
            # Once anything imported the 0.2 path `cvstereo.evaluate`, the import system binds that module to the
            # package's attribute; the module is callable and holds the same function, so both spellings work.
            assert value.evaluate is defined and callable(value), name
            continue
        assert value is defined, name
    assert set(cvstereo._EXPORTS) | {"__version__"} == set(cvstereo.__all__)
    assert cvstereo.__version__ == tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def test_star_import_gives_every_name_of_all():
    namespace: dict = {}
    exec("from cvstereo import *", namespace)
    assert set(cvstereo.__all__) <= set(namespace)
    assert namespace["make_events"] is cvstereo.make_events


def test_the_stub_lists_exactly_the_front_door():
    tree = ast.parse((ROOT / "cvstereo" / "__init__.pyi").read_text())
    imported = {alias.asname: f"{node.module}" for node in tree.body if isinstance(node, ast.ImportFrom)
                for alias in node.names}
    assert imported == cvstereo._EXPORTS
    stub_all = next(node.value for node in tree.body if isinstance(node, ast.Assign)
                    and node.targets[0].id == "__all__")
    assert ast.literal_eval(stub_all) == cvstereo.__all__


def test_import_cvstereo_loads_no_numpy():
    # The command line handles signals from its first line on; the heavy imports come after (cvstereo.cli).
    assert _run("import sys, cvstereo; print('numpy' in sys.modules)").strip() == "False"


def test_evaluate_is_callable_before_and_after_the_old_module_is_imported():
    code = """
import numpy as np
import cvstereo as cvs
from cvstereo.model.matches import make_matches
left = cvs.make_events([0, 10], [5, 6], [3, 3], [1, 1])
rec = cvs.Recording(left, left.copy(), np.array([3.0, 3.0]), np.array([3.0, 3.0]), resolution=(16, 16))
result = cvs.MatchResult(make_matches([0, 10], [5, 6], [3, 3], [1, 1], 0, [3, 5]), {"anchor": "event"})
first = cvs.evaluate(rec, result)
import cvstereo.evaluate
from cvstereo.evaluate import evaluate
second = cvs.evaluate(rec, result)
assert evaluate is cvstereo.evaluation.metrics.evaluate
print(first["mae"], second["mae"], first["bad1"], second["bad1"], type(cvs.evaluate).__name__)
"""
    out = _run(code).split()
    # Two matches against a true disparity of 3 px: one exact, one 2 px off -> mean error 1, half over 1 px.
    assert out == ["1.0", "1.0", "0.5", "0.5", "_CallableModule"]


@pytest.mark.parametrize(("module", "names"), README_PATHS, ids=[m for m, _ in README_PATHS])
def test_every_import_path_the_readme_documents_still_works(module, names):
    mod = importlib.import_module(module)
    for name in names:
        assert callable(getattr(mod, name)) or name == "METHODS", f"{module}.{name}"
    if module in MOVED:
        # The old name is the moved module itself, not a copy: classes are the same objects.
        assert mod is importlib.import_module(MOVED[module])


def test_every_old_module_name_imports_as_its_new_module():
    for old, new in MOVED.items():
        if new == "cvstereo.matchers.dv.matcher":
            continue  # imports without dv-processing too, but only this entry would need the extra to run
        assert importlib.import_module(old) is importlib.import_module(new), old


def test_objects_pickled_under_an_old_module_name_load_as_the_new_class():
    from cvstereo.geometry.depth import DepthModel

    model = DepthModel(a=100.0, c=1.5)
    legacy = pickle.dumps(model, protocol=0)
    assert b"cvstereo.geometry.depth\n" in legacy
    loaded = pickle.loads(legacy.replace(b"cvstereo.geometry.depth\n", b"cvstereo.depth\n"))
    assert type(loaded) is DepthModel and loaded == model


def test_the_builtin_table_and_the_entry_points_of_pyproject_agree():
    from cvstereo.matchers._registry import BUILTIN_METHODS

    toml = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert toml["project"]["entry-points"]["cvstereo.matchers"] == BUILTIN_METHODS


def test_a_plugin_of_another_distribution_is_added_but_cannot_replace_a_builtin(monkeypatch):
    import importlib.metadata

    from cvstereo.matchers import registry

    plugin = importlib.metadata.EntryPoint("my-opencv", "cvstereo.matchers.opencv.matcher:StereoBMMatcher",
                                           registry.ENTRY_POINT_GROUP)
    thief = importlib.metadata.EntryPoint("frame", "cvstereo.matchers.opencv.matcher:StereoBMMatcher",
                                          registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry.importlib.metadata, "entry_points", lambda **kw: [thief, plugin])
    registry._methods.cache_clear()
    try:
        assert list(registry.METHODS)[-1] == "my-opencv"
        assert registry.matcher_class("my-opencv").__name__ == "StereoBMMatcher"
        assert registry.matcher_class("frame").__name__ == "FrameClusterMatcher"
    finally:
        monkeypatch.undo()
        registry._methods.cache_clear()


def test_a_plain_checkout_with_only_the_dependencies_lists_every_method(tmp_path):
    """``python -c "import cvstereo as cvs; print(cvs.available_methods())"`` with the checkout first on
    sys.path and the installed distribution hidden: site-packages without cvstereo's metadata and without its
    editable-install hook, no site initialisation (-S), no user site or environment variables (-I)."""
    site = Path(sysconfig.get_paths()["purelib"])
    checkout, deps = tmp_path / "checkout", tmp_path / "site"
    checkout.mkdir()
    deps.mkdir()
    for package in ("cvstereo", "calibration_free"):  # a clone holds the packages, not an install's egg-info
        os.symlink(ROOT / package, checkout / package)
    for entry in site.iterdir():
        low = entry.name.lower()
        if low.startswith(("cvstereo", "__editable__")) or low.endswith(".pth"):
            continue
        os.symlink(entry, deps / entry.name)
    code = (f"import sys; sys.path[:0] = [{str(checkout)!r}, {str(deps)!r}]; "
            "import importlib.metadata as md; assert not md.entry_points(group='cvstereo.matchers'); "
            "import cvstereo as cvs; print(cvs.__file__); print(','.join(cvs.available_methods()))")
    done = subprocess.run([sys.executable, "-I", "-S", "-c", code], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    where, methods = done.stdout.split()
    assert Path(where) == checkout / "cvstereo" / "__init__.py"
    expected = ["frame", "frame-area", "event-time", "event-area", "event-vector", "stereobm", "sgbm"]
    expected += ["dv-semidense"] if importlib.util.find_spec("dv_processing") else []
    assert methods.split(",") == [*expected, "fused"]


def test_isinstance_holds_across_old_and_new_names():
    import cvstereo.matches as old

    from cvstereo.model.matches import MatchResult

    result = old.MatchResult(np.zeros(0, old.MATCH_DTYPE), {})
    assert isinstance(result, MatchResult)


def _public_modules() -> list[str]:
    """Every module of cvstereo whose dotted name has no part starting with ``_`` (packages included)."""
    out = []
    for path in sorted((ROOT / "cvstereo").rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        if not any(part.startswith("_") for part in parts) and parts[-1] != "__main__":
            out.append(".".join(parts))
    return out


def test_every_public_module_declares_all_and_defines_every_name_of_it():
    missing, undefined = [], {}
    for name in _public_modules():
        tree = ast.parse((ROOT / (name.replace(".", "/"))).with_suffix(".py").read_text()
                         if (ROOT / name.replace(".", "/")).with_suffix(".py").exists()
                         else (ROOT / name.replace(".", "/") / "__init__.py").read_text())
        if not any(isinstance(n, ast.Assign | ast.AnnAssign) and "__all__" in ast.unparse(n).split("=")[0]
                   for n in tree.body):
            missing.append(name)
            continue
        if name == "cvstereo.matchers.dv.matcher" and not importlib.util.find_spec("dv_processing"):
            continue
        module = importlib.import_module(name)
        absent = [n for n in module.__all__ if not hasattr(module, n)]
        if absent:
            undefined[name] = absent
    assert len(_public_modules()) > 100
    assert missing == [] and undefined == {}


def test_the_changelog_lists_every_move():
    text = (ROOT / "CHANGELOG.md").read_text()
    assert f"## {cvstereo.__version__}" in text
    missing = [f"{old} -> {new}" for old, new in MOVED.items() if f"| `{old}` | `{new}` |" not in text]
    assert missing == []
