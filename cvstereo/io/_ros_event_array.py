"""``dvs_msgs/EventArray`` decoded from its serialised bytes by numpy, one view per message instead of one Python
object per event.

The message is ``Header header, uint32 height, uint32 width, Event[] events`` with ``Event`` = ``uint16 x,
uint16 y, time ts, bool polarity``. ROS 1 packs fields without padding: 13 bytes an event. ROS 2 writes CDR: a
4-byte encapsulation header (byte 1: 1 for little-endian), then each field aligned to its size counted from the
end of that header; so the first event (4-aligned after the sequence length) takes 13 bytes and each later one 16
(``x`` at 2 mod 4, two bytes of padding before ``ts``, one after ``polarity``).

:func:`parse_event_array` returns None for anything it does not recognise exactly (a length that does not add
up, big-endian CDR), and the reader then decodes the message through rosbags as before, whose errors name the
damage; the reader also checks the first messages of each topic against rosbags' decoding
(:func:`same_event_array`), so a bag whose types differ from the published definitions is never misread.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["RawEventArray", "parse_event_array", "same_event_array"]

#: One event as ROS 1 packs it.
ROS1_EVENT = np.dtype([("x", "<u2"), ("y", "<u2"), ("sec", "<u4"), ("nsec", "<u4"), ("polarity", "u1")])
#: The columns handed on, whatever the layout: ``sec`` signed (CDR's is), ``polarity`` 0 or 1 (a bool).
EVENT_COLUMNS = np.dtype([("x", "<u2"), ("y", "<u2"), ("sec", "<i8"), ("nsec", "<u4"), ("polarity", "u1")])
#: The first event of a CDR sequence (4-aligned) and every later one (2 mod 4), offsets from the event's start.
_CDR_FIELDS = ["x", "y", "sec", "nsec", "polarity"]
_CDR_FORMATS = ["<u2", "<u2", "<i4", "<u4", "u1"]
CDR_FIRST_EVENT = np.dtype({"names": _CDR_FIELDS, "formats": _CDR_FORMATS, "offsets": [0, 2, 4, 8, 12],
                            "itemsize": 13})
CDR_LATER_EVENT = np.dtype({"names": _CDR_FIELDS, "formats": _CDR_FORMATS, "offsets": [0, 2, 6, 10, 14],
                            "itemsize": 15})
#: Bytes from one later event to the next (its padding byte included), and from the first event to the second.
CDR_LATER_STRIDE = 16
_CDR_SECOND = 14
_CDR_LITTLE_ENDIAN = 1
_CDR_HEADER = 4


class RawEventArray(NamedTuple):
    """What the reader needs of a ``dvs_msgs/EventArray``: the size it states and its events' columns."""

    width: int
    height: int
    events: np.ndarray  # (N,) of EVENT_COLUMNS


def _u32(raw: memoryview, at: int) -> int | None:
    return int.from_bytes(raw[at:at + 4], "little") if at + 4 <= len(raw) else None


def _ros1(raw: memoryview) -> RawEventArray | None:
    name_len = _u32(raw, 12)  # after seq, stamp.sec, stamp.nsec
    if name_len is None:
        return None
    at = 16 + name_len
    height, width, count = _u32(raw, at), _u32(raw, at + 4), _u32(raw, at + 8)
    if count is None or at + 12 + count * ROS1_EVENT.itemsize != len(raw):
        return None
    return RawEventArray(width, height, _handed_on(np.frombuffer(raw, ROS1_EVENT, count, at + 12)))


def _aligned(at: int, size: int) -> int:
    return at + (-at) % size


def _cdr(raw: memoryview) -> RawEventArray | None:
    if len(raw) < _CDR_HEADER or raw[1] != _CDR_LITTLE_ENDIAN:
        return None
    body = raw[_CDR_HEADER:]
    name_len = _u32(body, 8)  # after stamp.sec, stamp.nanosec; the length counts the closing NUL
    if name_len is None:
        return None
    at = _aligned(12 + name_len, 4)
    height, width, count = _u32(body, at), _u32(body, at + 4), _u32(body, at + 8)
    if count is None:
        return None
    first = at + 12
    if count == 0:
        end = first
    elif count == 1:
        end = first + CDR_FIRST_EVENT.itemsize
    else:  # the last event's closing padding byte is not written
        end = first + _CDR_SECOND + CDR_LATER_STRIDE * (count - 1) - 1
    if not end <= len(body) <= _aligned(end, 4) or any(body[end:]):
        return None
    events = np.empty(count, EVENT_COLUMNS)
    if count:
        events[:1] = _handed_on(np.frombuffer(body, CDR_FIRST_EVENT, 1, first))
    if count > 1:
        events[1:] = _handed_on(np.ndarray((count - 1,), CDR_LATER_EVENT, body, first + _CDR_SECOND,
                                           (CDR_LATER_STRIDE,)))
    return RawEventArray(width, height, events)


def _handed_on(view: np.ndarray) -> np.ndarray:
    """A view over a message's bytes as :data:`EVENT_COLUMNS` (a copy: the bytes go with the message)."""
    out = np.empty(view.size, EVENT_COLUMNS)
    for name in EVENT_COLUMNS.names:
        out[name] = view[name]
    out["polarity"] = view["polarity"] != 0
    return out


def parse_event_array(raw, ros2: bool) -> RawEventArray | None:
    """A ``dvs_msgs/EventArray`` from its serialised bytes (ROS 1, or ROS 2 CDR), or None when the bytes are not
    exactly that message as published (the caller then decodes them through rosbags)."""
    view = memoryview(raw).cast("B")
    return _cdr(view) if ros2 else _ros1(view)


def same_event_array(fast: RawEventArray, message) -> bool:
    """Whether ``fast`` holds what rosbags decoded as ``message`` (size and every event's fields)."""
    if (fast.width, fast.height) != (int(message.width), int(message.height)):
        return False
    if len(fast.events) != len(message.events):
        return False
    want = np.array([(e.x, e.y, e.ts.sec, e.ts.nanosec, bool(e.polarity)) for e in message.events], np.int64)
    got = np.stack([fast.events[f].astype(np.int64) for f in EVENT_COLUMNS.names], axis=1)
    return bool(np.array_equal(want.reshape(got.shape), got))
