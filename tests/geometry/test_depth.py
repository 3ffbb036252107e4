"""Distance from disparity: the two-point fit of d = a/Z - c."""

import numpy as np
import pytest

from cvstereo.geometry.depth import DepthModel, fit_depth_model


def test_fit_recovers_a_rig_exactly_from_two_distances():
    rig = DepthModel.from_rig(focal_px=160.0, baseline_m=0.10, offset_px=2.5)
    z = np.array([0.5, 1.5])
    model = fit_depth_model(z, rig.disparity(z))
    assert model.a == pytest.approx(16.0) and model.c == pytest.approx(2.5)
    # Hand check: at 1 m, d = 16 / 1 - 2.5 = 13.5 px, and back.
    assert float(model.disparity(1.0)) == pytest.approx(13.5)
    np.testing.assert_allclose(model.distance([13.5, 5.5]), [1.0, 2.0])


def test_least_squares_with_noise_and_weights():
    rng = np.random.default_rng(0)
    z = np.array([0.5, 0.75, 1.0, 1.25, 1.5])
    d = 16.0 / z - 2.5 + rng.normal(0, 0.05, z.size)
    model = fit_depth_model(z, d, weights=[1, 1, 1, 1, 1])
    assert model.a == pytest.approx(16.0, abs=0.2) and model.c == pytest.approx(2.5, abs=0.3)


def test_distance_beyond_infinity_is_inf():
    assert np.isinf(DepthModel(a=16.0, c=2.5).distance(-3.0))


@pytest.mark.parametrize(("z", "d", "msg"), [
    ([1.0, 1.0], [5.0, 5.0], "two or more different distances"),
    ([1.0], [5.0, 6.0], "one disparity per distance"),
    ([-1.0, 1.0], [5.0, 6.0], "must be positive"),
    ([1.0, np.nan], [5.0, 6.0], "finite"),
])
def test_bad_fits_are_refused(z, d, msg):
    with pytest.raises(ValueError, match=msg):
        fit_depth_model(z, d)
