"""Pieces of `cvstereo bench` that can be checked by hand (the full run is the benchmark itself)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvstereo.benchmark import distance_table, share_within, speed_table
from cvstereo.experiment import Combo


def test_share_within_any_known_disparity():
    d = np.array([2.0, 3.5, 7.2, 8.0, 9.1, 12.5, 20.0])
    # Within 1 px of 3, 8 or 12: 2.0, 3.5, 7.2, 8.0, 12.5 (9.1 is 1.1 px from 8).
    assert share_within(d, (12.0, 8.0, 3.0)) == pytest.approx(5 / 7)
    assert math.isnan(share_within(np.array([]), (8.0,)))


def test_distance_fit_on_exact_disparities_has_zero_error():
    combo = Combo("frame", "shared")
    a, c = 16.5, 3.0
    dists = {z: None for z in (0.5, 1.5, 0.75, 1.0, 1.25)}
    runs = {combo.label: {f"1arm-{round(z * 100)}cm": {"median": a / z - c} for z in dists}}
    out = distance_table([combo], runs, dists)[combo.label]
    assert out["a"] == pytest.approx(a) and out["c"] == pytest.approx(c)
    assert all(abs(e) < 1e-9 for e in out["error_cm"].values())


def test_speed_table_scales_matlab_time_to_the_data_length():
    combo = Combo("frame", "shared")
    # 5.5 s of data matched in 0.1 s: Matlab would have taken 8.23 s * 5.5 / 11.
    fig = {"events_per_s": 1e6, "realtime_x": 55.0, "elapsed_s": 0.1, "peak_rss_mb": 1.0, "rss_increase_mb": 0.0}
    row = speed_table([combo], {combo.label: {"2arms-50cm": fig}})[combo.label]
    assert row["speedup_vs_matlab"] == pytest.approx(8.23 * 0.5 / 0.1)
