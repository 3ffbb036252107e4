"""DSEC's metrics and PNGs at the function level: edge cases the command-level tests do not reach."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cvstereo.evaluation.dense_truth import predicted_maps, score_maps
from cvstereo.io.dsec_sequence import MAX_PNG_DISPARITY, read_disparity_png, write_disparity_png
from cvstereo.model.matches import make_matches


def test_no_answered_pixel_gives_no_error_figures_and_zero_coverage():
    truth = [(50_000, np.full((2, 3), 4.0))]
    m = make_matches([60_000], [0], [0], 0, 0, [4.0])  # after the only map: not its
    got = score_maps(m, truth, resolution=(3, 2))
    assert got["1PE"] is None and got["MAE"] is None and got["RMSE"] is None
    assert (got["coverage"], got["maps"], got["pixels_scored"], got["truth_pixels"]) == (0.0, 1, 0, 6)


def test_window_is_half_open_and_right_anchors_move_by_their_disparity():
    # (ts - 50 ms, ts]: t = 0 is out, t = 50 ms is in. The right-anchored match at x = 0 with d = 2 answers x = 2.
    #                  t       x          y          p  camera     disparity
    m = make_matches([0, 1, 50_000], [1, 0, 0], [0, 0, 0], 0, [0, 1, 0], [9.0, 2.0, 3.0])
    (_, image), = predicted_maps(m, [50_000], resolution=(3, 1))
    np.testing.assert_array_equal(image, [[3.0, np.nan, 2.0]])  # the t = 0 match (x = 1, d = 9) is out
    truth = [(50_000, np.array([[np.nan, 1.0, 4.0]]))]
    got = score_maps(m, truth, resolution=(3, 1))
    # only pixel 2 has both: error |2 - 4| = 2, above 1 px, not above 2 px; 1 of the 2 truth pixels answered
    assert (got["MAE"], got["RMSE"], got["1PE"], got["2PE"], got["coverage"]) == (2.0, 2.0, 1.0, 0.0, 0.5)


def test_png_round_trip_zero_and_limits(tmp_path):
    d = np.array([[np.nan, 0.0, -1.0, 1 / 1024, 10.3], [100.123, 255.99, MAX_PNG_DISPARITY, 0.5, np.inf]])
    with pytest.raises(ValueError, match=r"disparity inf px at pixel \(4, 1\)"):
        write_disparity_png(tmp_path / "d.png", d)
    assert not (tmp_path / "d.png").exists()
    d[1, 4] = np.nan
    write_disparity_png(tmp_path / "d.png", d)
    raw = cv2.imread(str(tmp_path / "d.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16
    # NaN, 0, negative and a value that rounds to 0 are "no answer"; the rest within 1/512 px
    np.testing.assert_array_equal(raw[0, :4], 0)
    back = read_disparity_png(tmp_path / "d.png")
    ok = raw > 0
    assert np.isnan(back[~ok]).all() and np.max(np.abs(back[ok] - d[ok])) <= 1 / 512
    assert raw[1, 2] == 65535
