"""The default rig check of ``match()`` on a prefix of the stream (cvstereo.rigcheck.prefix), and its precedence.

Recordings with a known swap and row offset are made from clean ones (tests.rigcheck.test_rigcheck); the check
must find them, and the matches must then be those of the clean recording: every match of the clean one that
does not involve the rows moved off the sensor comes back (MATCH_SHARE).
"""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.model.events import StereoPacket, iter_stereo_packets
from cvstereo.model.recording import Recording
from cvstereo.rigcheck import RigCheckParams
from cvstereo.rigcheck.prefix import PrefixRigCheck
from cvstereo.run import match
from tests.rigcheck.test_rigcheck import textured_patches, with_rig_errors
from tests.rigcheck.test_rigcheck_periodic import periodic_fan

#: Share of the clean recording's matches that the shifted one must give back after the check: the rows shifted
#: off the sensor (2-3 of 128) lose their events, and the matches near them change.
MATCH_SHARE = 0.9
METHOD = "frame-area"


@pytest.fixture(scope="module")
def patches() -> Recording:
    return textured_patches(seconds=0.6)


def _corrected_keys(result) -> set:
    """The matches as the matcher produced them (the rig correction's restore undone): (t, x, y, camera, d)."""
    applied = result.meta["rigcheck"]["applied"]
    m = result.matches
    right = m["camera"] == 1
    y = m["y"].astype(int) + right * applied["row_offset"]
    t = m["t"].astype(np.int64) - right * applied["time_offset_us"]
    return set(zip(t.tolist(), m["x"].tolist(), y.tolist(), m["camera"].tolist(), m["disparity"].tolist(),
                   strict=True))


@pytest.mark.parametrize(("swap", "rows"), [(False, 2), (False, -3), (True, 2), (True, -2), (True, 0)])
def test_finds_and_applies_swap_and_rows_as_the_aligned_recording(patches, swap, rows):
    aligned = match(patches, method=METHOD)
    assert aligned.meta["rigcheck"]["applied"]["swap"] is False
    assert aligned.meta["rigcheck"]["applied"]["row_offset"] == 0
    shifted = match(with_rig_errors(patches, rows=rows, swap=swap), method=METHOD)
    check = shifted.meta["rigcheck"]
    assert check["scope"] == "prefix" and check["skipped"] is None
    assert check["applied"]["swap"] is swap
    assert check["applied"]["row_offset"] == -rows
    assert abs(check["applied"]["time_offset_us"] - aligned.meta["rigcheck"]["applied"]["time_offset_us"]) <= 500
    assert np.median(shifted.disparity) > 0          # the matches refer to the cameras in the order used
    want, got = _corrected_keys(aligned), _corrected_keys(shifted)
    assert len(want) > 500
    assert len(want & got) >= MATCH_SHARE * len(want)


def test_without_the_check_the_shifted_recording_loses_its_matches(patches):
    # The independent side of the test above: the check is what brings the matches back.
    aligned = _corrected_keys(match(patches, method=METHOD))
    raw = match(with_rig_errors(patches, rows=3), method=METHOD, rig_check=False)
    assert "rigcheck" not in raw.meta
    keys = set(zip(raw.matches["t"].tolist(), raw.matches["x"].tolist(), raw.matches["y"].tolist(),
                   raw.matches["camera"].tolist(), raw.matches["disparity"].tolist(), strict=True))
    assert len(aligned & keys) < 0.5 * len(aligned)


def test_thesis_set_and_explicit_offsets_do_not_check(patches):
    shifted = with_rig_errors(patches, rows=2)
    assert "rigcheck" not in match(shifted, method=METHOD, param_set="thesis").meta
    given = match(shifted, method=METHOD, row_offset=0)         # "aligned", said explicitly: it wins
    assert "rigcheck" not in given.meta and "rig_correction" not in given.meta
    timed = match(shifted, method=METHOD, time_offset_us=100)
    assert "rigcheck" not in timed.meta
    assert timed.meta["rig_correction"] == {"row_offset": 0, "time_offset_us": 100, "dropped_events": 0}


def test_rectification_wins_over_the_check(patches):
    from cvstereo.geometry.calibration import StereoCalibration
    from cvstereo.geometry.rectify import Rectification

    k = np.array([[100.0, 0, 64], [0, 100.0, 64], [0, 0, 1]])
    cal = StereoCalibration.from_opencv(k, None, k, None, np.eye(3), np.array([-0.1, 0, 0]), (128, 128))
    result = match(patches, method=METHOD, rectification=Rectification(cal))
    assert "rigcheck" not in result.meta and "rectification" in result.meta


def test_periodic_scene_gets_no_time_offset():
    fan = periodic_fan(seconds=1.0, time_offset_us=3_000)
    result = match(fan, method=METHOD)
    check = result.meta["rigcheck"]
    assert check["skipped"] is None
    assert check["time_offset_ambiguous"] or check["time_offset_confidence"] < 0.6
    assert check["applied"]["time_offset_us"] == 0


def test_recording_shorter_than_the_prefix_is_checked_whole():
    short = textured_patches(seconds=0.3, seed=3)
    result = match(with_rig_errors(short, rows=2), method=METHOD)
    check = result.meta["rigcheck"]
    assert check["applied"]["row_offset"] == -2
    assert check["prefix_us"] <= 300_000 + 40_000      # the whole recording, to its last packet's end
    assert len(result) > 0


def test_too_few_events_leave_the_stream_as_recorded_and_say_why():
    from cvstereo.model.events import make_events

    left = make_events([0, 1000, 2000], [40, 41, 42], [5, 5, 5], [1, 1, 1])
    result = match(Recording(left, left), method=METHOD, threshold=0.5)
    check = result.meta["rigcheck"]
    assert check["applied"] == {"swap": False, "row_offset": 0, "time_offset_us": 0}
    assert "has 3 events" in check["skipped"]
    assert result.meta["input_events"] == 6


def test_prefix_is_held_then_the_rest_streams_once(patches):
    # The source is pulled once, packet by packet: the first packet reaches the matcher after the prefix's
    # packets and before the rest is read, and every packet comes through unchanged (an aligned rig).
    packets = list(iter_stereo_packets(patches.left, patches.right, 40_000))
    pulled = []

    def source():
        for i, p in enumerate(packets):
            pulled.append(i)
            yield p

    nothing = RigCheckParams(time_apply_confidence=2.0)          # with the two below: nothing applied
    check = PrefixRigCheck((128, 128), min_us=100_000, min_events=10, max_us=200_000, params=nothing,
                           row_min_confidence=2.0, swap_min_confidence=2.0)
    out = check.stream(source())
    first = next(out)
    prefix_packets = len(pulled)
    assert prefix_packets == 100_000 // 40_000 + 1 < len(packets)
    rest = [first, *out]
    assert pulled == list(range(len(packets)))                      # each read once, in order
    assert len(rest) == len(packets)
    for a, b in zip(rest, packets, strict=True):
        assert a.until == b.until and np.array_equal(a.left, b.left) and np.array_equal(a.right, b.right)
    assert check.describe()["prefix_us"] == prefix_packets * 40_000 - int(packets[0].left["t"].min())


def test_match_of_an_opened_file_streams_without_a_whole_read(patches, tmp_path, monkeypatch):
    from cvstereo.io import open_recording, read_recording, write_recording
    from cvstereo.io.stream import RecordingStream

    path = tmp_path / "p.npz"
    write_recording(path, with_rig_errors(patches, rows=2))
    in_memory = match(read_recording(path), method=METHOD)
    monkeypatch.setattr(RecordingStream, "read", lambda self: pytest.fail("the stream was read whole"))
    streamed = match(open_recording(path), method=METHOD)
    assert streamed.meta["rigcheck"]["applied"] == in_memory.meta["rigcheck"]["applied"]
    assert np.array_equal(streamed.matches, in_memory.matches)


def test_swapped_packet_negates_truth():
    from cvstereo.model.events import make_events
    from cvstereo.rigcheck.prefix import swapped_packet

    a, b = make_events([1], [2], [3], [1]), make_events([4], [5], [6], [0])
    p = swapped_packet(StereoPacket(a, b, 10, np.array([2.0], np.float32), None))
    assert p.left is b and p.right is a and p.until == 10
    assert p.left_disparity is None and p.right_disparity.tolist() == [-2.0]


def test_as_matched_follows_a_swap_of_the_prefix_check(patches):
    from cvstereo.geometry.source import as_matched

    swapped = with_rig_errors(patches, swap=True)
    result = match(swapped, method=METHOD)
    assert result.meta["rigcheck"]["applied"]["swap"] is True
    back = as_matched(swapped, result.meta)
    assert np.array_equal(back.left, patches.left)


def test_simulated_arm_swap_and_rows_found_on_the_prefix():
    # The simulator's rig puts the right camera's image vertical_offset_px rows low: the clean clip is matched
    # with that correction, the shifted one with it plus the shift, and they must agree.
    from cvstereo.io import read_recording
    from cvstereo.simulate import cached_preset

    full = read_recording(cached_preset("1arm-100cm", seconds=1.5))   # cached by test_rigcheck.py
    rec = full.slice_time(full.t_start, full.t_start + 700_000)
    own = -round(rec.meta["rig"]["vertical_offset_px"])
    aligned = match(rec, method=METHOD)
    assert aligned.meta["rigcheck"]["applied"]["row_offset"] == own
    shifted = match(with_rig_errors(rec, rows=3, swap=True), method=METHOD)
    applied = shifted.meta["rigcheck"]["applied"]
    assert applied["swap"] is True and applied["row_offset"] == own - 3
    assert shifted.meta["rigcheck"]["prefix_us"] < 650_000            # a prefix, not the whole clip
    want, got = _corrected_keys(aligned), _corrected_keys(shifted)
    assert len(want & got) >= MATCH_SHARE * len(want)


def test_evaluate_scores_a_swapped_run_on_the_cameras_it_used():
    # cvs.evaluate(recording, cvs.match(recording)) on a rig wired the wrong way round: the check swaps the cameras
    # before matching, and scoring must follow (given the recording as read, or already in the matches' order),
    # giving the figures of the correctly wired recording; scored the other way, every truth is negated.
    from cvstereo.evaluation.metrics import evaluate
    from cvstereo.geometry.source import as_matched
    from cvstereo.io import read_recording
    from cvstereo.simulate import cached_preset

    full = read_recording(cached_preset("1arm-100cm", seconds=1.5))   # cached by test_rigcheck.py
    rec = full.slice_time(full.t_start, full.t_start + 700_000)
    wired = evaluate(rec, match(rec, method=METHOD))
    swapped = rec.swapped()   # truth kept (negated, x_left - x_right of the swapped order)
    result = match(swapped, method=METHOD)
    assert result.meta["rigcheck"]["applied"]["swap"] is True
    as_read = evaluate(swapped, result)
    assert as_read == evaluate(as_matched(swapped, result.meta), result)
    assert wired["bad2"] < 0.2 and abs(as_read["bad2"] - wired["bad2"]) < 0.02
    assert abs(as_read["coverage"] - wired["coverage"]) < 0.02


@pytest.mark.parametrize(("swap", "rows"), [(False, 0), (True, 0), (True, 2)])
def test_side_by_matching_tells_the_order_where_the_overlay_is_not_trusted(patches, swap, rows):
    # A swap threshold no overlay confidence reaches hands every decision to the matcher's answers in both orders.
    check = PrefixRigCheck(patches.resolution, swap_min_confidence=1.01)
    list(check.stream(with_rig_errors(patches, rows=rows, swap=swap).packets(40_000)))
    found = check.describe()
    assert found["applied"]["swap"] is swap and found["applied"]["row_offset"] == -rows
    side = found["side_by_matching"]
    right_order, wrong_order = (side["exchanged"], side["given"]) if swap else (side["given"], side["exchanged"])
    assert right_order >= 3 * wrong_order > 0
    assert 0 < side["seconds"] <= found["seconds"]  # its two runs are part of the check's own time


def test_side_by_matching_is_not_run_where_the_overlay_is_sure(patches):
    result = match(with_rig_errors(patches, swap=True), method=METHOD)
    check = result.meta["rigcheck"]
    assert check["swap_confidence"] >= 0.8 and check["applied"]["swap"] is True
    assert check["side_by_matching"] is None
