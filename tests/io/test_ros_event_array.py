"""``dvs_msgs/EventArray`` decoded from its bytes by numpy (cvstereo.io._ros_event_array): the same events as
rosbags' own decoding of messages packed by hand (tests/_rosbag_files.py) in both serialisations, for every
alignment of the event sequence; bytes that are not exactly the published message are left to rosbags; a bag
whose ``Event`` differs from the published one (the same size, fields in another order) is read through rosbags,
right."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.io import read_recording
from cvstereo.io._ros_event_array import parse_event_array, same_event_array
from cvstereo.model.events import make_events
from tests._rosbag_files import ARRAY, event_array, test_typestore

pytest.importorskip("rosbags")


def _events(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = 1_700_000_000 * 10**6 + np.sort(rng.integers(0, 3_000_000, n))  # crosses whole seconds
    return make_events(t, rng.integers(0, 346, n), rng.integers(0, 260, n), rng.integers(0, 2, n))


@pytest.mark.parametrize("cdr", [False, True], ids=["ros1", "ros2-cdr"])
@pytest.mark.parametrize("frame_id", ["", "a", "ab", "abc", "camera"])  # every offset of the events mod 4
@pytest.mark.parametrize("n", [0, 1, 2, 3, 57])
def test_the_bytes_decode_to_rosbags_events(cdr, frame_id, n):
    ev = _events(n)
    raw = event_array(ev, 346, 260, cdr=cdr, frame_id=frame_id)
    fast = parse_event_array(raw, cdr)
    store = test_typestore(cdr)
    message = (store.deserialize_cdr if cdr else store.deserialize_ros1)(raw, ARRAY)
    assert fast is not None and (fast.width, fast.height) == (346, 260)
    assert same_event_array(fast, message)
    # and against the events packed, independently of rosbags
    np.testing.assert_array_equal(fast.events["x"], ev["x"])
    np.testing.assert_array_equal(fast.events["y"], ev["y"])
    np.testing.assert_array_equal(fast.events["sec"] * 10**6 + fast.events["nsec"] // 1000, ev["t"])
    np.testing.assert_array_equal(fast.events["polarity"], ev["p"])


@pytest.mark.parametrize("cdr", [False, True], ids=["ros1", "ros2-cdr"])
def test_bytes_that_are_not_the_message_are_left_to_rosbags(cdr):
    raw = event_array(_events(5), 346, 260, cdr=cdr)
    assert parse_event_array(raw[:-1], cdr) is None  # truncated
    assert parse_event_array(raw + b"\x00" * 16, cdr) is None  # trailing bytes beyond the alignment
    assert parse_event_array(b"", cdr) is None
    if cdr:
        assert parse_event_array(raw[:1] + b"\x00" + raw[2:], cdr) is None  # big-endian CDR


def test_a_bag_whose_event_type_differs_is_read_through_rosbags(tmp_path):
    """``Event`` with y before x: same size, so the byte decoder would swap them; the first message's check
    against rosbags' decoding keeps the topic on rosbags."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("uint16 y\nuint16 x\ntime ts\nbool polarity\n", "dvs_msgs/msg/Event"))
    store.register(get_types_from_msg("Header header\nuint32 height\nuint32 width\nEvent[] events\n", ARRAY))
    left, right = _events(40, 1), _events(40, 2)
    path = tmp_path / "swapped.bag"
    with Writer(path) as writer:
        for k, (topic, ev) in enumerate((("/cam0/events", left), ("/cam1/events", right))):
            conn = writer.add_connection(topic, ARRAY, typestore=store)
            swapped = ev.copy()
            swapped["x"], swapped["y"] = ev["y"], ev["x"]  # packed in the published order: x field holds y
            for i in range(0, 40, 20):
                writer.write(conn, 10**9 * (i + 1) + k, event_array(swapped[i:i + 20], 346, 260, cdr=False))
    rec = read_recording(path)
    assert rec.resolution == (346, 260)
    np.testing.assert_array_equal(rec.left, left)
    np.testing.assert_array_equal(rec.right, right)
