"""Evaluation figures on small hand-computed cases (evaluation.md)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cvstereo.evaluation.metrics import evaluate, markdown_table, match_truth, to_json
from cvstereo.model.events import make_events
from cvstereo.model.matches import MatchResult, make_matches
from cvstereo.model.recording import Recording

NAN = float("nan")
EVENT_META = {"anchor": "event", "window_us": 0}


def _recording():
    # left: three signal events and one noise event; right: two signal events and one noise event.
    left = make_events([100, 200, 300, 400], [10, 11, 12, 50], [5, 5, 6, 7], [1, 0, 1, 1])
    right = make_events([150, 250, 350], [4, 5, 90], [5, 5, 9], [1, 0, 0])
    return Recording(left, right, [6.0, 6.0, 7.0, NAN], [6.0, 6.0, NAN])


def test_event_anchors_hand_computed():
    rec = _recording()
    # Four matches on the left: errors 1, 0, 3 on signal events, one on the noise event.
    m = make_matches([100, 200, 300, 400], [10, 11, 12, 50], [5, 5, 6, 7], [1, 0, 1, 1], 0, [7.0, 6.0, 4.0, 9.0])
    f = evaluate(rec, m, {**EVENT_META, "anchor_cameras": [0]})
    assert f["matches"] == 4
    assert f["false_rate"] == pytest.approx(0.25)
    assert f["mae"] == pytest.approx(4 / 3)
    assert f["rmse"] == pytest.approx(math.sqrt((1 + 0 + 9) / 3))
    assert f["median_ae"] == pytest.approx(1.0)
    assert f["bad1"] == pytest.approx(1 / 3)  # only the error of 3 exceeds 1 px (1.0 is not > 1)
    assert f["bad2"] == pytest.approx(1 / 3)
    assert f["coverage"] == pytest.approx(1.0)  # all three left signal events matched
    assert f["mean"] == pytest.approx(26 / 4)
    assert f["std"] == pytest.approx(np.std([7.0, 6.0, 4.0, 9.0], ddof=1))
    assert f["truth_mean"] == pytest.approx((6 + 6 + 7) / 3)


def test_coverage_counts_both_anchor_cameras():
    rec = _recording()
    m = make_matches([150, 200], [4, 11], [5, 5], [1, 0], [1, 0], [6.0, 6.0])
    f = evaluate(rec, m, {**EVENT_META, "anchor_cameras": [0, 1]})
    # 5 events with finite truth across both cameras, 2 matched.
    assert f["coverage"] == pytest.approx(2 / 5)
    assert f["mae"] == 0.0 and f["false_rate"] == 0.0


def test_match_on_unknown_event_is_an_error():
    rec = _recording()
    m = make_matches([101], [10], [5], [1], 0, [6.0])
    with pytest.raises(ValueError, match=r"match 0 .*t=101.* camera 0"):
        evaluate(rec, m, EVENT_META)


def test_window_anchors_take_the_mean_over_the_window():
    w = 40_000
    # Pixel (3, 2) of the left camera: two events in window 0 with truths 4 and 6, one noise event;
    # pixel (8, 2): noise only in window 0; window 1 has one signal event at (3, 2) with truth 10.
    left = make_events([1_000, 2_000, 3_000, 5_000, 41_000], [3, 3, 3, 8, 3], [2, 2, 2, 2, 2], [1, 1, 0, 1, 1])
    right = make_events([1_000], [0], [0], [1])
    rec = Recording(left, right, [4.0, 6.0, NAN, NAN, 10.0], [NAN])
    m = make_matches([w, w, 2 * w], [3, 8, 3], [2, 2, 2], 1, 0, [5.5, 1.0, 12.0])
    meta = {"anchor": "window", "window_us": w, "anchor_cameras": [0]}
    truth = match_truth(rec, m, anchor="window", window_us=w)
    np.testing.assert_allclose(truth, [5.0, NAN, 10.0])
    f = evaluate(rec, m, meta)
    assert f["false_rate"] == pytest.approx(1 / 3)
    assert f["mae"] == pytest.approx((0.5 + 2.0) / 2)
    assert f["bad1"] == pytest.approx(0.5)
    # Cells with truth: (window 0, (3,2)) and (window 1, (3,2)); both matched.
    assert f["coverage"] == pytest.approx(1.0)


def test_window_anchor_off_grid_is_an_error():
    rec = _recording()
    m = make_matches([40_001], [10], [5], 1, 0, [6.0])
    with pytest.raises(ValueError, match="not a window end"):
        evaluate(rec, m, {"anchor": "window", "window_us": 40_000})


def test_without_truth_only_thesis_figures_and_speed():
    ev = make_events([0, 1_000_000], [1, 2], [1, 1], [1, 0])
    rec = Recording(ev, ev)
    m = make_matches([0, 1_000_000], [1, 2], [1, 1], [1, 0], 0, [2.0, 4.0])
    f = evaluate(rec, MatchResult(m, {**EVENT_META, "elapsed_s": 0.5, "input_events": 4}))
    assert f["mean"] == 3.0 and f["std"] == pytest.approx(math.sqrt(2))
    assert f["events_per_s"] == pytest.approx(8.0)
    assert f["realtime_x"] == pytest.approx(2.0)
    assert math.isnan(f["mae"]) and math.isnan(f["coverage"])


def test_empty_matches():
    f = evaluate(_recording(), make_matches([], [], [], [], [], []), EVENT_META)
    assert f["matches"] == 0 and math.isnan(f["mean"]) and math.isnan(f["false_rate"])
    assert f["coverage"] == 0.0


def test_json_and_markdown():
    f = evaluate(_recording(), make_matches([100], [10], [5], [1], 0, [7.0]), EVENT_META)
    data = json.loads(to_json({"r": f}))
    assert data["r"]["mae"] == 1.0 and data["r"]["std"] is None
    table = markdown_table({"1arm-50cm": f}, thesis={"1arm-50cm": (28.22, 4.86)})
    header, rule, row = table.splitlines()
    assert header.startswith("| recording | mean | thesis mean | std | thesis std |")
    assert "| 1arm-50cm | 7.00 | 28.22 | - | 4.86 |" in row
    assert rule.count("|") == header.count("|")
