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


def test_bench_runs_every_combo_on_every_recording_through_the_experiment_loop(monkeypatch):
    """run_bench's figures are evaluate() of match() on each recording, plus the bench's own; the distance set
    named like a preset is the recording run under that name."""
    from _event_scenes import moving_edges

    import cvstereo.benchmark as bench
    from cvstereo.evaluate import evaluate
    from cvstereo.pipeline import match
    from cvstereo.recording import Recording

    def rec(shift):
        left, right = moving_edges(shift=shift, duration_us=50_000, rows=(20, 30))
        return Recording(left, right)

    sims = {"2arms-50cm": rec(6), "1arm-50cm": rec(4)}
    dists = {z: rec(int(10 * z)) for z in (0.5, 1.5, 0.75, 1.0, 1.25)}
    monkeypatch.setattr(bench, "simulated_recordings", lambda config: sims)
    monkeypatch.setattr(bench, "real_recordings", lambda shared: {})
    monkeypatch.setattr(bench, "distance_recordings", lambda config: dists)
    results = bench.run_bench(bench.BenchConfig(quick=True, methods=("frame", "event-time")), progress=False,
                              log=lambda line: None)
    assert list(results["runs"]) == ["frame/shared", "frame/separate", "frame/on", "frame/off", "event-time/shared",
                                     "event-time/separate", "event-time/on", "event-time/off"]
    timed = {"elapsed_s", "events_per_s", "realtime_x", "peak_rss_mb", "rss_increase_mb"}
    for label, runs in results["runs"].items():
        method, variant = label.split("/")
        assert list(runs) == ["2arms-50cm", "1arm-50cm", "1arm-150cm", "1arm-75cm", "1arm-100cm", "1arm-125cm"]
        for name, figures in runs.items():
            recording = dists[0.5] if name == "1arm-50cm" else sims.get(name) or dists[int(name[5:-2]) / 100]
            result = match(recording, method=method, variant=variant)
            expected = evaluate(recording, result)
            expected["median"] = float(np.median(result.disparity)) if len(result) else float("nan")
            for key, value in expected.items():
                if key not in timed:
                    same = figures[key] == value or (np.isnan(value) and np.isnan(figures[key]))
                    assert same, (label, name, key)
    assert set(results["distance"]) == set(results["runs"])
