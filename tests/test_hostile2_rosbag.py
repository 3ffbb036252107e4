"""Hostile ROS bags (issues 26 and 27): every damaged or unsuitable bag ends in one line naming the bag and saying
what is wrong; good bags of every container read whole.

The bags are written with rosbags' writers around message bytes packed by hand (tests/_rosbag_files.py): a ROS 1
``.bag``, ROS 2 folders in sqlite3 and MCAP storage, 2,000 ``dvs_msgs`` events per camera on a 128x128 sensor.
Then they are spoilt as bags are in practice: cut short (a recording killed), random bytes named ``.bag``, a
topic name mistyped, no event topics at all, one camera only, three event topics, a message whose bytes were
damaged, a message of another sensor size, an MCAP file named ``.dat``, events that go back in time from one
message to the next, a folder without its ``metadata.yaml``.

Failures say their kind (``tests/_hostile.py``), so that ``bench/hostile_tally.py`` tallies old and new code.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests._hostile import case, check_case
from tests._hostile_calls import working_copy
from tests._prophesee_files import scene_events
from tests._rosbag_files import ARRAY, event_array, split, write_bag

pytest.importorskip("rosbags")

pytestmark = pytest.mark.timeout(60)

N = 2000
W = H = 128
LEFT, RIGHT = scene_events(N, W, H, seed=7), scene_events(N, W, H, seed=8)
TOPICS = ("/dvs/left/events", "/dvs/right/events")


def _array_messages(events, *, cdr: bool, parts: int = 4, size=(W, H)) -> tuple[str, list[bytes]]:
    return ARRAY, [event_array(e, *size, cdr=cdr) for e in split(events, parts)]


def _stereo(path, *, ros2: bool, storage: str = "sqlite3", left=None, right=None, extra=None):
    topics = {TOPICS[0]: left or _array_messages(LEFT, cdr=ros2), TOPICS[1]: right or _array_messages(RIGHT, cdr=ros2),
              **(extra or {})}
    return write_bag(path, topics, ros2=ros2, storage=storage)


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("rosbag")
    _stereo(d / "good.bag", ros2=False)
    _stereo(d / "good2", ros2=True)
    _stereo(d / "goodmcap", ros2=True, storage="mcap")
    data = (d / "good.bag").read_bytes()
    (d / "cut.bag").write_bytes(data[: len(data) // 2])
    (d / "garbage.bag").write_bytes(np.random.default_rng(3).integers(0, 256, 5000, np.uint8).tobytes())
    (d / "empty.bag").write_bytes(b"")
    (d / "storage.dat").write_bytes((d / "goodmcap" / "goodmcap.mcap").read_bytes())
    _stereo(d / "cut2", ros2=True)
    db3 = d / "cut2" / "cut2.db3"
    db3.write_bytes(db3.read_bytes()[:3000])
    _stereo(d / "nometa", ros2=True)
    (d / "nometa" / "metadata.yaml").unlink()
    write_bag(d / "strings.bag", {"/chatter": ("std_msgs/msg/String", [b"\x05\x00\x00\x00hello"])}, ros2=False)
    write_bag(d / "one.bag", {TOPICS[0]: _array_messages(LEFT, cdr=False)}, ros2=False)
    write_bag(d / "unnamed.bag", {"/dvs/events": _array_messages(LEFT, cdr=False),
                                  "/dvs2/events": _array_messages(RIGHT, cdr=False)}, ros2=False)
    _stereo(d / "three.bag", ros2=False, extra={"/dvs/left/events_raw": _array_messages(LEFT, cdr=False)})
    # A message whose events count says more than its bytes hold (bytes lost in the middle of a message).
    kind, messages = _array_messages(LEFT, cdr=False)
    damaged = bytearray(messages[2])
    damaged[-5 * 13:] = b""
    _stereo(d / "damaged.bag", ros2=False, left=(kind, [*messages[:2], bytes(damaged), *messages[3:]]))
    # CDR: the encapsulation header overwritten (a ROS 2 message that is not CDR).
    kind, messages = _array_messages(RIGHT, cdr=True)
    _stereo(d / "notcdr", ros2=True, right=(kind, [messages[0], b"\xff\xff" + messages[1][2:], *messages[2:]]))
    # The third message of the left camera says 640x480.
    kind, messages = _array_messages(LEFT, cdr=False)
    other = event_array(split(LEFT, 4)[2], 640, 480, cdr=False)
    _stereo(d / "resize.bag", ros2=False, left=(kind, [*messages[:2], other, *messages[3:]]))
    # The right camera's second and third messages swapped: its events go back in time at message 2.
    kind, messages = _array_messages(RIGHT, cdr=False)
    _stereo(d / "unsorted.bag", ros2=False, left=None,
            right=(kind, [messages[0], messages[2], messages[1], messages[3]]))
    # An event outside the sensor (x 200 on a 128x128 sensor the messages state).
    outside = LEFT.copy()
    outside["x"][1500] = 200
    _stereo(d / "outside.bag", ros2=False, left=_array_messages(outside, cdr=False))
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    return working_copy(base, tmp_path, monkeypatch)


CASES = {
    # --- good bags: every event read, topics found by name -------------------------------------------------
    "reads-ros1": case("info good.bag", 0, out=(f"{N:,}", "/dvs/left/events")),
    "reads-ros2-sqlite3-folder": case("info good2", 0, out=f"{N:,}"),
    "reads-ros2-mcap-folder": case("info goodmcap", 0, out=f"{N:,}"),
    "reads-ros2-db3-file": case("info good2/good2.db3", 0, out=f"{N:,}"),
    "matches-ros1": case("match good.bag -o m.npz", 0, writes="m.npz"),
    "topics-named": case("info unnamed.bag --topics /dvs/events,/dvs2/events", 0, out=f"{N:,}"),
    # --- not a bag, or not a whole one -----------------------------------------------------------------------
    "cut-ros1": case("info cut.bag", 1, ("cut.bag", "ROS bag")),
    "garbage-named-bag": case("info garbage.bag", 1, ("garbage.bag", "not a ROS bag")),
    "empty-bag": case("info empty.bag", 1, ("empty.bag", "ROS bag")),
    "mcap-under-another-name": case("info storage.dat", 1, ("storage.dat", ".mcap")),
    "cut-ros2-db3": case("info cut2", 1, ("cut2", "ROS bag")),
    "folder-without-metadata": case("info nometa", 1, ("nometa", "metadata.yaml")),
    "match-cut-leaves-nothing": case("match cut.bag -o m.npz", 1, ("cut.bag",), absent="m.npz"),
    # --- topics ----------------------------------------------------------------------------------------------
    "wrong-topic": case("info good.bag --topics /dvs/left/events,/dvs/rihgt/events", 1,
                        ("good.bag", "/dvs/rihgt/events", "not in the bag", "/dvs/right/events")),
    "topic-not-events": case("info strings.bag --topics /chatter,/chatter2", 1, ("strings.bag", "/chatter")),
    "topics-one-name": case("info good.bag --topics /dvs/left/events", 1, ("--topics", "comma")),
    "no-event-topics": case("info strings.bag", 1, ("strings.bag", "no topic of event messages", "/chatter")),
    "one-camera-only": case("info one.bag", 1, ("one.bag", "one event topic only", "--topics")),
    "names-say-no-side": case("info unnamed.bag", 1, ("unnamed.bag", "left/right", "/dvs2/events", "--topics")),
    "three-event-topics": case("info three.bag", 1, ("three.bag", "3 event topics", "--topics")),
    "topics-on-npz": case("info m.npz --topics a,b", 1, ("topics", "npz")),
    # --- damaged messages ------------------------------------------------------------------------------------
    "damaged-payload": case("info damaged.bag", 1, ("damaged.bag", "/dvs/left/events", "message 2")),
    "not-cdr": case("info notcdr", 1, ("notcdr", "/dvs/right/events", "message 1")),
    "size-changes": case("info resize.bag", 1, ("resize.bag", "message 2", "640x480")),
    "unsorted-stamps": case("info unsorted.bag", 1, ("unsorted.bag", "/dvs/right/events", "earlier", "message 2")),
    "event-outside-sensor": case("info outside.bag", 1, ("outside.bag", "/dvs/left/events", "200")),
    "resolution-contradicts": case("info good.bag --resolution 640x480", 1, ("good.bag", "128x128")),
}


@pytest.mark.parametrize("name", CASES)
def test_hostile_rosbag(name, work, capsys):
    if name == "topics-on-npz":
        from cvstereo.io import write_recording
        from cvstereo.model.recording import Recording

        write_recording(work / "m.npz", Recording(LEFT, RIGHT, resolution=(W, H)))
    check_case(CASES[name], work, capsys)
