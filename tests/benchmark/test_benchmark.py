"""Pieces of `cvstereo bench` that can be checked by hand (the full run is the benchmark itself)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvstereo.benchmark.harness import bench_markdown, distance_table, share_within, speed_table
from cvstereo.evaluation.experiment import Combo


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
    row = speed_table([combo], {combo.label: fig})[combo.label]
    assert row["speedup_vs_matlab"] == pytest.approx(8.23 * 0.5 / 0.1)


def _tiny_bench(monkeypatch, folder, workers):
    """run_bench on small moving-edge scenes written to ``folder``: (results, recordings by name)."""
    from _event_scenes import moving_edges

    import cvstereo.benchmark.harness as bench
    from cvstereo.io import write_recording_npz
    from cvstereo.model.recording import Recording

    def rec(name, shift):
        left, right = moving_edges(shift=shift, duration_us=50_000, rows=(20, 30))
        path = folder / f"{name}.npz"
        write_recording_npz(path, Recording(left, right))
        return path

    sims = {"2arms-50cm": rec("2arms", 6), "1arm-50cm": rec("1arm", 4)}
    # Nearer, larger disparity.
    dists = {z: rec(f"d{round(z * 100)}", round(10 / z)) for z in (0.5, 1.5, 0.75, 1.0, 1.25)}
    monkeypatch.setattr(bench, "simulated_recordings", lambda config: sims)
    monkeypatch.setattr(bench, "real_recordings", lambda shared: {})
    monkeypatch.setattr(bench, "distance_recordings", lambda config: dists)
    results = bench.run_bench(bench.BenchConfig(quick=True, methods=("frame", "event-time"), workers=workers),
                              progress=False, log=lambda line: None)
    return results, sims, dists


def test_bench_runs_every_combo_on_every_recording_through_the_sweep_engine(monkeypatch, tmp_path):
    """run_bench's figures are evaluate() of match() on each recording, plus the bench's own; the distance set
    named like a preset is the recording run under that name."""
    from cvstereo.evaluation.metrics import evaluate
    from cvstereo.io import read_recording
    from cvstereo.run import match

    results, sims, dists = _tiny_bench(monkeypatch, tmp_path, workers=0)
    # The thesis set's variants, then each method's adaptive default beside them.
    assert list(results["runs"]) == ["frame/shared", "frame/separate", "frame/on", "frame/off",
                                     "frame/separate (adaptive)", "event-time/shared", "event-time/separate",
                                     "event-time/on", "event-time/off", "event-time/separate (adaptive)"]
    timed = {"elapsed_s", "events_per_s", "realtime_x", "peak_rss_mb", "rss_increase_mb"}
    for label, runs in results["runs"].items():
        combo = results["combos"][label]
        method, variant, param_set = combo["method"], combo["variant"], combo["param_set"]
        assert list(runs) == ["2arms-50cm", "1arm-50cm", "1arm-150cm", "1arm-75cm", "1arm-100cm", "1arm-125cm"]
        for name, figures in runs.items():
            path = dists[0.5] if name == "1arm-50cm" else sims.get(name) or dists[int(name[5:-2]) / 100]
            recording = read_recording(path)
            result = match(recording, method=method, variant=variant, param_set=param_set)
            expected = evaluate(recording, result)
            expected["median"] = float(np.median(result.disparity)) if len(result) else float("nan")
            for key, value in expected.items():
                if key not in timed:
                    same = figures[key] == value or (np.isnan(value) and np.isnan(figures[key]))
                    assert same, (label, name, key)
    assert set(results["distance"]) == set(results["runs"])
    # Speed and memory per combo on 2arms-50cm, from runs that agreed or the cap, with the load beside.
    assert list(results["speed"]) == list(results["runs"])
    for s in results["speed"].values():
        assert 2 <= s["runs"] <= 6 and (s["agreed"] or s["runs"] == 6)
        assert s["events_per_s"] > 0 and "load_before" in s and "load_after" in s
    text = bench_markdown(results)
    assert "| frame/shared |" in text and "load" in text


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_bench_on_two_workers_gives_the_serial_accuracy_figures(monkeypatch, tmp_path):
    pytest.importorskip("dask.distributed")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    serial, _, _ = _tiny_bench(monkeypatch, tmp_path / "a", workers=0)
    parallel, _, _ = _tiny_bench(monkeypatch, tmp_path / "b", workers=2)

    def same(a, b):
        return a == b or (isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b))

    assert list(parallel["runs"]) == list(serial["runs"])
    for label, by_name in serial["runs"].items():
        assert list(parallel["runs"][label]) == list(by_name)
        for name, figures in by_name.items():
            other = parallel["runs"][label][name]
            assert set(other) == set(figures)
            assert all(same(figures[k], other[k]) for k in figures), (label, name)
    assert parallel["distance"].keys() == serial["distance"].keys()


def test_bench_score_adds_median_and_known_disparity_share_to_sweep_rows(tmp_path):
    """The bench's figures ride on the sweep engine's score hook, which is part of the cell key."""
    from _event_scenes import moving_edges

    from cvstereo.benchmark.harness import bench_cell_figures
    from cvstereo.io import write_recording_npz
    from cvstereo.model.recording import Recording
    from cvstereo.run import match
    from cvstereo.sweep import Cell, run_sweep

    left, right = moving_edges(shift=8, duration_us=50_000, rows=(20, 30))
    path = tmp_path / "scene.npz"
    write_recording_npz(path, Recording(left, right))
    cell = Cell(str(path), "frame", "shared")
    plain = run_sweep([cell], tmp_path / "plain", workers=0).rows[0]
    scored = run_sweep([cell], tmp_path / "scored", workers=0, score=bench_cell_figures).rows[0]
    assert plain["key"] != scored["key"] and "median" not in plain
    result = match(cell.recording, method="frame", variant="shared")
    assert len(result) > 0 and scored["median"] == float(np.median(result.disparity))
    assert "within_1px" not in scored  # not one of the real recordings
    # Named like a real recording: the share within 1 px of its known 8 px.
    figures = bench_cell_figures(Cell(str(tmp_path / "Fan_disp8.dat"), "frame", "shared"), None, result)
    assert figures["within_1px"] == share_within(result.disparity, (8.0,))


def test_cli_bench_refuses_negative_workers(capsys):
    from cvstereo.cli import main

    assert main(["bench", "--workers", "-1", "-o", "x"]) == 1
    err = capsys.readouterr().err
    assert "--workers -1" in err and err.count("\n") == 1
