"""``match()`` from a path streams the reader's packets: same matches and meta as from the loaded recording."""

from __future__ import annotations

import numpy as np
import pytest
from _event_scenes import moving_edges

import cvstereo.io
import cvstereo.io.npz
import cvstereo.io.stream
from cvstereo.io import read_recording, write_recording
from cvstereo.model.recording import Recording
from cvstereo.run import match


def _recording(seed: int = 0) -> Recording:
    """Moving edges seen 6 px apart, starting at 1 ms (so that the duration is not the last time stamp)."""
    left, right = moving_edges(shift=6, duration_us=60_000, rows=(20, 40), seed=seed)
    left["t"] += 1_000
    right["t"] += 1_000
    return Recording(left, right, meta={"source": "test"})


@pytest.fixture(params=["recording.npz", "recording.txt", "recording.aedat"])
def recording_file(request, tmp_path):
    rec = _recording()
    path = tmp_path / request.param
    write_recording(path, rec)
    return path


def _no_whole_reads(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("match(path) read the whole file")

    monkeypatch.setattr(cvstereo.io.stream.RecordingStream, "read", refuse)
    monkeypatch.setattr(cvstereo.io.npz, "read_recording_npz", refuse)
    monkeypatch.setattr(cvstereo.io, "read_recording_npz", refuse)
    monkeypatch.setattr(cvstereo.io, "read_recording", refuse)


@pytest.mark.parametrize(("method", "variant"), [("frame", "separate"), ("event-time", "shared"),
                                                 ("frame-area", "gaussian")])
def test_match_from_a_path_streams_and_equals_the_loaded_recording(recording_file, monkeypatch, method, variant):
    loaded = read_recording(recording_file)
    expected = match(loaded, method=method, variant=variant, packet_us=7_000)
    _no_whole_reads(monkeypatch)
    got = match(recording_file, method=method, variant=variant, packet_us=7_000)
    assert expected.matches.size > 0
    np.testing.assert_array_equal(got.matches, expected.matches)
    assert got.meta["input_events"] == loaded.left.size + loaded.right.size == expected.meta["input_events"]
    assert got.meta["duration_s"] == pytest.approx(loaded.duration_s) and loaded.duration_s > 0.05
    assert got.meta["resolution"] == list(loaded.resolution)
    assert got.meta["input"] == [str(recording_file)]


def test_match_from_a_path_with_a_rig_correction(tmp_path, monkeypatch):
    path = tmp_path / "r.npz"
    write_recording(path, _recording(1))
    expected = match(read_recording(path), method="frame", row_offset=1, time_offset_us=300)
    _no_whole_reads(monkeypatch)
    got = match(path, method="frame", row_offset=1, time_offset_us=300)
    np.testing.assert_array_equal(got.matches, expected.matches)
    assert got.meta["rig_correction"] == expected.meta["rig_correction"]


def test_without_any_entry_point_the_builtin_matchers_are_still_registered(monkeypatch):
    # 0.2 raised NoMatchersError here (a checkout on sys.path, not installed); the built-in table lists them.
    import cvstereo.matchers.registry as registry
    from cvstereo.matchers._registry import BUILTIN_METHODS

    monkeypatch.setattr(registry.importlib.metadata, "entry_points", lambda **kw: [])
    registry._methods.cache_clear()
    try:
        assert dict(registry.METHODS) == BUILTIN_METHODS
        assert registry.matcher_class("event-area").method == "event-area"
    finally:
        monkeypatch.undo()
        registry._methods.cache_clear()


def test_run_is_the_loop_match_uses_and_reports_every_packet():
    from cvstereo.matchers.registry import create_matcher
    from cvstereo.run import run

    rec = _recording(2)
    seen = []
    result = run(create_matcher("frame", resolution=rec.resolution), rec.packets(10_000),
                 on_packet=lambda packet, found: seen.append((packet, found.size)))
    expected = match(rec, method="frame", packet_us=10_000, rig_check=False)   # run() has no stages
    np.testing.assert_array_equal(result.matches, expected.matches)
    assert result.meta["fingerprint"] == expected.meta["fingerprint"]
    assert result.meta["input_events"] == rec.left.size + rec.right.size
    # One call per packet, then one for the flush (packet None); together they hold every match.
    assert seen[-1][0] is None and all(packet is not None for packet, _ in seen[:-1])
    assert sum(n for _, n in seen) == result.matches.size
    assert sum(p.left.size + p.right.size for p, _ in seen[:-1]) == rec.left.size + rec.right.size
