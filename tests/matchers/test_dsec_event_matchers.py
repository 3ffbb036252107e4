"""The event matchers on a DSEC-layout file at 640x480: events from the simulator (one arm at 1 m on a 640x480
sensor, true disparity about 67 px) written as DSEC ships them, read back and matched.

They answer there with the simulator's disparity, and exactly as on the same recording in memory: the reader,
the 640x480 disparity range and DSEC's clock (times near 5 * 10^10 us) change nothing. On the calibrated
blinking-dot sequence of ``tests/_dsec_scene.py`` (distorted, turned right camera) they answer through
``--calibration`` with the distances of the scene's two planes; with one event per blink they could not (see
``write_dsec_sequence``).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("h5py")
pytest.importorskip("hdf5plugin")

from cvstereo.evaluation.metrics import evaluate
from cvstereo.io import read_matches, read_recording
from cvstereo.model.recording import Recording
from cvstereo.run import match
from tests._hdf5_fixtures import write_dsec_pair

#: DSEC's t_offset is microseconds of the day; a multiple of the 40 ms window and of the 250 us decay step, so
#: that the windows and decay steps of the absolute clock fall on the same events as in memory.
T_OFFSET = 52_000_000_000
EVENT_MATCHERS = ("event-time", "event-area", "event-vector")


@pytest.fixture(scope="module")
def arm640(tmp_path_factory):
    from cvstereo.simulate import ArmsScene, Rig, simulate

    rec = simulate(ArmsScene(arms=1, distance_m=1.0), rig=Rig().for_sensor((640, 480)), seconds=0.2, seed=5)
    left, right = write_dsec_pair(tmp_path_factory.mktemp("dsec"), rec, t_offset=T_OFFSET)
    return rec, left, right


def test_the_dsec_files_hold_the_simulated_events(arm640):
    rec, left, right = arm640
    back = read_recording(left, right)
    assert back.resolution == (640, 480) and back.meta.get("t_offset") in (None, T_OFFSET)
    for cam in ("left", "right"):
        got, want = getattr(back, cam), getattr(rec, cam)
        np.testing.assert_array_equal(got["t"], want["t"] + T_OFFSET)
        for field in ("x", "y", "p"):
            np.testing.assert_array_equal(got[field], want[field])


@pytest.mark.slow
@pytest.mark.parametrize("method", EVENT_MATCHERS)
def test_event_matchers_answer_on_a_640x480_dsec_file(arm640, method):
    rec, left, right = arm640
    back = read_recording(left, right)
    got = match(back, method=method)
    # Against the simulator's per-event truth (the file keeps the events' order, so the truth carries over).
    truth = Recording(back.left, back.right, rec.left_disparity, rec.right_disparity, back.resolution)
    figures = evaluate(truth, got)
    assert len(got) > 5000, figures
    assert figures["coverage"] > 0.2 and figures["median_ae"] <= 1.0, figures
    assert abs(np.median(got.disparity) - np.nanmedian(rec.left_disparity)) <= 2
    # The same matches as on the recording in memory, on DSEC's clock.
    mem = match(rec, method=method)
    np.testing.assert_array_equal(got.matches["t"], mem.matches["t"] + T_OFFSET)
    for field in set(got.matches.dtype.names) - {"t"}:
        np.testing.assert_array_equal(got.matches[field], mem.matches[field])


@pytest.mark.slow
def test_match_cli_on_the_dsec_pair(arm640, tmp_path):
    from cvstereo.cli import main

    rec, left, right = arm640
    assert main(["match", str(left), str(right), "-m", "event-area", "-o", str(tmp_path / "m.npz")]) == 0
    got = read_matches(tmp_path / "m.npz")
    expected = match(rec, method="event-area")
    assert got.matches.size == expected.matches.size > 5000
    np.testing.assert_array_equal(got.matches["disparity"], expected.matches["disparity"])


#: Share of the matches whose distance lies within 10 % of one of the scene's planes, at least (measured with
#: seeds 0, 1, 2: event-time 0.99, event-vector 0.80, event-area 0.67; sgbm 1.00 in test_sample_dsec.py). Dots
#: on a random pattern repeat along a 640-px row, so the block matchers meet look-alike blocks more often.
ON_A_PLANE = {"event-time": 0.95, "event-vector": 0.7, "event-area": 0.6}


@pytest.mark.slow
@pytest.mark.parametrize("method", EVENT_MATCHERS)
def test_event_matchers_with_calibration_on_the_dsec_scene(method, tmp_path, capsys):
    from cvstereo.cli import main
    from tests._dsec_scene import DEPTHS, write_dsec_sequence

    seq = write_dsec_sequence(tmp_path / "seq", seconds=0.2, seed=1)
    ev = seq / "events"
    assert main(["match", str(ev / "left" / "events.h5"), str(ev / "right" / "events.h5"), "-m", method,
                 "--calibration", str(seq / "calibration" / "cam_to_cam.yaml"), "-o", str(tmp_path / "m.npz")]) == 0
    z = read_matches(tmp_path / "m.npz").arrays["depth_m"].astype(np.float64)
    z = z[np.isfinite(z)]
    assert z.size > 5000, capsys.readouterr().out
    per_plane = [np.mean(np.abs(z - d) / d < 0.1) for d in DEPTHS]
    assert sum(per_plane) >= ON_A_PLANE[method], per_plane
    assert min(per_plane) > 0.15, per_plane  # the box and the wall both
