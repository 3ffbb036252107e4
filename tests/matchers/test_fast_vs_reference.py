"""Fast == reference for every registered method and variant, over random packet cuts and a simulated clip.

Each fast matcher (numba kernels, stacked frames) must give exactly the matches of its readable reference
(``cvstereo/matchers/<name>/reference.py``, which shares no compiled code with it: test_reference_independence),
bit for bit and in the same order, however the stream is cut into packets. The cases are enumerated from the
registry: a registered method needs a reference here or a reasoned exemption (:data:`EXEMPT`), and each of its
variants is run.
Beside the variant, the parameters that change the code path (anchor or reference camera, side restriction,
polarity mode, candidate test, Gaussian) are drawn too, and both threshold modes: ``absolute`` (the thesis'
constants) and ``relative`` (thresholds that follow the signal level, :mod:`cvstereo.matchers._shared.signal_level`,
with short
level windows and a small warm-up so that the thresholds change often within a short stream).
"""

from __future__ import annotations

import cv2
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
from cvstereo.matchers.fused.reference import fused_reference
from cvstereo.matchers.registry import METHODS, matcher_class, matcher_params
from cvstereo.matchers.sets import ADAPTIVE, PARAM_SETS
from cvstereo.model.events import make_events
from cvstereo.model.matches import validate_matches

#: method -> its reference, the parameters drawn beside the variant (a dict value sets several at once), and
#: overrides that make random streams reach the thresholds (per variant).
CASES = {
    "frame": (frame_clusters_reference, {"anchor_camera": [0, 1], "max_disparity": [64, 6], "min_support": [0, 3],
                                         "filter": [{"gaussian": True}, {"gaussian": False, "threshold": 2.0}]},
              {}),
    "frame-area": (frame_area_reference, {"reference_camera": [0, 1], "max_disparity": [64, 9],
                                          "polarity": ["shared", "separate", "on"], "lr_check": [False, True],
                                          "value_units": ["own", "camera", "polarity"],
                                          "uniqueness": [0.0, 0.2]},
                   {"no-gaussian": {"threshold": 3.0}}),
    "event-time": (event_time_reference, {"reference_camera": [0, 1], "restrict_side": [True, False],
                                          "max_disparity": [12], "reference_read": ["before", "after"],
                                          "consensus": [{"consensus_radius": 0},
                                                        {"consensus_radius": 2, "consensus_window_us": 5_000},
                                                        {"consensus_radius": 1, "consensus_min": 1}]}, {}),
    "event-area": (event_area_reference, {"polarity": ["shared", "separate", "on"], "max_disparity": [20],
                                          "cost_scale": [0.0, 0.6], "sad_frames": ["own", "all"],
                                          "own_ratio": [0.0, 0.6], "uniqueness": [0.0, 0.2],
                                          "value_units": ["own", "camera", "polarity"]},
                   {"no-gaussian": {"threshold": 2.0}}),
    "event-vector": (event_vector_reference, {"require_candidate_threshold": [True, False],
                                              "polarity": ["shared", "separate"], "max_disparity": [20],
                                              "run_ends": [False, True],
                                              "bound": [{"cost_ratio": 0.0}, {"cost_ratio": 0.3, "cost_slack": 2.0}],
                                              "tie_break": ["smallest", "centre"]}, {}),
}

#: Methods with a reference but no axes here: fused (its random packet cuts, with its own parameter axes and
#: scenes, are test_fused's test_fast_equals_reference_across_packet_cuts; the simulated clip is run here).
OTHER_REFERENCES = {"fused": fused_reference}

#: Registered methods without a reference, and why: they wrap third-party matchers (OpenCV's StereoBM and
#: StereoSGBM, iniVation's dv-processing), whose algorithm is not ours to restate; their own tests
#: (test_baseline, test_compare_dv) check what this package adds around them.
EXEMPT = {
    "stereobm": "cv2.StereoBM on the windows' frames (test_baseline)",
    "sgbm": "cv2.StereoSGBM on the windows' frames (test_baseline)",
    "dv-semidense": "dv-processing's SemiDenseStereoMatcher (test_compare_dv)",
}

#: Every (method, variant) of the registry that has a case: the variants are read from each matcher class.
COMBOS = [(m, v) for m in METHODS if m in CASES for v in matcher_class(m).variants]
CLIP_COMBOS = [(m, v) for m in METHODS if m in CASES or m in OTHER_REFERENCES for v in matcher_class(m).variants]

#: Threshold modes: the overrides of each (relative: drawn scales beside short level windows).
MODES = {
    "absolute": {},
    "relative": {"threshold_mode": "relative", "level_window_us": 5_000, "level_warmup": 20, "level_windows": 3},
}
#: Relative mode: the scales drawn (event-time also scales its value tolerance, and its time window by the pace).
SCALES = {"threshold_scale": [0.5, 0.8]}
EVENT_TIME_SCALES = {"value_tolerance_scale": [0.3, 0.4], "time_window_scale": [0.4, 0.0, 2.0],
                     "value_units": ["own", "reference"]}


def mode_params(method: str, mode: str, draw) -> dict:
    """The threshold-mode overrides of one case; ``draw(name, values)`` picks one of ``values``."""
    if mode == "absolute":
        return {}
    scales = {**SCALES, **(EVENT_TIME_SCALES if method == "event-time" else {})}
    return {**MODES[mode], **{name: draw(name, values) for name, values in scales.items()}}


def reference_of(method: str):
    return CASES[method][0] if method in CASES else OTHER_REFERENCES[method]


def uncovered(registered: dict[str, list[str]]) -> list[str]:
    """What a registry (method -> its variants) has without a case here, and exemptions it no longer registers."""
    problems = [f"exempt {m!r} is not registered" for m in EXEMPT if m not in registered]
    for method, variants in registered.items():
        if method in EXEMPT:
            continue
        if method not in CASES and method not in OTHER_REFERENCES:
            problems.append(f"{method!r} has no reference case")
            continue
        problems += [f"{method!r} variant {v!r} has no case" for v in variants if (method, v) not in CLIP_COMBOS]
    return problems


def test_every_registered_method_and_variant_has_a_case():
    # Walks the registry itself: a matcher registered later, or a variant added to one, fails here until it gets
    # a reference (CASES or OTHER_REFERENCES) or an exemption with its reason.
    registry = {m: list(matcher_class(m).variants) for m in METHODS}
    assert uncovered(registry) == []
    assert not set(EXEMPT) & (set(CASES) | set(OTHER_REFERENCES))  # exempt or covered, not both
    # The thesis' five and fused, every variant of each (frame 4, frame-area 2, event-time 4, event-area 2,
    # event-vector 1, fused 1).
    assert len(CLIP_COMBOS) == 14 and len(COMBOS) == 13


def test_the_coverage_check_refuses_a_matcher_or_variant_without_a_case():
    registry = {m: list(matcher_class(m).variants) for m in METHODS}
    assert uncovered({**registry, "plugin": ["default"]}) == ["'plugin' has no reference case"]
    assert uncovered({**registry, "frame": [*registry["frame"], "diagonal"]}) == [
        "'frame' variant 'diagonal' has no case"]
    del registry["sgbm"]
    assert uncovered(registry) == ["exempt 'sgbm' is not registered"]


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


#: A method the ``adaptive`` set does not change (:data:`cvstereo.matchers.sets.ADAPTIVE`) is run once.
CLIP_CASES = [(m, v, s) for m, v in CLIP_COMBOS for s in PARAM_SETS if s == "thesis" or m in ADAPTIVE]


@pytest.mark.parametrize(("method", "variant", "param_set"), CLIP_CASES)
def test_fast_equals_reference_on_a_simulated_clip(method, variant, param_set):
    reference = reference_of(method)
    cls = matcher_class(method)
    # fused's whole-window numpy reference is the slowest: half the clip (its windows still carry its prior).
    t_stop = 50_000 if method == "fused" else 100_000
    left, right, resolution = simulated_clip(t_stop)
    params = matcher_params(method, variant, resolution=resolution, param_set=param_set)
    expected = reference(left, right, params, resolution=resolution)
    got = feed_cut(cls(params, resolution=resolution), left, right, range(0, t_stop, 3_333))
    # The single-pixel event-area variant needs four events at one pixel within a few ms (README: known limits).
    assert expected.size > 0 or (method, variant) == ("event-area", "no-gaussian")
    np.testing.assert_array_equal(got, expected)
    if param_set == "adaptive" and expected.size:
        # The set did change the result (else this case would test the thesis set twice).
        thesis = matcher_params(method, variant, resolution=resolution, param_set="thesis")
        assert not np.array_equal(feed_cut(cls(thesis, resolution=resolution), left, right, []), expected)


def cancelling_pair():
    """Right camera (the reference): one ON and one OFF event at (10, 5), 21 ON at (12, 6) and 21 OFF at (11, 7):
    offsets (dy, dx) = (1, 2) and (2, 1) of equal weight g(1) g(2), so the filtered value at (10, 5) is exactly 0
    by eq. 3.6. The left camera sees it all 3 px further right. Returns left, right, resolution."""
    def camera(shift):
        parts = [(1000 + np.arange(21), 12, 6, 1), (1000 + np.arange(21), 11, 7, 0), ([2000], 10, 5, 1),
                 ([2001], 10, 5, 0)]
        t, x, y, p = (np.concatenate(c) for c in zip(*[(np.asarray(t), np.full(len(t), x + shift),
                                                          np.full(len(t), y), np.full(len(t), p))
                                                         for t, x, y, p in parts], strict=True))
        order = np.argsort(t, kind="stable")
        return make_events(t[order], x[order], y[order], p[order])

    return camera(3), camera(0), (24, 12)


def test_frame_area_reference_gives_p_0_where_the_filtered_value_cancels():
    left, right, resolution = cancelling_pair()
    expected = frame_area_reference(left, right, matcher_class("frame-area").make_params("gaussian"),
                                    resolution=resolution)
    # By hand: the strong ON pixel (21 (g(0)^2 - g(1)^2) = 2.15 >= 2) is scanned first and finds 3 px; its
    # 5x5 takes in (10, 5) and (11, 7); p = 1 only where the frame is > 0: (12, 6), not (10, 5) (exactly 0).
    assert expected[["x", "y", "p"]].tolist() == [(10, 5, 0), (12, 6, 1), (11, 7, 0)]
    assert (expected["disparity"] == 3.0).all()


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="fast path: p follows cv2's float32 rounding (+9e-9) where the filtered value is 0 by "
                          "eq. 3.6 (found by the independent Gaussian; the fast path is not this change's to alter)")
def test_frame_area_polarity_where_the_filtered_value_cancels():
    left, right, resolution = cancelling_pair()
    # The fast frames reproduce cv2.GaussianBlur bit for bit, whose float32 rounding is OpenCV's and the CPU's.
    frame = np.zeros((resolution[1], resolution[0]), np.float32)
    frame[6, 12], frame[7, 11] = 21, -21
    if not cv2.GaussianBlur(frame, (5, 5), 1.0, borderType=cv2.BORDER_CONSTANT)[5, 10] > 0:
        pytest.skip("this OpenCV rounds the cancelling sum to <= 0: the fast matcher's p is 0 as well")
    params = matcher_class("frame-area").make_params("gaussian")
    got = feed_cut(matcher_class("frame-area")(params, resolution=resolution), left, right, [])
    np.testing.assert_array_equal(got, frame_area_reference(left, right, params, resolution=resolution))
