"""The ROS event messages cvstereo reads, their definitions, and the decoding of one message into event columns.

``dvs_msgs/EventArray`` (the rpg_dvs_ros driver's message, most robotics datasets) holds one ``Event`` (x, y,
ts, polarity) per event, ``ts`` a ROS time; ``event_camera_msgs/EventPacket`` (the ros-event-camera drivers)
holds the sensor's own bytes in an ``encoding``: ``evt3`` (Prophesee EVT 3.0, decoded by the ``evt3`` package
as for ``.raw`` files), ``mono`` (64-bit words: polarity in bit 63, y in 62..48, x in 47..32, ``dt`` in 31..0,
the time ``time_base + dt`` in nanoseconds) or ``trigger`` (external triggers, no events). Neither package is
in rosbags' type store: the definitions are registered here from their ``.msg`` text, so that bags that do not
embed them (older ROS 2 bags) are read too; a bag's own definitions take precedence.
"""

from __future__ import annotations

import functools

import numpy as np

from cvstereo.errors import CorruptFileError, MissingExtraError

__all__ = ["EVENT_ARRAY", "EVENT_PACKET", "EVENT_TYPES", "PacketDecoder", "import_rosbags", "typestore"]

EVENT_ARRAY = "dvs_msgs/msg/EventArray"
EVENT_PACKET = "event_camera_msgs/msg/EventPacket"
#: The ``.msg`` text of each type (as the packages publish them; ``Header`` and ``time`` are ROS 1's names,
#: which rosbags maps to ``std_msgs/msg/Header`` and ``builtin_interfaces/msg/Time`` for either ROS).
DEFINITIONS = {
    "dvs_msgs/msg/Event": "uint16 x\nuint16 y\ntime ts\nbool polarity\n",
    EVENT_ARRAY: "Header header\nuint32 height\nuint32 width\nEvent[] events\n",
    EVENT_PACKET: ("Header header\nuint32 height\nuint32 width\nuint64 seq\nuint64 time_base\nstring encoding\n"
                   "bool is_bigendian\nuint8[] events\n"),
}
#: The message types that carry events.
EVENT_TYPES = (EVENT_ARRAY, EVENT_PACKET)
#: ``event_camera_msgs`` encodings read, and those that carry no change events (skipped).
PACKET_ENCODINGS = ("evt3", "mono")
NO_EVENT_ENCODINGS = ("trigger",)
NS_PER_US = 1_000
US_PER_S = 1_000_000
NS_PER_S = 1_000_000_000


def import_rosbags():
    """The ``rosbags`` package, or an error naming the extra that installs it."""
    try:
        import rosbags.rosbag1
        import rosbags.rosbag2
        import rosbags.typesys

        return rosbags
    except ImportError as exc:
        raise MissingExtraError("reading ROS bags needs the package 'rosbags': pip install 'cvstereo[ros]'") from exc


def _bag_types(definitions: tuple) -> dict:
    """The types a bag defines, from its ``(msgtype, format, text)`` definitions (ROS 1 bags always embed them,
    ROS 2 bags from rosbag2 9 on)."""
    rosbags = import_rosbags()
    types: dict = {}
    for msgtype, form, text in definitions:
        if form == "MSG" and text:
            types.update(rosbags.typesys.get_types_from_msg(text, msgtype))
        elif form == "IDL" and text:
            separator = "=" * 80 + "\n"
            parts = text.split(separator)[1:] if text.startswith(separator) else ["IDL: \n" + text]
            for part in parts:
                types.update(rosbags.typesys.get_types_from_idl(part.split("\n", 1)[1]))
    return types


def typestore(connections, ros2: bool):
    """A rosbags type store for a bag's ``connections``: the event types of :data:`DEFINITIONS`, what the bag
    itself defines (which wins where they differ), and the ROS distribution's standard types they refer to."""
    definitions = tuple(sorted({(c.msgtype, c.msgdef.format.name, c.msgdef.data) for c in connections}))
    return _cached_typestore(definitions, ros2)


@functools.lru_cache(maxsize=8)
def _cached_typestore(definitions: tuple, ros2: bool):
    # Cached by the definitions: a stream opens the bag once per camera and per look at its sizes, and building a
    # store generates code for each type.
    import_rosbags()
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    types: dict = {}
    for name, text in DEFINITIONS.items():
        types.update(get_types_from_msg(text, name))
    types.update(_bag_types(definitions))
    standard = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC).fielddefs
    missing = [name for name in types]
    while missing:  # only the standard types referred to: registering all of them takes far longer
        for ref in _references(types[missing.pop()]):
            if ref not in types and ref in standard:
                types[ref] = standard[ref]
                missing.append(ref)
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    return store


def _references(fielddef) -> list[str]:
    """The message types a rosbags field definition ``(constants, fields)`` refers to."""
    from rosbags.typesys.base import Nodetype

    refs = []
    for _, (node, detail) in fielddef[1]:
        if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            node, detail = detail[0]
        if node == Nodetype.NAME:
            refs.append(detail)
    return refs


class PacketDecoder:
    """Decode one topic's messages, in bag order, into ``(t, x, y, p)`` columns (t in microseconds).

    One decoder per camera: EVT 3.0 keeps its state (the time's high bits, the current row) from one packet to
    the next, as a sensor's stream is cut into packets anywhere.

    Parameters
    ----------
    source : str
        Named in errors (``"bag [topic /dvs/left]"``).
    resolution : (width, height)
        The sensor size the messages must state.
    """

    def __init__(self, source: str, resolution: tuple[int, int]):
        self.source = source
        self.resolution = tuple(resolution)
        self._evt3 = None

    def columns(self, message, msgtype: str, index: int) -> tuple[np.ndarray, ...] | None:
        """The events of ``message`` (number ``index`` of its topic) as columns, or None when it holds none.

        Raises
        ------
        CorruptFileError
            A message stating another sensor size, an unknown encoding, or EVT/mono bytes that are not whole
            words.
        """
        size = (int(message.width), int(message.height))
        if size != (0, 0) and size != self.resolution:
            raise CorruptFileError(f"{self.source}: message {index} says the sensor is {size[0]}x{size[1]}, the "
                                   f"first said {self.resolution[0]}x{self.resolution[1]}; the topic mixes "
                                   "cameras or the bag is damaged.")
        if msgtype == EVENT_ARRAY:
            return self._event_array(message.events, index)
        encoding = str(message.encoding)
        if encoding in NO_EVENT_ENCODINGS:
            return None
        if encoding == "mono":
            return self._mono(message, index)
        if encoding == "evt3":
            return self._evt3_columns(message, index)
        raise CorruptFileError(f"{self.source}: message {index} has the encoding '{encoding}'; cvstereo reads "
                               f"event_camera_msgs packets in {', '.join(PACKET_ENCODINGS)}.")

    def _event_array(self, events, index: int) -> tuple[np.ndarray, ...] | None:
        """``dvs_msgs/Event`` objects as columns; ``ts`` (seconds, nanoseconds) to microseconds, rounded down."""
        if not len(events):
            return None
        if isinstance(events, np.ndarray):  # decoded from the bytes (cvstereo.io._ros_event_array)
            rows = np.stack([events[f].astype(np.int64) for f in ("sec", "nsec", "x", "y", "polarity")], axis=1)
        else:
            rows = np.array([(e.ts.sec, e.ts.nanosec, e.x, e.y, e.polarity) for e in events], np.int64)
        bad = np.flatnonzero(rows[:, 1] >= NS_PER_S)
        if bad.size:
            raise CorruptFileError(f"{self.source}: message {index}, event {bad[0]}: ts.nsec is {rows[bad[0], 1]}, "
                                   "not below one second; the bag is damaged.")
        t = rows[:, 0] * US_PER_S + rows[:, 1] // NS_PER_US
        return t, rows[:, 2], rows[:, 3], rows[:, 4].astype(np.int8)

    def _mono(self, message, index: int) -> tuple[np.ndarray, ...]:
        data = np.asarray(message.events, np.uint8)
        if data.size % 8:
            raise CorruptFileError(f"{self.source}: message {index} holds {data.size} bytes of 'mono' events, not "
                                   "a whole number of 8-byte words; the bag is damaged.")
        words = data.view(">u8" if message.is_bigendian else "<u8").astype(np.uint64)
        dt = (words & np.uint64(0xFFFFFFFF)).astype(np.int64)
        t = (int(message.time_base) + dt) // NS_PER_US
        x = ((words >> np.uint64(32)) & np.uint64(0xFFFF)).astype(np.int64)
        y = ((words >> np.uint64(48)) & np.uint64(0x7FFF)).astype(np.int64)
        return t, x, y, (words >> np.uint64(63)).astype(np.int8)

    def _evt3_columns(self, message, index: int) -> tuple[np.ndarray, ...] | None:
        if message.is_bigendian:
            raise CorruptFileError(f"{self.source}: message {index} says its EVT 3.0 words are big-endian; EVT 3.0 "
                                   "is little-endian as the sensor sends it, so the bag is damaged.")
        if self._evt3 is None:
            from cvstereo.io.prophesee import _decoder_module

            self._evt3 = _decoder_module("evt3").Decoder(*self.resolution)
        try:
            events = self._evt3.feed(np.asarray(message.events, np.uint8).tobytes())
        except (KeyboardInterrupt, SystemExit, MissingExtraError):
            raise
        except BaseException as exc:  # the decoder's Rust panics are BaseExceptions
            raise CorruptFileError(f"{self.source}: the EVT 3.0 decoder failed on message {index} "
                                   f"[{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}]; the bag "
                                   "is damaged.") from None
        if events is None or not len(events.t):
            return None
        return events.t, events.x, events.y, events.p


