"""Fused's segment test (design part 11): the segments by hand, and exactly those answers penalised."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import feed_cut
from test_fused import textured_pair

from cvstereo.matchers.fused._segments import segment_min_for, small_segments
from cvstereo.matchers.fused.matcher import FusedMatcher
from cvstereo.matchers.fused.params import FusedParams


def test_segments_by_hand():
    # (x, y, disparity, judged) and whether its segment has fewer than 3 judged answers.
    answers = [
        (2, 2, 5.0, True, False), (3, 2, 5.0, True, False), (4, 2, 5.5, True, False),
        (6, 2, 6.0, True, False),  # 2 px from (4, 2), 0.5 px of disparity: the same run of 4
        (9, 2, 6.0, True, True),  # 3 px from the run: alone
        (2, 5, 5.0, True, True),  # 3 rows below the run: alone
        (3, 6, 7.5, True, True),  # beside (2, 5) but 2.5 px of disparity away: alone
        (10, 8, 1.0, True, False), (11, 8, 2.0, True, False), (12, 8, 3.0, True, False),  # 1 px steps: joined
        (14, 2, 5.0, True, True), (16, 2, 5.0, False, False), (18, 2, 5.0, True, True),  # no bridge unjudged
    ]
    x, y, d, judged, expected = (np.array(c) for c in zip(*answers, strict=True))
    grid = np.full((10, 20), -1, np.int64)
    got = small_segments(x.astype(np.int64), y.astype(np.int64), d.astype(np.float64), judged.astype(bool), grid, 3)
    np.testing.assert_array_equal(got, expected.astype(bool))
    assert (grid == -1).all()  # the scratch is left as it was given
    assert not small_segments(x, y, d, judged, grid, 1).any()


@pytest.mark.parametrize(("least", "width", "expected"), [(50, 128, 50), (50, 640, 250), (50, 346, 135), (0, 640, 0)])
def test_least_answers_scale_with_the_width(least, width, expected):
    assert segment_min_for(FusedParams(segment_min_answers=least), width) == expected


def _groups(x, y, d, judged):
    """Each judged answer's segment size, by a flood fill written out plainly (an independent expectation)."""
    size = np.zeros(x.size, int)
    label = -np.ones(x.size, int)
    for i in np.flatnonzero(judged):
        if label[i] >= 0:
            continue
        label[i], todo, members = i, [i], [i]
        while todo:
            j = todo.pop()
            near = judged & (label < 0) & (np.maximum(abs(x - x[j]), abs(y - y[j])) <= 2) & (abs(d - d[j]) <= 1.0)
            for q in np.flatnonzero(near):
                label[q] = i
                todo.append(q)
                members.append(q)
        size[members] = len(members)
    return size


@pytest.mark.parametrize("least", [8, 20])
def test_ranks_exactly_the_answers_of_small_segments_between_the_tiers(least):
    # The same answers with and without the test (no prior: temporal_weight 0); with it, the consistent answers
    # whose segment in their window holds fewer than the least count (scaled to the 40 px width), but for the
    # clear ones (below isolated_max_uncertainty), move to (0.5, 0.75], the inconsistent ones to (0.75, 1].
    left, right, resolution = textured_pair(7, windows=6, noise=120)
    runs = {}
    for n in (0, least):
        m = FusedMatcher(FusedParams(max_uncertainty=1.0, temporal_weight=0.0, segment_min_answers=n),
                         resolution=resolution)
        runs[n] = (feed_cut(m, left, right, []), m.take_uncertainty().astype(np.float64))
    (got, u_off), (got_on, u_on) = runs[0], runs[least]
    np.testing.assert_array_equal(got_on, got)
    x, y, d = got["x"].astype(int), got["y"].astype(int), got["disparity"].astype(np.float64)
    small = np.zeros(got.size, bool)
    for t in np.unique(got["t"]):
        w = got["t"] == t
        sizes = _groups(x[w], y[w], d[w], u_off[w] <= 0.5)
        small[w] = (u_off[w] <= 0.5) & (sizes < round(least * resolution[0] / 128))
    flagged = small & ~(u_off < FusedParams().isolated_max_uncertainty)
    assert 0 < flagged.sum() < (u_off <= 0.5).sum()
    tiers = np.where(flagged, 0.5 + u_off / 2, np.where(u_off > 0.5, 0.75 + (u_off - 0.5) / 2, u_off))
    np.testing.assert_allclose(u_on, tiers, atol=1e-6)  # float32 uncertainties
    assert u_on[flagged].max() <= 0.75 < u_on[u_off > 0.5].min()
