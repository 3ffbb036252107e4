"""dv-processing's SemiDenseStereoMatcher through our matcher protocol (extra `compare`)."""

from __future__ import annotations

import numpy as np
import pytest

from calibration_free import create_matcher
from cvstereo.matchers.registry import available_methods
from cvstereo.model.events import make_events

pytest.importorskip("dv_processing", reason="dv-processing (extra 'compare') is not installed")

W = 40_000


def _shifted_texture(rng, k, *, n=20_000, windows=2):
    # The same random texture in both cameras, k px further left in the right camera.
    x, y, p = rng.integers(0, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n)
    t = np.sort(rng.integers(0, windows * W, n))
    keep = x >= k
    return make_events(t, x, y, p), make_events(t[keep], x[keep] - k, y[keep], p[keep])


def test_listed_when_installed():
    assert "dv-semidense" in available_methods()


@pytest.mark.parametrize("k", [5, 14])
def test_recovers_the_shift_of_a_texture(rng, k):
    left, right = _shifted_texture(rng, k)
    m = create_matcher("dv-semidense")
    out = np.concatenate([m.feed(left, right), m.flush()])
    assert out.size > 1000
    assert set(np.unique(out["t"])) <= {W, 2 * W}
    assert (out["camera"] == 0).all()
    # dv-processing's SGBM leaves its left strip (48 disparities) empty; inside it the shift is found.
    inner = out[out["x"] >= 48 + 6]
    assert np.mean(np.abs(inner["disparity"] - k) <= 1.0) > 0.9


def test_anchors_are_left_pixels_with_events(rng):
    left, right = _shifted_texture(rng, 8, n=8000, windows=1)
    m = create_matcher("dv-semidense")
    out = np.concatenate([m.feed(left, right), m.flush()])
    seen = set(zip(left["x"].tolist(), left["y"].tolist(), strict=True))
    assert out.size and all((x, y) in seen for x, y in zip(out["x"].tolist(), out["y"].tolist(), strict=True))
