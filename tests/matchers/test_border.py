"""The border rule (cvstereo.matchers._shared.border): no answer where the matcher's own evidence puts the partner
outside the other image; on a plane filling the view, every registered matcher's default keeps at most 1 % of its
answers in the strip where the true partner lies outside the other camera's image (issue 24)."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.matchers._shared.border import BorderParams, BorderRule, _inward_order, border_rule_for
from cvstereo.matchers.registry import available_methods, matcher_class
from cvstereo.matchers.sets import resolve
from cvstereo.model.matches import make_matches
from cvstereo.run import match
from cvstereo.simulate import FamilyScene, Rig
from cvstereo.simulate.core import simulate

WIDTH, HEIGHT = 128, 128
#: The plane's disparity: an eighth of the width, as the border figure's planes (bench_generalization.py).
PLANE_D = 16
#: Largest share of a matcher's answers in the strip that the rule allows (issue 24's "done when").
MAX_STRIP_SHARE = 0.01
#: Smallest share of the correct answers (within 1 px of the plane) the rule keeps compared with no rule.
MIN_CORRECT_KEPT = 0.97


def _matches(rows):
    """Matches from (t, x, y, camera, disparity) tuples."""
    t, x, y, cam, d = (list(c) for c in zip(*rows, strict=True))
    return make_matches(t=t, x=x, y=y, p=[1] * len(t), camera=cam, disparity=d)


def test_left_strip_refused_where_the_surface_inward_is_nearer():
    # Evidence at x = 20 in rows 0..2 says 8 px; at x = 5 a 4 px answer cannot be right (8 > 5): refused.
    # At x = 10 the room (10) exceeds the 8 px of the evidence: kept.
    rule = BorderRule((32, 3), horizon_us=1000, rows=1)
    m = _matches([(0, 20, 0, 0, 8.0), (0, 20, 1, 0, 8.0), (0, 20, 2, 0, 8.0),
                  (5, 5, 1, 0, 4.0), (5, 10, 1, 0, 8.0)])
    assert rule(m)["x"].tolist() == [20, 20, 20, 10]


def test_right_camera_mirrors_the_rule():
    # Right camera, width 32: room at x = 28 is 31 - 28 = 3 < 8 -> refused; at x = 20 room 11 >= 8 -> kept.
    rule = BorderRule((32, 3), horizon_us=1000, rows=1)
    m = _matches([(0, 12, y, 1, 8.0) for y in range(3)] + [(5, 28, 1, 1, 2.0), (5, 20, 1, 1, 8.0)])
    assert rule(m)["x"].tolist() == [12, 12, 12, 20]


def test_a_lone_outlier_does_not_refuse():
    # One row says 30 px beside x = 10, two rows say 4 px: the majority keeps the answer.
    rule = BorderRule((64, 3), horizon_us=1000, rows=1)
    m = _matches([(0, 12, 1, 0, 4.0), (0, 12, 2, 0, 4.0), (1, 40, 0, 0, 30.0), (5, 10, 1, 0, 4.0)])
    assert rule(m).size == 4
    # With the outlier alone beside it, the same answer is refused.
    alone = BorderRule((64, 3), horizon_us=1000, rows=1)
    assert alone(_matches([(1, 40, 0, 0, 30.0), (5, 10, 1, 0, 4.0)])).size == 1


def test_evidence_expires_after_the_horizon():
    rule = BorderRule((32, 1), horizon_us=100, rows=0)
    m = _matches([(0, 20, 0, 0, 8.0), (50, 5, 0, 0, 3.0), (200, 4, 0, 0, 3.0)])
    # t = 50: the 8 px at t = 0 is recent -> refused; t = 200: it expired and nothing replaced it -> kept.
    assert rule(m)["t"].tolist() == [0, 200]


def test_a_window_is_decided_inward_first():
    # All at one time (a window), the strip's answer listed first: the window's own answers inward decide it.
    rule = BorderRule((32, 1), horizon_us=1000, rows=0)
    m = _matches([(40, 3, 0, 0, 2.0), (40, 20, 0, 0, 8.0)])
    assert rule(m)["x"].tolist() == [20]


@pytest.mark.parametrize("span", [1, 3, 40, 20_000])  # runs of equal times of every length: merge sort, insertion
def test_the_decision_order_is_time_then_inward_first(span):
    # The order the rule decides in equals numpy's lexsort by time, then room largest first, ties as given
    # (the independent expectation); out of time order it says so, and the rule falls back to that lexsort.
    rng = np.random.default_rng(span)
    n, width = 500, 64
    t = np.sort(rng.integers(0, span, n)).astype(np.int64)
    x = rng.integers(0, width, n).astype(np.int16)
    cam = rng.integers(0, 2, n).astype(np.uint8)
    room = np.where(cam == 0, x.astype(np.int64), width - 1 - x.astype(np.int64))
    order = np.empty(n, np.int64)
    assert _inward_order(t, x, cam, width, order)
    assert np.array_equal(order, np.lexsort((-room, t)))
    if span > 1:
        assert not _inward_order(t[::-1].copy(), x, cam, width, order)


def test_a_long_run_with_columns_off_the_sensor_is_still_ordered_like_lexsort():
    # A caller's own matches may lie off the sensor: the counting sort of long runs has no bin for them, and the
    # run is then merge-sorted (the same order, by the independent lexsort).
    rng = np.random.default_rng(7)
    n, width = 300, 64
    t = np.zeros(n, np.int64)
    x = rng.integers(-5, width + 5, n).astype(np.int16)
    cam = rng.integers(0, 2, n).astype(np.uint8)
    room = np.where(cam == 0, x.astype(np.int64), width - 1 - x.astype(np.int64))
    order = np.empty(n, np.int64)
    assert _inward_order(t, x, cam, width, order)
    assert np.array_equal(order, np.lexsort((-room, t)))


def test_matches_out_of_time_order_get_the_same_decisions():
    rows = [(40, 3, 0, 0, 2.0), (40, 20, 0, 0, 8.0), (10, 25, 0, 0, 9.0)]
    ordered = BorderRule((32, 1), horizon_us=1000, rows=0)(_matches(sorted(rows)))
    shuffled = BorderRule((32, 1), horizon_us=1000, rows=0)(_matches(rows))
    assert sorted(shuffled["x"].tolist()) == sorted(ordered["x"].tolist()) == [20, 25]


def test_decisions_do_not_depend_on_the_packets():
    rng = np.random.default_rng(3)
    n = 400
    t = np.sort(rng.integers(0, 20_000, n))
    x = rng.integers(0, 64, n)
    d = np.minimum(rng.integers(0, 30, n), x).astype(float)
    rows = list(zip(t.tolist(), x.tolist(), rng.integers(0, 8, n).tolist(), rng.integers(0, 2, n).tolist(),
                    d.tolist(), strict=True))
    m = _matches(rows)
    whole = BorderRule((64, 8), horizon_us=5000, rows=2)(m)
    rule = BorderRule((64, 8), horizon_us=5000, rows=2)
    cut = int(np.searchsorted(m["t"], 10_000))  # a packet boundary between two times
    parts = np.concatenate([rule(m[:cut]), rule(m[cut:])])
    assert 0 < whole.size < n
    assert np.array_equal(whole, parts)


def test_the_thesis_set_has_no_rule_and_adaptive_has_it():
    for method in ("frame", "event-time", "sgbm"):
        cls = matcher_class(method)
        variant, values = resolve(method, None, "thesis")
        assert border_rule_for(cls.params_for(variant, **values), (WIDTH, HEIGHT)) is None
        variant, values = resolve(method, None, "adaptive")
        assert border_rule_for(cls.params_for(variant, **values), (WIDTH, HEIGHT)) is not None


@pytest.mark.parametrize("field, value", [("border_horizon_us", -1), ("border_rows", 1.5)])
def test_bad_border_fields_are_refused_with_their_name(field, value):
    with pytest.raises(ValueError, match=field):
        BorderParams(**{field: value})


@pytest.fixture(scope="module")
def plane():
    """A textured fronto-parallel plane at PLANE_D px filling the view, the rig moving sideways, ideal rig
    (d = f*B/Z exactly): left x < PLANE_D and right x > W - 1 - PLANE_D have no partner."""
    rig = Rig().for_sensor((WIDTH, HEIGHT)).ideal()
    seconds = 0.5
    scene = FamilyScene("border", 7, (WIDTH, HEIGHT), rig.focal_px, seconds, disparity_px=float(PLANE_D))
    return simulate(scene, rig=rig, seconds=seconds, seed=7, render_hz=max(100.0, scene.plan.image_speed_px_s / 0.5))


def _strip_share(m) -> float:
    strip = ((m["camera"] == 0) & (m["x"] < PLANE_D)) | ((m["camera"] == 1) & (m["x"] > WIDTH - 1 - PLANE_D))
    return float(strip.mean())


@pytest.mark.parametrize("method", available_methods())
def test_no_answers_where_the_partner_is_outside_the_other_image(plane, method):
    with_rule = match(plane, method=method).matches       # the default set and the method's default variant
    assert with_rule.size > 100, f"{method} answered {with_rule.size} times on the plane"
    assert _strip_share(with_rule) <= MAX_STRIP_SHARE, \
        f"{method}: {_strip_share(with_rule):.2%} of its answers lie where the partner is outside the other image"


@pytest.mark.parametrize("method", [m for m in available_methods() if m in ("event-area", "event-vector", "sgbm")])
def test_the_rule_keeps_the_correct_answers(plane, method):
    without = match(plane, method=method, border_horizon_us=0).matches
    with_rule = match(plane, method=method).matches
    assert _strip_share(without) > MAX_STRIP_SHARE  # there was something to refuse
    # Correct answers whose partner is inside the other image (away from the strip).
    room = [np.where(m["camera"] == 0, m["x"], WIDTH - 1 - m["x"]) for m in (without, with_rule)]
    correct = [int(np.sum((np.abs(m["disparity"] - PLANE_D) <= 1) & (r >= PLANE_D)))
               for m, r in zip((without, with_rule), room, strict=True)]
    assert correct[1] >= MIN_CORRECT_KEPT * correct[0], f"{method}: correct answers {correct[0]} -> {correct[1]}"
