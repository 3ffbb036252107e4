"""The thesis rig, defined once (cvstereo.geometry.rig): the simulator, the point cloud and the samples read it."""

import numpy as np
import pytest

from cvstereo.geometry.pointcloud import Intrinsics
from cvstereo.geometry.rig import THESIS_RIG
from cvstereo.simulate.families import BASELINE_M, GRAIN_FOCAL_PX
from cvstereo.simulate.rig import Rig


@pytest.mark.parametrize(("distance_m", "low", "high"), [(0.5, 28.0, 30.0), (1.0, 13.0, 14.0), (1.5, 7.0, 8.0)])
def test_thesis_rig_gives_the_disparities_the_thesis_measured(distance_m, low, high):
    # docs/algorithms.md: about 28-30 px at 50 cm, 13-14 px at 100 cm, 7-8 px at 150 cm.
    assert low <= float(THESIS_RIG.depth_model().disparity(distance_m)) <= high


def test_the_simulator_point_cloud_and_suite_use_the_thesis_rig():
    rig = Rig()
    assert (rig.baseline_m, rig.focal_px, rig.axis_offset_px, rig.resolution) == (
        THESIS_RIG.baseline_m, THESIS_RIG.focal_px, THESIS_RIG.axis_offset_px, THESIS_RIG.resolution)
    assert (BASELINE_M, GRAIN_FOCAL_PX) == (THESIS_RIG.baseline_m, THESIS_RIG.focal_px)
    intr = Intrinsics.from_options(THESIS_RIG.resolution)
    assert (intr.focal_px, intr.cx, intr.cy) == (THESIS_RIG.focal_px, 63.5, 63.5)


def test_samples_depth_is_the_thesis_rig():
    import importlib.util
    from pathlib import Path

    for name in ("live_view", "disparity_video"):
        path = Path(__file__).resolve().parents[2] / "samples" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(f"_sample_{name}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        # 10 cm x 165 px, offset 3 px: the same model a recording simulated with the default rig describes.
        assert (module.RIG.a, module.RIG.c) == (pytest.approx(16.5), 3.0)
        assert np.isclose(module.RIG.distance(13.5), 1.0)
