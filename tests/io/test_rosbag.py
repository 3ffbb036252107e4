"""ROS 1 and ROS 2 bags of ``dvs_msgs/EventArray`` and ``event_camera_msgs/EventPacket`` messages.

The bags' containers come from rosbags' writers; every message's bytes are packed by hand from the published
definitions (tests/_rosbag_files.py), EVT 3.0 payloads word by word (tests/_prophesee_files.py). A stereo bag
reads back event for event and matches exactly as the same events from ``.npz``.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from cvstereo.errors import MissingExtraError
from cvstereo.io import detect_format, open_recording, read_matches, read_recording, write_recording
from cvstereo.model.recording import Recording
from tests._hostile import run_cli
from tests._io_helpers import textured_blobs
from tests._prophesee_files import scene_events
from tests._rosbag_files import ARRAY, PACKET, event_array, event_packet, evt3_packets, mono_words, split, write_bag

pytest.importorskip("rosbags")
pytest.importorskip("evt3")

WIDTH, HEIGHT = 128, 128
#: A ROS time (1.7e9 s after 1970) in microseconds: dvs_msgs events carry the host's wall clock.
ROS_EPOCH_US = 1_700_000_000 * 10**6
CONTAINERS = {"ros1": {"ros2": False}, "ros2-sqlite3": {"ros2": True, "storage": "sqlite3"},
              "ros2-mcap": {"ros2": True, "storage": "mcap"}}


def _sensor_order(events: np.ndarray) -> np.ndarray:
    """Events in the order an EVT 3.0 sensor sends them within one microsecond (row, polarity, x)."""
    return events[np.lexsort((events["x"], events["p"], events["y"], events["t"]))]


@pytest.fixture(scope="module")
def blobs() -> Recording:
    rec = textured_blobs(4)
    return Recording(_sensor_order(rec.left), _sensor_order(rec.right), None, None, rec.resolution, {})


def _messages(events: np.ndarray, kind: str, cdr: bool, parts: int) -> tuple[str, list[bytes]]:
    """One camera's events as ``parts`` messages of ``kind`` (``dvs`` or ``evt3``)."""
    if kind == "dvs":
        return ARRAY, [event_array(e, WIDTH, HEIGHT, cdr=cdr, seq=i) for i, e in enumerate(split(events, parts))]
    size = 2 * len(events)  # EVT 3.0 has at least one 16-bit word per event: cut at odd bytes across the stream
    packets = evt3_packets(events, [size * k // parts + 1 for k in range(1, parts)])
    return PACKET, [event_packet(p, WIDTH, HEIGHT, cdr=cdr, seq=i) for i, p in enumerate(packets)]


def _stereo_bag(path, rec: Recording, kind: str, container: str, topics=("/dvs/left/events", "/dvs/right/events")):
    options = CONTAINERS[container]
    cdr = options["ros2"]
    return write_bag(path, {topics[0]: _messages(rec.left, kind, cdr, 7),
                            topics[1]: _messages(rec.right, kind, cdr, 5)}, **options)


def _shifted(rec: Recording, offset: int) -> Recording:
    left, right = rec.left.copy(), rec.right.copy()
    left["t"] += offset
    right["t"] += offset
    return Recording(left, right, None, None, rec.resolution, {})


@pytest.mark.parametrize("container", CONTAINERS)
@pytest.mark.parametrize("kind", ["dvs", "evt3"])
def test_stereo_bag_reads_back_and_matches_like_npz(tmp_path, blobs, kind, container, monkeypatch):
    """dvs_msgs events carry ROS times (1.7e9 s); EVT 3.0 packets the sensor's microseconds."""
    rec = _shifted(blobs, ROS_EPOCH_US) if kind == "dvs" else blobs
    bag = _stereo_bag(tmp_path / ("rec.bag" if container == "ros1" else "rec"), rec, kind, container)
    assert detect_format(bag) == "rosbag"
    got = read_recording(bag)
    for cam in ("left", "right"):
        np.testing.assert_array_equal(getattr(got, cam), getattr(rec, cam))
    assert got.resolution == (WIDTH, HEIGHT)
    assert got.meta["topics"] == ["/dvs/left/events", "/dvs/right/events"]
    assert got.meta["ros"] == (1 if container == "ros1" else 2)
    write_recording(tmp_path / "same.npz", rec)
    monkeypatch.chdir(tmp_path)
    assert run_cli(["match", str(bag), "-o", "a.npz"]) == (0, "")
    assert run_cli(["match", "same.npz", "-o", "b.npz"]) == (0, "")
    a, b = read_matches(tmp_path / "a.npz"), read_matches(tmp_path / "b.npz")
    assert a.matches.size > 0
    np.testing.assert_array_equal(a.matches, b.matches)


def test_streamed_message_by_message(tmp_path, blobs):
    """One chunk per message that holds events (an empty message gives none); the stream walks twice."""
    left = blobs.left
    messages = [left[:10], left[:0], left[10:500], left[500:]]
    bag = write_bag(tmp_path / "s.bag", {
        "/left": (ARRAY, [event_array(e, WIDTH, HEIGHT, cdr=False) for e in messages]),
        "/right": (ARRAY, [event_array(blobs.right, WIDTH, HEIGHT, cdr=False)])}, ros2=False)
    stream = open_recording(bag)
    for _ in range(2):
        chunks = [c for c, _ in stream.chunks("left")]
        assert [len(c) for c in chunks] == [10, 490, len(left) - 500]
        np.testing.assert_array_equal(np.concatenate(chunks), left)


def test_evt3_clock_wraps_across_packets(tmp_path):
    """More than 2**24 us: the EVT 3.0 clock (24 bits) wraps twice, and the packets cut words and TIME_HIGH runs
    anywhere, so the decoder's state must carry from packet to packet."""
    events = scene_events(3000, 640, 480, seed=3)
    events["t"] = events["t"] * 20
    assert events["t"][-1] > 2 * 2**24
    packets = evt3_packets(events, list(range(1, 2 * len(events), 301)))
    bag = write_bag(tmp_path / "w", {
        "/cam0/events": (PACKET, [event_packet(p, 640, 480, cdr=True) for p in packets]),
        "/cam1/events": (PACKET, [event_packet(p, 640, 480, cdr=True) for p in packets[:3]])},
        ros2=True, storage="mcap")
    got = open_recording(bag)
    assert got.resolution == (640, 480) and got.meta["topics"] == ["/cam0/events", "/cam1/events"]
    np.testing.assert_array_equal(got.read_camera("left")[0], events)


def test_mono_packets_trigger_topics_and_no_embedded_definitions(tmp_path, blobs):
    """``mono`` packets (time_base + dt in ns), a third event topic of trigger packets that ``topics`` leaves out,
    and a ROS 2 bag that embeds no message definitions (the registered ones are used)."""
    rec = _shifted(blobs, ROS_EPOCH_US)

    def mono(events):
        out = []
        for e in split(events, 4):
            base = int(e["t"][0]) * 1000 - 12_345  # time_base need not be an event's time
            out.append(event_packet(mono_words(e, base), WIDTH, HEIGHT, cdr=True, encoding="mono", time_base=base))
        return out

    trigger = event_packet(b"\x00" * 8, WIDTH, HEIGHT, cdr=True, encoding="trigger")
    bag = write_bag(tmp_path / "m", {"/a/events": (PACKET, mono(rec.left)), "/b/events": (PACKET, mono(rec.right)),
                                     "/a/trigger": (PACKET, [trigger])}, ros2=True, definitions=False)
    with pytest.raises(ValueError, match=r"3 event topics.*--topics"):
        open_recording(bag)
    got = read_recording(bag, topics="/a/events,/b/events")
    np.testing.assert_array_equal(got.left, rec.left)
    np.testing.assert_array_equal(got.right, rec.right)
    swapped = read_recording(bag, topics=("/b/events", "/a/events"))
    np.testing.assert_array_equal(swapped.left, rec.right)
    # the trigger topic holds packets but no change events: a camera with none
    assert len(read_recording(bag, topics="/a/events,/a/trigger").right) == 0


def test_cli_topics_option(tmp_path, blobs, monkeypatch):
    _stereo_bag(tmp_path / "t.bag", blobs, "dvs", "ros1", topics=("/x/events", "/y/events"))
    monkeypatch.chdir(tmp_path)
    assert run_cli(["match", "t.bag", "--topics", "/x/events,/y/events", "-o", "a.npz"]) == (0, "")
    write_recording(tmp_path / "same.npz", blobs)
    assert run_cli(["match", "same.npz", "-o", "b.npz"]) == (0, "")
    np.testing.assert_array_equal(read_matches(tmp_path / "a.npz").matches, read_matches(tmp_path / "b.npz").matches)


def test_missing_rosbags_names_the_extra(tmp_path, blobs, monkeypatch):
    bag = _stereo_bag(tmp_path / "x.bag", blobs, "dvs", "ros1")
    for name in [m for m in sys.modules if m == "rosbags" or m.startswith("rosbags.")]:
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(MissingExtraError, match=r"cvstereo\[ros\]"):
        open_recording(bag)
