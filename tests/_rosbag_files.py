"""ROS bags of event messages for the reader's tests: the container from rosbags' writers, every message's bytes
packed here by hand from the published definitions (not by rosbags' serializer).

``dvs_msgs/EventArray``: ``Header header, uint32 height, uint32 width, Event[] events`` with ``Event``:
``uint16 x, uint16 y, time ts, bool polarity``. ``event_camera_msgs/EventPacket``: ``Header header, uint32 height,
uint32 width, uint64 seq, uint64 time_base, string encoding, bool is_bigendian, uint8[] events``.

ROS 1 serialisation: fields packed little-endian without padding; ``Header`` is ``uint32 seq, time stamp,
string frame_id``; ``time`` is ``uint32 sec, uint32 nsec``; strings and arrays are preceded by a ``uint32``
length. ROS 2 (CDR, little-endian): a 4-byte encapsulation header ``00 01 00 00``, then every primitive aligned to
its size counted from after that header; ``Header`` is ``int32 sec, uint32 nanosec, string frame_id``; strings
carry their terminating NUL in their ``uint32`` length.
"""

from __future__ import annotations

import functools
import itertools
import struct

import numpy as np

from tests._prophesee_files import evt3_words

MSG_TEXT = {
    "dvs_msgs/msg/Event": "uint16 x\nuint16 y\ntime ts\nbool polarity\n",
    "dvs_msgs/msg/EventArray": "Header header\nuint32 height\nuint32 width\nEvent[] events\n",
    "event_camera_msgs/msg/EventPacket": ("Header header\nuint32 height\nuint32 width\nuint64 seq\nuint64 time_base\n"
                                          "string encoding\nbool is_bigendian\nuint8[] events\n"),
}
ARRAY, PACKET = "dvs_msgs/msg/EventArray", "event_camera_msgs/msg/EventPacket"
FRAME_ID = "camera"


class Packer:
    """Little-endian fields; ``cdr`` aligns each primitive to its size, counted after the 4-byte header."""

    def __init__(self, cdr: bool):
        self.cdr = cdr
        self.out = bytearray(b"\x00\x01\x00\x00" if cdr else b"")

    def put(self, fmt: str, *values) -> None:
        if self.cdr:
            size = struct.calcsize("<" + fmt[0])
            self.out += b"\x00" * (-(len(self.out) - 4) % size)
        self.out += struct.pack("<" + fmt, *values)

    def string(self, text: str) -> None:
        data = text.encode() + (b"\x00" if self.cdr else b"")
        self.put("I", len(data))
        self.out += data

    def header(self, seq: int, stamp_ns: int, frame_id: str = FRAME_ID) -> None:
        if not self.cdr:
            self.put("I", seq)
        self.put("i" if self.cdr else "I", stamp_ns // 10**9)
        self.put("I", stamp_ns % 10**9)
        self.string(frame_id)


def event_array(events: np.ndarray, width: int, height: int, *, cdr: bool, seq: int = 0,
                frame_id: str = FRAME_ID) -> bytes:
    """One ``dvs_msgs/EventArray`` of ``events`` (times in microseconds), the header stamped with the first time."""
    pack = Packer(cdr)
    pack.header(seq, int(events["t"][0]) * 1000 if len(events) else 0, frame_id)
    pack.put("I", height)
    pack.put("I", width)
    pack.put("I", len(events))
    for e in events:
        pack.put("H", int(e["x"]))
        pack.put("H", int(e["y"]))
        ns = int(e["t"]) * 1000
        pack.put("i" if cdr else "I", ns // 10**9)
        pack.put("I", ns % 10**9)
        pack.put("B", int(e["p"]))
    return bytes(pack.out)


def event_packet(payload: bytes, width: int, height: int, *, cdr: bool, encoding: str = "evt3", seq: int = 0,
                 time_base: int = 0, big_endian: bool = False) -> bytes:
    """One ``event_camera_msgs/EventPacket`` holding ``payload`` in ``encoding``."""
    pack = Packer(cdr)
    pack.header(seq, 0)
    pack.put("I", height)
    pack.put("I", width)
    pack.put("Q", seq)
    pack.put("Q", time_base)
    pack.string(encoding)
    pack.put("B", int(big_endian))
    pack.put("I", len(payload))
    pack.out += payload
    return bytes(pack.out)


def mono_words(events: np.ndarray, time_base_ns: int) -> bytes:
    """The ``mono`` encoding: polarity in bit 63, y in 62..48, x in 47..32, ``t - time_base`` (ns) in 31..0."""
    words = [int(e["p"]) << 63 | int(e["y"]) << 48 | int(e["x"]) << 32 | (int(e["t"]) * 1000 - time_base_ns)
             for e in events]
    return np.array(words, "<u8").tobytes()


def evt3_packets(events: np.ndarray, cuts: list[int]) -> list[bytes]:
    """A camera's EVT 3.0 stream cut into packets at the byte offsets ``cuts`` (anywhere, as a driver cuts)."""
    data = evt3_words(events).tobytes()
    bounds = [0, *[c for c in cuts if 0 < c < len(data)], len(data)]
    return [data[a:b] for a, b in itertools.pairwise(bounds)]


def split(events: np.ndarray, parts: int) -> list[np.ndarray]:
    """``events`` in ``parts`` consecutive messages (some may be empty)."""
    return np.array_split(events, parts)


@functools.lru_cache(maxsize=2)
def test_typestore(ros2: bool):
    """rosbags' store of the ROS distribution with the event types registered from :data:`MSG_TEXT` (for the
    connections' definitions only: the payloads never pass through it)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
    for name, text in MSG_TEXT.items():
        store.register(get_types_from_msg(text, name))
    return store


test_typestore.__test__ = False


def write_bag(path, topics: dict[str, tuple[str, list[bytes]]], *, ros2: bool, storage: str = "sqlite3",
              definitions: bool = True, stamps: dict[str, list[int]] | None = None):
    """A bag at ``path`` holding, per topic, ``(msgtype, payloads)`` in order; a ROS 2 bag in ``storage``
    (``sqlite3`` or ``mcap``), with the message definitions embedded unless ``definitions`` is False. Record
    times are 1 ms apart, topics interleaved, unless ``stamps`` gives them (ns) per topic."""
    store = test_typestore(ros2)
    if ros2:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer = Writer(path, version=9, storage_plugin=StoragePlugin[storage.upper()])
    else:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
    with writer:
        connections = {}
        for topic, (msgtype, _) in topics.items():
            if definitions or not ros2:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            else:
                connections[topic] = writer.add_connection(topic, msgtype, msgdef="", rihs01="RIHS01_" + "0" * 64)
        records = []
        for k, (topic, (_, payloads)) in enumerate(topics.items()):
            times = (stamps or {}).get(topic) or [1_000_000 * (i + 1) + k for i in range(len(payloads))]
            records += [(stamp, topic, data) for stamp, data in zip(times, payloads, strict=True)]
        for stamp, topic, data in sorted(records, key=lambda r: r[0]):
            writer.write(connections[topic], stamp, data)
    return path
