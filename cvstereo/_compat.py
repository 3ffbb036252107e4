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
MOVED: dict[str, str] = {
    "cvstereo.events": "cvstereo.model.events",
    "cvstereo.recording": "cvstereo.model.recording",
    "cvstereo.matches": "cvstereo.model.matches",
    "cvstereo.polarity": "cvstereo.model.polarity",
    "cvstereo.arrays": "cvstereo.model.arrays",
    "cvstereo.columns": "cvstereo.model.columns",
    "cvstereo.sensor_size": "cvstereo.model.sensor_size",
    "cvstereo.fingerprint": "cvstereo.model.fingerprint",
    "cvstereo.windows": "cvstereo.frames.windows",
    "cvstereo.dynamic_frames": "cvstereo.frames.dynamic",
    "cvstereo.signal_level": "cvstereo.matchers._shared.signal_level",
    "cvstereo.sorted_runs": "cvstereo.matchers._shared.sorted_runs",
    "cvstereo.sparse_frames": "cvstereo.matchers._shared.sparse_frames",
    "cvstereo.support": "cvstereo.matchers._shared.support",
    "calibration_free.merge_order": "cvstereo.matchers._shared.merge_order",
    "calibration_free._event_common": "cvstereo.matchers._shared.event_common",
    "calibration_free.params": "cvstereo.matchers.thesis_params",
    "cvstereo.matchers._shared.thesis_params": "cvstereo.matchers.thesis_params",
    "cvstereo.matcher": "cvstereo.matchers.protocol",
    "cvstereo.registry": "cvstereo.matchers.registry",
    "cvstereo.params": "cvstereo.matchers.params",
    "cvstereo.param_sets": "cvstereo.matchers.sets",
    "calibration_free.frame_clusters": "cvstereo.matchers.frame.matcher",
    "calibration_free.frame_area": "cvstereo.matchers.frame_area.matcher",
    "calibration_free.event_time": "cvstereo.matchers.event_time.matcher",
    "calibration_free.event_area": "cvstereo.matchers.event_area.matcher",
    "calibration_free.event_vector": "cvstereo.matchers.event_vector.matcher",
    "calibration_free.fused": "cvstereo.matchers.fused.matcher",
    "calibration_free._fused_features": "cvstereo.matchers.fused._features",
    "calibration_free._fused_kernel": "cvstereo.matchers.fused._kernels",
    "calibration_free.fused_params": "cvstereo.matchers.fused.params",
    "calibration_free.fused_signal": "cvstereo.matchers.fused.signal",
    "cvstereo.baseline": "cvstereo.matchers.opencv.matcher",
    "cvstereo.compare_dv": "cvstereo.matchers.dv.matcher",
    "calibration_free.reference.frame_clusters": "cvstereo.matchers.frame.reference",
    "calibration_free.reference.frame_area": "cvstereo.matchers.frame_area.reference",
    "calibration_free.reference.event_time": "cvstereo.matchers.event_time.reference",
    "calibration_free.reference.event_area": "cvstereo.matchers.event_area.reference",
    "calibration_free.reference.event_vector": "cvstereo.matchers.event_vector.reference",
    "calibration_free.reference.fused": "cvstereo.matchers.fused.reference",
    "calibration_free.reference.dynamic_frames": "cvstereo.matchers._shared.reference_frames",
    "calibration_free.reference.windows": "cvstereo.matchers._shared.reference_windows",
    "cvstereo.pipeline": "cvstereo.run",
    "cvstereo.calibration": "cvstereo.geometry.calibration",
    "cvstereo.rectify": "cvstereo.geometry.rectify",
    "cvstereo.rigcorrect": "cvstereo.geometry.rigcorrect",
    "cvstereo.depth": "cvstereo.geometry.depth",
    "cvstereo.depth_file": "cvstereo.geometry.depth_file",
    "cvstereo.pointcloud": "cvstereo.geometry.pointcloud",
    "cvstereo.disparity_maps": "cvstereo.geometry.disparity_maps",
    "cvstereo.overlay": "cvstereo.geometry.overlay",
    "cvstereo.geometry_source": "cvstereo.geometry.source",
    "cvstereo.evaluate": "cvstereo.evaluation.metrics",
    "cvstereo.thesis": "cvstereo.evaluation.thesis",
    "cvstereo.experiment": "cvstereo.evaluation.experiment",
    "cvstereo.timing": "cvstereo.benchmark.timing",
    # Private modules that other packages imported: public now (no module imports another package's private one).
    "cvstereo.io._atomic": "cvstereo.io.atomic",
    "cvstereo.io._source": "cvstereo.io.files",
    "cvstereo.io._paths": "cvstereo.io.paths",
    "cvstereo.viz._mpl": "cvstereo.viz.mpl",
}


class _AliasLoader(importlib.abc.Loader):
    """Loads an old name as the module it moved to: the same module object, not a copy."""

    def __init__(self, target: str):
        self.target = target

    def create_module(self, spec):
        # The import system keeps the module's own __name__, __loader__ and __file__ (it sets them only where
        # missing) but always sets __spec__ to the old name's; exec_module puts the module's own spec back,
        # so the module stays what it is and is merely also known under the old name.
        module = importlib.import_module(self.target)
        self._own_spec = module.__spec__
        return module

    def exec_module(self, module) -> None:
        """Nothing to run (the module ran when it was imported under its own name): restore its spec."""
        module.__spec__ = self._own_spec


class _AliasFinder(importlib.abc.MetaPathFinder):
    """Finds the old module names of :data:`MOVED`; every other name is left to the finders before it."""

    def find_spec(self, fullname, path=None, target=None):
        new = MOVED.get(fullname)
        return None if new is None else importlib.util.spec_from_loader(fullname, _AliasLoader(new))


def install() -> None:
    """Put the finder of old names at the end of :data:`sys.meta_path` (once)."""
    if not any(isinstance(finder, _AliasFinder) for finder in sys.meta_path):
        sys.meta_path.append(_AliasFinder())
