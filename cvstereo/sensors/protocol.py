"""The eDVS128 serial protocol: commands, event formats and the settings on which public drivers disagree.

Facts (formats.md, checked against public drivers; see the module notes below):

- UART 8N1, 4 Mbaud by default, RTS/CTS flow control; a byte costs 10 bit times, so 4 Mbaud carries
  400 kB/s.
- Commands are ASCII lines: ``R`` reset (the banner contains ``EDVS``), ``E+``/``E-`` start/stop
  streaming, ``!Ex`` event format, ``!Bx=y`` bias x, ``!BF`` flush biases to the chip, ``!U0`` echo off,
  ``!ET0`` timestamp reset, ``!ETM0``/``!ETM+`` arm/run timestamp master, ``!ETS`` timestamp slave.
- An event is ``[sync][y 7 bits]`` ``[polarity][x 7 bits]`` and an optional big-endian timestamp:
  ``E0`` none (2 bytes), ``E1`` variable-length delta (3-6 bytes), ``E2`` 16 bit (4), ``E3`` 24 bit (5),
  ``E4`` 32 bit (6); timestamps tick in microseconds.

Where drivers disagree (so these are settings, :class:`ProtocolSettings`):

- sync bit: edvstools requires bit 7 of byte 0 set (``1yyyyyyy``); libcaer treats a set bit 7 as
  "data not aligned", and the 2011 firmware help quoted in jAER's serial interface documents
  ``0yyyyyyy`` (jAER itself does not check it).
- polarity sense: jAER copies the bit into the DVS128 raw polarity bit (1 = OFF); libcaer reads a set
  bit as ON.
- format numbering: current firmware numbers the 16-bit format ``!E2``; the 2011 firmware and
  edvstools use ``!E1`` = 16 bit, ``!E2`` = 24 bit, ``!E3`` = 32 bit (no variable-length format).
- line ending: most drivers send ``\\n``; jAER sends ``E+\\r\\n`` in one place.
- timestamp reset: formats.md says ``!ET0``; the firmware help of a later board reads ``!ET[=t]``.
  The command text is a setting too.

The variable-length ``E1`` layout used here (the delta to the previous event in 7-bit groups, most
significant first, bit 7 set on the last group only) is our reading of the firmware help ("1..4 bytes
delta-timestamp, 7 bits each"); no public driver decodes it, so treat it as unverified.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

__all__ = ["BITS_PER_BYTE", "DEFAULT_BAUD", "FORMATS", "FORMAT_NUMBERS", "MAX_DELTA_BYTES", "Commands", "EventFormat",
           "ProtocolSettings", "encode_events", "event_format", "format_from_number", "link_event_rate"]

#: Bits on the wire per byte with 8N1 framing (start + 8 data + stop).
BITS_PER_BYTE = 10

#: Default link speed of the eDVS128.
DEFAULT_BAUD = 4_000_000

#: Maximum number of 7-bit groups of an E1 delta timestamp (28 bits, 268 s).
MAX_DELTA_BYTES = 4


@dataclass(frozen=True)
class EventFormat:
    """One event format on the wire.

    Attributes
    ----------
    name : str
        ``"E0"`` ... ``"E4"`` (current firmware numbering).
    ts_bytes : int
        Bytes of absolute timestamp after the two address bytes (0 for E0 and E1).
    delta : bool
        True for E1: a variable-length delta timestamp follows instead.
    """

    name: str
    ts_bytes: int
    delta: bool = False

    @property
    def size(self) -> int:
        """Bytes per event (the shortest, for E1)."""
        return 2 + self.ts_bytes + (1 if self.delta else 0)

    @property
    def max_size(self) -> int:
        """Bytes per event, longest case."""
        return 2 + self.ts_bytes + (MAX_DELTA_BYTES if self.delta else 0)

    @property
    def wrap(self) -> int:
        """Period of the on-wire timestamp in microseconds (0 when there is no absolute timestamp)."""
        return 1 << (8 * self.ts_bytes) if self.ts_bytes else 0

    @property
    def has_time(self) -> bool:
        """Whether the device sends time (absolute or delta) with each event."""
        return self.delta or self.ts_bytes > 0


FORMATS: dict[str, EventFormat] = {
    "E0": EventFormat("E0", 0),
    "E1": EventFormat("E1", 0, delta=True),
    "E2": EventFormat("E2", 2),
    "E3": EventFormat("E3", 3),
    "E4": EventFormat("E4", 4),
}

#: Format name -> number sent in ``!Ex``, per firmware generation.
FORMAT_NUMBERS: dict[str, dict[str, int]] = {
    "current": {"E0": 0, "E1": 1, "E2": 2, "E3": 3, "E4": 4},
    # 2011 firmware / edvstools: no variable-length format, the timestamped formats shift down by one.
    "legacy": {"E0": 0, "E2": 1, "E3": 2, "E4": 3},
}


def event_format(name: str | EventFormat) -> EventFormat:
    """Look up an event format by name (``"E2"``, case-insensitive).

    Raises
    ------
    ValueError
        Unknown name; the message lists the known ones.
    """
    if isinstance(name, EventFormat):
        return name
    key = str(name).upper()
    if key not in FORMATS:
        raise ValueError(f"unknown eDVS event format '{name}'; choose one of: {', '.join(FORMATS)}.")
    return FORMATS[key]


@dataclass(frozen=True)
class Commands:
    """The command texts (without line ending); override one where a firmware spells it differently."""

    reset: str = "R"
    start: str = "E+"
    stop: str = "E-"
    echo_off: str = "!U0"
    flush_biases: str = "!BF"
    timestamp_reset: str = "!ET0"
    master_arm: str = "!ETM0"
    master_run: str = "!ETM+"
    slave: str = "!ETS"
    help: str = "??"
    #: Text the reset banner contains.
    banner: str = "EDVS"


@dataclass(frozen=True)
class ProtocolSettings:
    """How to talk to one board and read its bytes.

    Parameters
    ----------
    event_format : {"E0", "E1", "E2", "E3", "E4"}
        Format asked for with ``!Ex`` and decoded (current-firmware names).
    sync_bit_set : bool
        True: byte 0 of an event has bit 7 set (``1yyyyyyy``, current firmware, edvstools);
        False: bit 7 clear (libcaer, 2011 firmware).
    off_bit_set : bool
        True: a set polarity bit means OFF (jAER, the default); False: it means ON (libcaer).
    numbering : {"current", "legacy"}
        Format numbers of ``!Ex`` (see :data:`FORMAT_NUMBERS`).
    line_ending : str
        Appended to every command: ``"\\n"`` (default) or ``"\\r\\n"``.
    commands : Commands
        Command texts.
    """

    event_format: str = "E2"
    sync_bit_set: bool = True
    off_bit_set: bool = True
    numbering: Literal["current", "legacy"] = "current"
    line_ending: str = "\n"
    commands: Commands = field(default_factory=Commands)

    def __post_init__(self):
        fmt = event_format(self.event_format)
        object.__setattr__(self, "event_format", fmt.name)
        if self.numbering not in FORMAT_NUMBERS:
            raise ValueError(f"unknown format numbering '{self.numbering}'; choose 'current' or 'legacy'.")
        if fmt.name not in FORMAT_NUMBERS[self.numbering]:
            raise ValueError(
                f"format {fmt.name} does not exist in {self.numbering} firmware; "
                f"choose one of {', '.join(FORMAT_NUMBERS[self.numbering])}."
            )
        if self.line_ending not in ("\n", "\r\n", "\r"):
            raise ValueError(f"line ending {self.line_ending!r} is not one of '\\n', '\\r\\n', '\\r'.")

    @property
    def format(self) -> EventFormat:
        """The :class:`EventFormat` of :attr:`event_format`."""
        return FORMATS[self.event_format]

    def line(self, text: str) -> bytes:
        """A command line as bytes, with the line ending."""
        return (text + self.line_ending).encode("ascii")

    def format_command(self) -> str:
        """``!Ex`` for the chosen format and numbering."""
        return f"!E{FORMAT_NUMBERS[self.numbering][self.event_format]}"

    @staticmethod
    def bias_command(index: int, value: int) -> str:
        """``!Bx=y``: set bias register ``index`` (0-11) to ``value`` (0 .. 2**24 - 1)."""
        if not 0 <= int(index) <= 11:
            raise ValueError(f"bias index {index} out of range; the eDVS128 has bias registers 0..11.")
        if not 0 <= int(value) < 1 << 24:
            raise ValueError(f"bias value {value} out of range 0..{(1 << 24) - 1} (24-bit register).")
        return f"!B{int(index)}={int(value)}"


def format_from_number(number: int, numbering: str = "current") -> str:
    """The format name that ``!E<number>`` selects in a firmware generation, or raise ValueError."""
    for name, num in FORMAT_NUMBERS[numbering].items():
        if num == number:
            return name
    raise ValueError(f"!E{number} is not an event format of {numbering} firmware.")


def link_event_rate(fmt: str | EventFormat, baud: int = DEFAULT_BAUD) -> float:
    """Maximum events per second the link carries in a format (shortest encoding for E1)."""
    return baud / BITS_PER_BYTE / event_format(fmt).size


def encode_events(events: np.ndarray, settings: ProtocolSettings, *, t_prev: int = 0) -> bytes:
    """Encode events as a board would send them (used by the virtual eDVS and the benchmark).

    Parameters
    ----------
    events : (N,) ndarray of EVENT_DTYPE
        ``t`` is the device time in microseconds (absolute formats send it modulo their wrap).
    settings : ProtocolSettings
    t_prev : int, keyword-only
        Device time of the event sent before these (E1 deltas are relative to it).

    Returns
    -------
    bytes
    """
    fmt = settings.format
    n = events.size
    sync = 0x80 if settings.sync_bit_set else 0
    b0 = (events["y"].astype(np.uint8) & 0x7F) | sync
    off = events["p"] == 0
    pol = off if settings.off_bit_set else ~off
    b1 = (events["x"].astype(np.uint8) & 0x7F) | (pol.astype(np.uint8) << 7)
    if fmt.delta:
        t = events["t"].astype(np.int64)
        delta = np.diff(t, prepend=np.int64(t_prev))
        if n and (delta.min() < 0 or delta.max() >= 1 << (7 * MAX_DELTA_BYTES)):
            raise ValueError("E1 deltas must be non-negative and below 2**28 us.")
        # Number of 7-bit groups per event: 1 + floor(log128(delta)).
        groups = 1 + (delta >= 1 << 7) + (delta >= 1 << 14) + (delta >= 1 << 21)
        sizes = 2 + groups
        ends = np.cumsum(sizes)
        starts = ends - sizes
        out = np.zeros(int(ends[-1]) if n else 0, dtype=np.uint8)
        out[starts] = b0
        out[starts + 1] = b1
        for g in range(MAX_DELTA_BYTES):
            # Group g counted from the last one: shift 7*g; only events with more than g groups have it.
            has = groups > g
            pos = ends[has] - 1 - g
            val = (delta[has] >> (7 * g)) & 0x7F
            out[pos] = val | (0x80 if g == 0 else 0)
        return out.tobytes()
    out = np.empty((n, fmt.size), dtype=np.uint8)
    out[:, 0] = b0
    out[:, 1] = b1
    if fmt.ts_bytes:
        t = events["t"].astype(np.int64) % fmt.wrap
        for k in range(fmt.ts_bytes):
            out[:, 2 + k] = (t >> (8 * (fmt.ts_bytes - 1 - k))) & 0xFF
    return out.tobytes()
