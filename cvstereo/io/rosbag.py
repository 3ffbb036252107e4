"""ROS 1 and ROS 2 bags of event-camera messages (the ``ros`` extra: ``rosbags``, pure Python).

A ROS 1 bag is one ``.bag`` file (it starts with ``#ROSBAG V2.0``); a ROS 2 bag is a folder holding
``metadata.yaml`` and its ``.db3`` (sqlite3) or ``.mcap`` files, or one such storage file alone. The events are
``dvs_msgs/EventArray`` or ``event_camera_msgs/EventPacket`` messages (:mod:`cvstereo.io._ros_messages`), one
topic per camera: ``topics=("LEFT", "RIGHT")`` (the CLI's ``--topics LEFT,RIGHT``) names them, else the bag's
two event topics are told apart by their names (``left``/``right``, or ``cam0``/``cam1``).

Clock: every event keeps its own time, in microseconds, as the messages carry it: a ``dvs_msgs`` event's ``ts``
(the ROS time the driver gave it, nanoseconds rounded down), an ``event_camera_msgs`` packet's sensor time
(EVT 3.0 decoded as in ``.raw`` files; ``mono``: ``time_base + dt``). The message header stamps and the bag's
record times are not used: they say when a packet was sent, not when its events happened. Both cameras must
therefore share one clock, as a stereo rig's drivers give it (one host's ROS time, or synchronised sensors).

Each camera is read message by message in the bag's order, so memory stays bounded; its events must be in time
order across messages (an error names the topic and the message otherwise). The sensor size is what the
messages state (every message of a topic must agree).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

from cvstereo.errors import CorruptFileError, EventFormatError, MissingExtraError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io._ros_event_array import parse_event_array, same_event_array
from cvstereo.io._ros_messages import EVENT_ARRAY, EVENT_PACKET, EVENT_TYPES, PacketDecoder, import_rosbags, typestore
from cvstereo.io.files import is_ros2_folder, require_input, require_regular_file
from cvstereo.io.stream import Chunk, RecordingStream
from cvstereo.model.events import check_resolution
from cvstereo.model.recording import CAMERAS

__all__ = ["FORMAT", "open_rosbag", "parse_topics", "sniff_rosbag"]

FORMAT = "rosbag"
ROS1_MAGIC = b"#ROSBAG V2.0"
MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
#: The first bytes of ROS 2's storage files, and the extension rosbags needs to read each.
ROS2_STORAGE = {MCAP_MAGIC: ".mcap", SQLITE_MAGIC: ".db3"}
HEAD_BYTES = max(len(magic) for magic in (ROS1_MAGIC, *ROS2_STORAGE))
#: Name pairs that tell the left camera's topic from the right one's, in order of preference.
SIDE_NAMES = (("left", "right"), ("cam0", "cam1"))


def sniff_rosbag(path: str | os.PathLike, head: bytes = b"") -> bool:
    """Whether ``path`` (a file starting with ``head``, or a folder) is a ROS bag: ``#ROSBAG V2.0`` at the start,
    an MCAP or SQLite ``.db3`` storage file, or a ROS 2 bag folder."""
    if is_ros2_folder(path):
        return True
    if head.startswith(ROS1_MAGIC) or head.startswith(MCAP_MAGIC):
        return True
    return head.startswith(SQLITE_MAGIC) and Path(path).suffix.lower() == ".db3"  # not every SQLite file


def parse_topics(topics, *, source: str = "--topics") -> tuple[str, str] | None:
    """``"LEFT,RIGHT"`` (or a pair) as two topic names; None stays None (find them).

    Raises
    ------
    ValueError
        Not two distinct non-empty names.
    """
    if topics is None:
        return None
    names = tuple(n.strip() for n in (topics.split(",") if isinstance(topics, str) else topics))
    if len(names) != 2 or not all(names) or names[0] == names[1]:
        raise ValueError(f"{source} '{','.join(names)}': give the left and the right camera's event topics, two "
                         "different names separated by a comma, e.g. /dvs/left/events,/dvs/right/events.")
    return names


def _reader(path: str):
    """A rosbags reader of the bag at ``path`` (not yet opened) and whether it is a ROS 2 bag."""
    rosbags = import_rosbags()
    if Path(path).is_dir():
        require_input(path)  # a ROS 2 bag folder, else says what is missing
        return rosbags.rosbag2.Reader(Path(path)), True
    with open(require_regular_file(path), "rb") as fh:
        head = fh.read(HEAD_BYTES)
    if head.startswith(ROS1_MAGIC):
        return rosbags.rosbag1.Reader(Path(path)), False
    suffix = next((s for magic, s in ROS2_STORAGE.items() if head.startswith(magic)), None)
    if suffix is None:
        raise CorruptFileError(f"{path}: not a ROS bag (no '#ROSBAG V2.0' at the start, not an MCAP or SQLite "
                               "storage file of a ROS 2 bag).")
    if Path(path).suffix.lower() != suffix:
        raise CorruptFileError(f"{path}: a ROS 2 {suffix} storage file under another name; name it *{suffix}.")
    return rosbags.rosbag2.Reader(Path(path)), True


def _damaged(path: str, exc: BaseException) -> CorruptFileError:
    """One line saying the bag cannot be read, with rosbags' reason."""
    reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return CorruptFileError(f"{path}: not a readable ROS bag [{reason}]; the bag is damaged or truncated (a bag "
                            "whose recording was cut off can be reindexed: `rosbag reindex`, `ros2 bag reindex`).")


_OURS = (CorruptFileError, EventFormatError, MissingExtraError, OSError)


def _event_topics(connections) -> dict[str, str]:
    """The bag's topics of event messages and their types."""
    return {c.topic: c.msgtype for c in connections if c.msgtype in EVENT_TYPES}


def _choose_topics(path: str, given: tuple[str, str] | None, connections) -> tuple[str, str]:
    """The left and right cameras' topics: those given (which must hold events), else found by name."""
    events = _event_topics(connections)
    listing = ", ".join(f"{c.topic} ({c.msgtype})" for c in connections) or "no topics"
    if given is not None:
        for topic in given:
            if topic not in events:
                kinds = sorted({c.msgtype for c in connections if c.topic == topic})
                what = f"holds {', '.join(kinds)}, no event messages" if kinds else "is not in the bag"
                raise ValueError(f"{path}: topic {topic} {what}; the bag holds {listing}.")
        return given
    if len(events) == 2:
        for left_word, right_word in SIDE_NAMES:
            left = [t for t in events if left_word in t.lower() and right_word not in t.lower()]
            right = [t for t in events if right_word in t.lower() and left_word not in t.lower()]
            if len(left) == 1 and len(right) == 1:
                return left[0], right[0]
    why = {0: "no topic of event messages (dvs_msgs/EventArray, event_camera_msgs/EventPacket)",
           1: "one event topic only (a stereo recording needs a topic per camera)"}.get(
        len(events), f"{len(events)} event topics whose names do not say left/right or cam0/cam1")
    raise ValueError(f"{path}: {why}; the bag holds {listing}. Give --topics LEFT,RIGHT.")


def _messages(path: str, topic: str, label: str):
    """``(message, msgtype, index)`` of one topic's messages, deserialised, in the bag's order; the bag is opened
    anew for each call, so that the two cameras are read side by side."""
    reader, ros2 = _reader(path)
    try:
        reader.open()
    except _OURS:
        _close_quietly(reader)
        raise
    except Exception as exc:
        _close_quietly(reader)
        raise _damaged(path, exc) from None
    try:
        store = typestore(reader.connections, ros2)
        deserialize = store.deserialize_cdr if ros2 else store.deserialize_ros1
        connections = [c for c in reader.connections if c.topic == topic]
        # dvs_msgs/EventArray from its bytes by numpy, once its first message with events decodes as rosbags
        # decodes it (a bag whose types differ from the published ones stays with rosbags); None: not yet known.
        from_bytes: dict[int, bool] = {}
        for index, (connection, _, raw) in enumerate(reader.messages(connections=connections)):
            trusted = from_bytes.get(connection.id)
            fast = parse_event_array(raw, ros2) if connection.msgtype == EVENT_ARRAY and trusted is not False else None
            if fast is not None and trusted:
                message = fast
            else:
                message = _deserialize(deserialize, raw, connection, path, topic, label, index)
                if fast is not None:
                    if not same_event_array(fast, message):
                        from_bytes[connection.id] = False
                    elif len(fast.events):
                        from_bytes[connection.id] = True
            yield message, connection.msgtype, index
    except _OURS:
        raise
    except Exception as exc:
        raise _damaged(path, exc) from None
    finally:
        reader.close()


def _deserialize(deserialize, raw, connection, path: str, topic: str, label: str, index: int):
    """One message decoded by rosbags; an error naming the message when its bytes are not its type."""
    try:
        return deserialize(raw, connection.msgtype)
    except Exception as exc:
        raise CorruptFileError(f"{path} [topic {topic}, {label}]: message {index} cannot be decoded as "
                               f"{connection.msgtype} [{str(exc).strip() or type(exc).__name__}]; the bag "
                               "is damaged.") from None


def _topic_size(path: str, topic: str, label: str) -> tuple[int, int] | None:
    """The sensor size the first message of ``topic`` states, None when it states none (0x0) or there is none."""
    for message, _, _ in _messages(path, topic, label):
        size = (int(message.width), int(message.height))
        return None if size == (0, 0) else size
    return None


def _camera_chunks(path: str, topic: str, label: str, resolution: tuple[int, int]) -> Iterator[Chunk]:
    """One camera's events, message by message, checked (inside the sensor, in time order across messages)."""
    source = f"{path} [topic {topic}, {label}]"
    decoder = PacketDecoder(source, resolution)
    check = ChunkChecker(resolution=resolution, source=source)
    for message, msgtype, index in _messages(path, topic, label):
        columns = decoder.columns(message, msgtype, index)
        if columns is None:
            continue
        try:
            events = check.columns(*columns)
        except EventFormatError as exc:
            raise EventFormatError(f"{exc} [message {index} of the topic]") from None
        yield events, None


def open_rosbag(path: str | os.PathLike, *, topics=None,
                resolution: tuple[int, int] | None = None) -> RecordingStream:
    """Open a ROS 1 or ROS 2 bag of a stereo event recording for streaming.

    Parameters
    ----------
    path : path-like
        A ROS 1 ``.bag`` file, a ROS 2 bag folder, or a ROS 2 ``.db3`` / ``.mcap`` storage file.
    topics : str or (str, str), optional, keyword-only
        The left and the right camera's event topics (``"LEFT,RIGHT"``). Default: the bag's two event topics,
        told apart by ``left``/``right`` or ``cam0``/``cam1`` in their names.
    resolution : (width, height), optional, keyword-only
        The sensor size where the messages state none (0x0); where they do, they must agree.

    Returns
    -------
    RecordingStream
        ``meta`` holds ``source``, ``format``, ``ros`` (1 or 2), ``topics`` (left, right) and ``clock``.

    Raises
    ------
    ValueError
        No two event topics to be told apart, a topic given that is not in the bag or holds no events (each
        error lists the bag's topics), the two cameras of different sizes.
    CorruptFileError
        Not a ROS bag, a damaged or truncated one, a message that cannot be decoded; events out of time order
        or outside the sensor (:class:`~cvstereo.errors.EventFormatError`).
    MissingExtraError
        ``rosbags`` (the ``ros`` extra) is not installed, or ``evt3`` (the ``prophesee`` extra) for EVT 3.0
        packets.
    """
    path = os.fspath(path)
    wanted = parse_topics(topics)
    reader, ros2 = _reader(path)
    try:
        reader.open()
        connections = list(reader.connections)
    except _OURS:
        raise
    except Exception as exc:
        raise _damaged(path, exc) from None
    finally:
        _close_quietly(reader)
    chosen = _choose_topics(path, wanted, connections)
    sizes = {label: _topic_size(path, topic, label) for label, topic in zip(CAMERAS, chosen, strict=True)}
    stated = {s for s in sizes.values() if s is not None}
    if len(stated) > 1:
        raise ValueError(f"{path}: the cameras' topics state different sensor sizes ({sizes['left']} and "
                         f"{sizes['right']}); cvstereo matches cameras of one size.")
    size = next(iter(stated)) if stated else None
    if size is not None and resolution is not None and tuple(resolution) != size:
        raise ValueError(f"{path}: the messages say the sensor is {size[0]}x{size[1]}, not "
                         f"{resolution[0]}x{resolution[1]}.")
    if size is None and resolution is None:
        raise ValueError(f"{path}: the messages of {' and '.join(chosen)} state no sensor size; give --resolution WxH.")
    size = check_resolution(size or tuple(resolution), source=f"{path}: sensor size", error=CorruptFileError)
    kinds = {_event_topics(connections)[t] for t in chosen}
    clock = {frozenset({EVENT_ARRAY}): "the events' ts (ROS time)",
             frozenset({EVENT_PACKET}): "the sensors' time (EVT 3.0 / mono packets)"}.get(
        frozenset(kinds), "each camera's events' own times (dvs_msgs ts, event_camera_msgs sensor time)")
    meta = {"source": path, "format": FORMAT, "ros": 2 if ros2 else 1, "topics": list(chosen), "clock": clock,
            "resolution_from": "messages" if stated else "given"}
    by_camera = dict(zip(CAMERAS, chosen, strict=True))

    def open_chunks(camera: str) -> Iterator[Chunk]:
        return _camera_chunks(path, by_camera[camera], camera, size)

    return RecordingStream(FORMAT, (path,), CAMERAS, size, meta, False, open_chunks)


def _close_quietly(reader) -> None:
    """Close a rosbags reader that may not have opened (a failed open leaves it half open)."""
    try:
        reader.close()
    except Exception:  # a reader whose open failed has nothing to close
        pass
