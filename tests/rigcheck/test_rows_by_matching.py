"""Rows by matching (cvstereo.rigcheck.rows_by_matching) and their use by the default prefix check."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.model.events import make_events
from cvstereo.rigcheck.prefix import MATCHING_MIN_PROMINENCE
from cvstereo.rigcheck.rows_by_matching import matching_span, rows_by_matching, rows_from_counts
from cvstereo.run import match
from tests.rigcheck.test_rigcheck import textured_patches, with_rig_errors


@pytest.fixture(scope="module")
def patches():
    return textured_patches(seconds=0.6)


def test_rows_from_counts_by_hand():
    # Peak at -1 (700) between 650 and 480: the parabola's vertex at -1 + 0.5 * (650 - 480) / (650 - 1400 + 480).
    found = rows_from_counts({-2: 650, -1: 700, 0: 480, 1: 70, 2: 30})
    assert found.offset == -1                               # vertex at -1.31
    assert found.prominence == pytest.approx(1 - 480 / 700)  # median 480
    found = rows_from_counts({-3: 10, -2: 40, -1: 61, 0: 60, 1: 12})
    assert found.offset == -1                               # vertex at -0.55: rounds to -1
    assert rows_from_counts({-1: 0, 0: 0, 1: 0}) == (0, 0.0, {-1: 0, 0: 0, 1: 0}, 0)
    assert rows_from_counts({-4: 5, -2: 9, 0: 7, 2: 1}).offset == -2     # no neighbour both sides: the best itself
    flat = rows_from_counts({r: 1000 + (r == 3) for r in range(-8, 9)})
    assert flat.prominence < MATCHING_MIN_PROMINENCE        # a flat profile does not tell the rows


def test_matching_span_by_hand():
    left = make_events(np.arange(0, 1_000_000, 1000), np.zeros(1000, int), np.zeros(1000, int), np.ones(1000, int))
    right = make_events(np.arange(500, 1_000_000, 2000), np.zeros(500, int), np.zeros(500, int), np.ones(500, int))
    # Dense enough: 100 events each within 80 ms? left's 100th at 99 ms, right's at 198.5 ms -> 198,501.
    assert matching_span(left, right, min_us=80_000, max_us=10_000_000, events=100) == 198_501
    assert matching_span(left, right, min_us=250_000, max_us=10_000_000, events=100) == 250_000
    assert matching_span(left, right, min_us=80_000, max_us=150_000, events=100) == 150_000
    assert matching_span(left, right, min_us=80_000, max_us=10_000_000, events=10**6) == 999_001  # the last event


@pytest.mark.parametrize(("rows", "threads"), [(0, 1), (2, 1), (-3, 1), (-3, 3)])
def test_rows_by_matching_finds_a_known_row_shift(patches, rows, threads):
    rec = with_rig_errors(patches, rows=rows)
    found = rows_by_matching(rec.left, rec.right, resolution=rec.resolution, reach=6, threads=threads)
    assert found.offset == -rows
    assert found.prominence >= MATCHING_MIN_PROMINENCE
    assert max(found.counts.values()) == found.counts[-rows]
    # The even offsets, then the two beside the best of them.
    best_even = max((r for r in found.counts if r % 2 == 0), key=found.counts.get)
    assert set(found.counts) == set(range(-6, 7, 2)) | {best_even - 1, best_even + 1}
    if threads > 1:  # the offsets matched side by side: the same counts as one after another
        assert found == rows_by_matching(rec.left, rec.right, resolution=rec.resolution, reach=6, threads=1)


@pytest.mark.shared_data
@pytest.mark.parametrize("rows", [0, 2])
def test_prefix_check_takes_the_rows_by_matching_where_the_overlay_is_unsure(tum_dir, rows):
    """NSTlogo (2,600 events of a logo sliding sideways): the overlay's row confidence stays below the gate; the
    matching finds the rows moved by ``rows`` and the prefix check applies them."""
    from cvstereo.io import read_recording

    rec = with_rig_errors(read_recording(tum_dir / "NSTlogo_disp12-8-3.dat"), rows=rows)
    check = match(rec, method="frame-area").meta["rigcheck"]
    assert check["row_offset_confidence"] < 0.3
    assert check["rows_by_matching"]["offset"] == -rows
    assert check["applied"]["row_offset"] == -rows
    skipped = match(rec, method="frame-area", rig_check=False)
    assert rows == 0 or len(skipped.matches) < 0.5 * len(match(rec, method="frame-area").matches)


@pytest.mark.parametrize(("by_matching", "rows", "said"), [
    (None, 0, "first 0.5 s"),
    ({"offset": -2}, -2, "first 0.5 s (rows by matching)"),
    ({"offset": 3}, 0, "first 0.5 s (rows: none stood out)")])
def test_the_geometry_line_says_where_the_rows_came_from(by_matching, rows, said):
    from cvstereo.geometry.source import Geometry

    found = {"applied": {"swap": False, "row_offset": rows, "time_offset_us": 0}, "prefix_us": 500_000,
             "skipped": None, "rows_by_matching": by_matching}
    label = Geometry().with_prefix_check(found).labels["rigcheck"]
    assert label.endswith(said)


def test_a_scene_without_vertical_structure_gives_a_flat_profile():
    """Full-height vertical bars sliding sideways look the same at every row offset: the answers' profile stays
    within a few percent of flat (the rows cut at the sensor's edges make the only slope), below the gate."""
    rng = np.random.default_rng(0)
    cams = []
    for shift in (4, -4):  # disparity 8
        t, x = [], []
        for ti in range(0, 400_000, 1000):
            for c in (30, 55, 80, 100):  # x stays within 6..124
                t.append(ti + rng.integers(0, 300, 128))
                x.append(np.full(128, int(c + 20 * np.sin(2 * np.pi * ti / 200_000)) + shift))
        t, x = np.concatenate(t), np.concatenate(x)
        order = np.argsort(t, kind="stable")
        cams.append(make_events(t[order], x[order], np.tile(np.arange(128), t.size // 128)[order], 1))
    found = rows_by_matching(*cams, resolution=(128, 128), reach=8)
    assert found.prominence < MATCHING_MIN_PROMINENCE
    assert max(found.counts.values()) <= 1.15 * min(found.counts.values())


def test_the_counting_matcher_keeps_the_answers_the_check_was_tuned_on():
    """The rows by matching count frame-area's answers without its uniqueness check (MATCHING_PARAMS): the
    check's thresholds were chosen on those answers, and on a repeating texture the default's check drops them."""
    from cvstereo.matchers.registry import create_matcher
    from cvstereo.model.matches import concat_matches
    from cvstereo.rigcheck.rows_by_matching import span_matches

    # Vertical bars every 6 px sliding right one pixel per ms, each bar's pixels firing as it arrives; the right
    # camera sees them 4 px further left: disparities 4, 10, 16, ... fit alike.
    t = np.arange(0, 300_000, 1000)
    ts, xs, ys = [], [], []
    for k, tk in enumerate(t):
        x = np.arange(10 + k % 6, 110, 6)
        xx, yy = np.meshgrid(x, np.arange(30, 90))
        ts.append(np.full(xx.size, tk)), xs.append(xx.ravel()), ys.append(yy.ravel())
    t, x, y = (np.concatenate(a) for a in (ts, xs, ys))
    left, right = make_events(t, x, y, np.ones(t.size, int)), make_events(t, x - 4, y, np.ones(t.size, int))
    resolution, end = (128, 128), int(t[-1]) + 1

    def answers(**params):
        matcher = create_matcher("frame-area", resolution=resolution, threads=1, **params)
        return concat_matches([matcher.feed(left, right, until=end), matcher.flush()])

    counted = span_matches(left, right, resolution=resolution, end=end)
    assert counted.size > 1000
    np.testing.assert_array_equal(counted, answers(uniqueness=0.0))
    assert answers().size < counted.size / 5  # the default's uniqueness check leaves the bars unanswered
