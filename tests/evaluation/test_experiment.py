"""cvstereo.evaluation.experiment: the demo's and bench's runs are sweep-engine cells, equal to match + evaluate."""

from __future__ import annotations

import math

import pytest
from _event_scenes import moving_edges

from cvstereo.evaluation.experiment import Combo, run_experiment
from cvstereo.evaluation.metrics import FIGURES, evaluate
from cvstereo.model.recording import Recording
from cvstereo.run import match
from cvstereo.sweep import Cell, run_sweep


def _recordings():
    out = {}
    for name, shift in (("near", 9), ("far", 4)):
        left, right = moving_edges(shift=shift, duration_us=50_000, rows=(20, 30))
        out[name] = Recording(left, right)
    return out


def test_in_memory_experiment_equals_match_and_evaluate():
    recordings = _recordings()
    combos = [Combo("frame", "shared"), Combo("event-time", "on", param_set="adaptive")]
    result = run_experiment(recordings, combos)
    assert list(result.figures) == combos
    for combo in combos:
        assert list(result.figures[combo]) == ["near", "far"]
        for name, rec in recordings.items():
            expected = evaluate(rec, match(rec, method=combo.method, variant=combo.variant,
                                           param_set=combo.param_set))
            got = result.figures[combo][name]
            assert set(got) == set(FIGURES)
            for key in FIGURES:
                if key in ("events_per_s", "realtime_x"):
                    continue  # timing
                same = got[key] == expected[key] or (math.isnan(got[key]) and math.isnan(expected[key]))
                assert same, (combo.label, name, key, got[key], expected[key])
    assert result.figures[combos[0]]["near"]["matches"] > 0


def test_failing_run_names_combo_and_recording():
    with pytest.raises(RuntimeError, match=r"frame/shared \[bogus=1\] on near failed: ValueError"):
        run_experiment({"near": _recordings()["near"]}, [Combo("frame", "shared", params=(("bogus", 1),))])


def test_in_memory_recordings_are_not_sent_to_workers(tmp_path):
    rec = _recordings()["far"]
    with pytest.raises(ValueError, match="in this process only"):
        run_sweep([Cell("memory:far", "frame", None)], tmp_path, workers=2, recordings={"memory:far": rec})
