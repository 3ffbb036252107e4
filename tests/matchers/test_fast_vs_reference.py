"""Fast == reference for every method and variant of the thesis' five, over random packet cuts.

Each fast matcher (numba kernels, stacked frames) must give exactly the matches of its readable reference in
:mod:`calibration_free.reference`, bit for bit and in the same order, however the stream is cut into packets.
Beside the variant, the parameters that change the code path (anchor or reference camera, side restriction,
polarity mode, candidate test, Gaussian) are drawn too, and both threshold modes: ``absolute`` (the thesis'
constants) and ``relative`` (thresholds that follow the signal level, :mod:`cvstereo.matchers._shared.signal_level`,
with short
level windows and a small warm-up so that the thresholds change often within a short stream).
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from _event_scenes import feed_cut, random_pair, simulated_clip
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from cvstereo.matchers.event_area.reference import event_area_reference
from cvstereo.matchers.event_time.reference import event_time_reference
from cvstereo.matchers.event_vector.reference import event_vector_reference
from cvstereo.matchers.frame.reference import frame_clusters_reference
from cvstereo.matchers.frame_area.reference import frame_area_reference
from cvstereo.matchers.registry import METHODS, matcher_class
from cvstereo.model.events import make_events
from cvstereo.model.matches import validate_matches

#: method -> its reference, the parameters drawn beside the variant (a dict value sets several at once), and
#: overrides that make random streams reach the thresholds (per variant).
CASES = {
    "frame": (frame_clusters_reference, {"anchor_camera": [0, 1], "max_disparity": [64, 6], "min_support": [0, 3],
                                         "filter": [{"gaussian": True}, {"gaussian": False, "threshold": 2.0}]},
              {}),
    "frame-area": (frame_area_reference, {"reference_camera": [0, 1], "max_disparity": [64, 9],
                                          "polarity": ["shared", "separate", "on"], "lr_check": [False, True]},
                   {"no-gaussian": {"threshold": 3.0}}),
    "event-time": (event_time_reference, {"reference_camera": [0, 1], "restrict_side": [True, False],
                                          "max_disparity": [12], "reference_read": ["before", "after"],
                                          "consensus": [{"consensus_radius": 0},
                                                        {"consensus_radius": 2, "consensus_window_us": 5_000},
                                                        {"consensus_radius": 1, "consensus_min": 1}]}, {}),
    "event-area": (event_area_reference, {"polarity": ["shared", "separate", "on"], "max_disparity": [20],
                                          "cost_scale": [0.0, 0.6], "sad_frames": ["own", "all"],
                                          "own_ratio": [0.0, 0.6], "uniqueness": [0.0, 0.2]},
                   {"no-gaussian": {"threshold": 2.0}}),
    "event-vector": (event_vector_reference, {"require_candidate_threshold": [True, False],
                                              "polarity": ["shared", "separate"], "max_disparity": [20],
                                              "run_ends": [False, True],
                                              "bound": [{"cost_ratio": 0.0}, {"cost_ratio": 0.3, "cost_slack": 2.0}],
                                              "tie_break": ["smallest", "centre"]}, {}),
}

COMBOS = [(m, v) for m in CASES for v in matcher_class(m).variants]

#: Threshold modes: the overrides of each (relative: drawn scales beside short level windows).
MODES = {
    "absolute": {},
    "relative": {"threshold_mode": "relative", "level_window_us": 5_000, "level_warmup": 20, "level_windows": 3},
}
#: Relative mode: the scales drawn (event-time also scales its value tolerance, and its time window by the pace).
SCALES = {"threshold_scale": [0.5, 0.8]}
EVENT_TIME_SCALES = {"value_tolerance_scale": [0.3, 0.4], "time_window_scale": [0.4, 0.0, 2.0]}


def mode_params(method: str, mode: str, draw) -> dict:
    """The threshold-mode overrides of one case; ``draw(name, values)`` picks one of ``values``."""
    if mode == "absolute":
        return {}
    scales = {**SCALES, **(EVENT_TIME_SCALES if method == "event-time" else {})}
    return {**MODES[mode], **{name: draw(name, values) for name, values in scales.items()}}


def test_every_registered_thesis_variant_is_covered():
    # The thesis' matchers are the registered ones with a reference beside them (cvstereo.matchers.<name>.
    # reference); fused has one too and its own test (test_fused), built on the thesis' matchers.
    with_reference = [m for m in METHODS if m != "fused" and importlib.util.find_spec(
        matcher_class(m).__module__.rpartition(".")[0] + ".reference") is not None]
    assert with_reference == list(CASES) and len(COMBOS) == 13


def blob_pair(seed: int, *, windows: int = 3, window_us: int = 40_000, size: int = 48):
    """Rectangular blobs with several events per pixel, seen by the right camera a few px further left, with
    random noise on top: frames that pass the thresholds, rows that match and rows that do not."""
    rng = np.random.default_rng(seed)
    cams = [[], []]
    for k in range(windows):
        shift = int(rng.integers(0, 8))
        for _ in range(8):
            w, h = rng.integers(2, 7), rng.integers(2, 5)
            x0, y0 = rng.integers(shift + 2, size - w - 2), rng.integers(2, size - h - 2)
            yy, xx = np.mgrid[y0:y0 + h, x0:x0 + w]
            x, y = np.repeat(xx.ravel(), 3), np.repeat(yy.ravel(), 3)
            t = np.sort(rng.integers(k * window_us, (k + 1) * window_us, x.size))
            p = np.full(x.size, rng.integers(0, 2))
            keep = rng.random(x.size) < 0.9
            cams[0].append((t, x, y, p))
            cams[1].append((t[keep], x[keep] - shift, y[keep], p[keep]))
        for cam in cams:
            n = 150
            cam.append((rng.integers(k * window_us, (k + 1) * window_us, n), rng.integers(0, size, n),
                        rng.integers(0, size, n), rng.integers(0, 2, n)))
    out = []
    for cam in cams:
        t, x, y, p = (np.concatenate(c) for c in zip(*cam, strict=True))
        order = np.argsort(t, kind="stable")
        out.append(make_events(t[order], x[order], y[order], p[order]))
    return out[0], out[1], (size, size)


def scene(method: str, seed: int):
    if method.startswith("frame"):
        return blob_pair(seed)
    if method == "event-time":
        return random_pair(seed, n=1500, width=24, height=6)
    return random_pair(seed, n=1000, width=32, height=8)


@pytest.mark.parametrize("mode", list(MODES))
@pytest.mark.parametrize(("method", "variant"), COMBOS)
@settings(max_examples=8, deadline=None)
@given(data=st.data(), seed=st.integers(0, 2**32 - 1), n_cuts=st.integers(0, 30))
def test_fast_equals_reference_across_packet_cuts(method, variant, mode, data, seed, n_cuts):
    reference, axes, per_variant = CASES[method]
    cls = matcher_class(method)
    drawn = {}
    for name, values in axes.items():
        value = data.draw(st.sampled_from(values), label=name)
        drawn.update(value if isinstance(value, dict) else {name: value})
    drawn.update(mode_params(method, mode, lambda name, values: data.draw(st.sampled_from(values), label=name)))
    params = cls.make_params(variant, **{**drawn, **per_variant.get(variant, {})})
    left, right, resolution = scene(method, seed)
    expected = reference(left, right, params, resolution=resolution)
    cuts = np.random.default_rng(seed).choice(np.concatenate([left["t"], right["t"]]), n_cuts)
    got = feed_cut(cls(params, resolution=resolution), left, right, cuts)
    # A shared ON/OFF frame of independent random streams may stay below the event-time threshold; and a
    # drawn relative threshold (with the adaptive checks) can leave a blob scene without a match: such a draw
    # proves nothing, the next one is taken (the simulated-clip test below always has matches).
    assume(expected.size > 0 or (method == "event-time" and params.polarity == "shared"))
    np.testing.assert_array_equal(got, expected)
    validate_matches(got)


@pytest.mark.parametrize("mode", list(MODES))
@pytest.mark.parametrize(("method", "variant"), COMBOS)
def test_fast_equals_reference_on_a_simulated_clip(method, variant, mode):
    reference = CASES[method][0]
    cls = matcher_class(method)
    left, right, resolution = simulated_clip(100_000)
    params = cls.make_params(variant, **mode_params(method, mode, lambda name, values: values[0]))
    expected = reference(left, right, params, resolution=resolution)
    got = feed_cut(cls(params, resolution=resolution), left, right, range(0, 100_000, 3_333))
    # The single-pixel event-area variant needs four events at one pixel within a few ms (README: known limits).
    assert expected.size > 0 or (method, variant) == ("event-area", "no-gaussian")
    np.testing.assert_array_equal(got, expected)
    if mode == "relative" and expected.size:
        # The relative thresholds did change the result (else this case would test the absolute path twice).
        absolute = feed_cut(cls(cls.make_params(variant), resolution=resolution), left, right, [])
        assert not np.array_equal(absolute, expected)
