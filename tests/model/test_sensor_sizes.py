"""Any sensor size: the disparity range follows the width (one rule), and every matcher answers at 346x260."""

from __future__ import annotations

import pytest

from cvstereo.matchers.registry import available_methods, create_matcher

THESIS = ("frame", "frame-area", "event-time", "event-area", "event-vector")


@pytest.mark.parametrize("method", THESIS)
@pytest.mark.parametrize(("resolution", "expected"), [((128, 128), 64), ((240, 180), 120), ((346, 260), 173),
                                                      ((640, 480), 320)])
def test_disparity_range_is_round_64_width_over_128(method, resolution, expected):
    assert create_matcher(method, resolution=resolution).params.max_disparity == expected
    assert create_matcher(method, resolution=resolution, param_set="thesis").params.max_disparity == expected
    # Given explicitly, it is kept.
    assert create_matcher(method, resolution=resolution, max_disparity=30).params.max_disparity == 30


@pytest.mark.parametrize("method", ["stereobm", "sgbm"])
@pytest.mark.parametrize(("resolution", "expected"), [((128, 128), 63), ((240, 180), 127), ((346, 260), 175),
                                                      ((640, 480), 319)])
def test_opencv_range_scales_in_whole_sixteens(method, resolution, expected):
    """OpenCV searches a multiple of 16 disparities: the scaled count (64 * width / 128) is rounded up to one."""
    prm = create_matcher(method, resolution=resolution).params
    assert prm.max_disparity == expected and (prm.max_disparity - prm.min_disparity + 1) % 16 == 0
    # The old name (a count) still sets it.
    assert create_matcher(method, resolution=resolution, num_disparities=32).params.max_disparity == 31


@pytest.fixture(scope="module")
def davis346():
    """One arm at 1 m seen by the thesis' optics on a 346x260 sensor (disparities x 346/128, about 37 px)."""
    from cvstereo.simulate import ArmsScene, Rig, simulate

    return simulate(ArmsScene(arms=1, distance_m=1.0), rig=Rig().for_sensor((346, 260)), seconds=0.4, seed=5)


@pytest.mark.slow
@pytest.mark.parametrize("method", [*THESIS, "stereobm", "sgbm", "dv-semidense", "fused"])
def test_every_matcher_answers_at_346x260(davis346, method):
    if method not in available_methods():
        pytest.skip(f"{method} is not installed here")
    from cvstereo.evaluation.metrics import evaluate
    from cvstereo.run import match

    figures = evaluate(davis346, match(davis346, method=method))
    assert figures["coverage"] > 0.1, figures
    assert figures["median_ae"] <= 1.0, figures
