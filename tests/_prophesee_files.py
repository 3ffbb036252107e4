"""Prophesee files written byte by byte from the published format descriptions, for the readers' tests.

Independent of every decoder: each word is packed here from the bit layout of the format pages (EVT 2.0:
32-bit words, type in bits 31..28, CD words ``ts[27:22] x[21:11] y[10:0]``, TIME_HIGH ``t >> 6`` in 27..0;
EVT 2.1: 64-bit words written as one little-endian integer, ``type[63:60] ts[59:54] x[53:43] y[42:32]``
and a 32-pixel validity mask in 31..0; EVT 3.0: 16-bit words, type in 15..12, ADDR_Y / ADDR_X /
VECT_BASE_X / VECT_12 / VECT_8 / TIME_LOW / TIME_HIGH; DAT: ``% `` header, type byte 0x0C and size byte 8,
then ``<u4 t`` and ``<u4`` with ``x`` in bits 0..13, ``y`` in 14..27, ``p`` in 28..31), and CSV lines
``x,y,p,t`` as Metavision writes them. The events are of :data:`cvstereo.model.events.EVENT_DTYPE`.
"""

from __future__ import annotations

import numpy as np

EVT2_TYPES = {"off": 0x0, "on": 0x1, "time_high": 0x8, "trigger": 0xA}
EVT3_TYPES = {"addr_y": 0x0, "addr_x": 0x2, "vect_base_x": 0x3, "vect_12": 0x4, "vect_8": 0x5,
              "time_low": 0x6, "time_high": 0x8, "trigger": 0xA}
HEADER_NAMES = {"evt2": "EVT2", "evt21": "EVT21", "evt3": "EVT3"}


def raw_header(encoding: str, width: int, height: int, *, with_end: bool = True) -> bytes:
    """The ASCII header of a Metavision ``.raw`` file (as an EVK4 writes it, with ``% end``)."""
    lines = ["% camera_integrator_name Prophesee", "% date 2026-01-02 03:04:05",
             f"% format {HEADER_NAMES[encoding]};height={height};width={width}", f"% geometry {width}x{height}"]
    if with_end:
        lines.append("% end")
    return ("\n".join(lines) + "\n").encode()


def evt2_words(events: np.ndarray) -> np.ndarray:
    """EVT 2.0: one TIME_HIGH word whenever ``t >> 6`` changes, then one CD word per event."""
    words, high = [], None
    for e in events:
        t = int(e["t"])
        if t >> 6 != high:
            high = t >> 6
            words.append(EVT2_TYPES["time_high"] << 28 | (high & 0xFFFFFFF))
        kind = EVT2_TYPES["on"] if e["p"] else EVT2_TYPES["off"]
        words.append(kind << 28 | (t & 0x3F) << 22 | int(e["x"]) << 11 | int(e["y"]))
    return np.array(words, "<u4")


def evt21_words(events: np.ndarray) -> np.ndarray:
    """EVT 2.1: events of one time, row, polarity and 32-pixel group share one vector word."""
    words, high, i = [], None, 0
    while i < len(events):
        e = events[i]
        t, y, p, base = int(e["t"]), int(e["y"]), int(e["p"]), int(e["x"]) & ~31
        mask, j = 0, i
        while (j < len(events) and int(events[j]["t"]) == t and int(events[j]["y"]) == y
               and int(events[j]["p"]) == p and int(events[j]["x"]) & ~31 == base):
            mask |= 1 << (int(events[j]["x"]) - base)
            j += 1
        if t >> 6 != high:
            high = t >> 6
            words.append(EVT2_TYPES["time_high"] << 60 | (high & 0xFFFFFFF) << 32)
        kind = EVT2_TYPES["on"] if p else EVT2_TYPES["off"]
        words.append(kind << 60 | (t & 0x3F) << 54 | base << 43 | y << 32 | mask)
        i = j
    return np.array(words, "<u8")


def evt3_words(events: np.ndarray, *, vectors: bool = True) -> np.ndarray:
    """EVT 3.0: every TIME_HIGH step and TIME_LOW when it changes, ADDR_Y when the row changes; runs of x of one
    time, row and polarity as VECT_BASE_X + VECT_12 words (``vectors``), single events as ADDR_X."""
    words, high, low, row, i = [], None, None, None, 0

    def put(kind, payload):
        words.append(EVT3_TYPES[kind] << 12 | payload)

    while i < len(events):
        e = events[i]
        t, y, p, x = int(e["t"]), int(e["y"]), int(e["p"]), int(e["x"])
        if t >> 12 != high:
            # A sensor sends TIME_HIGH each time the clock's high bits advance (every 4096 us), with or without
            # events, which is how a reader sees the 24-bit clock wrap.
            for step in range(t >> 12 if high is None else high + 1, (t >> 12) + 1):
                put("time_high", step & 0xFFF)
            high, low = t >> 12, None
        if t & 0xFFF != low:
            low = t & 0xFFF
            put("time_low", low)
        if y != row:
            row = y
            put("addr_y", y)
        j = i
        while (j < len(events) and int(events[j]["t"]) == t and int(events[j]["y"]) == y
               and int(events[j]["p"]) == p and int(events[j]["x"]) < x + 12):
            j += 1
        if vectors and j - i > 1:
            put("vect_base_x", p << 11 | x)
            mask = 0
            for k in range(i, j):
                mask |= 1 << (int(events[k]["x"]) - x)
            put("vect_12", mask)
        else:
            j = i + 1
            put("addr_x", p << 11 | x)
        i = j
    return np.array(words, "<u2")


def raw_file(path, events: np.ndarray, encoding: str, width: int, height: int, **options) -> None:
    """A ``.raw`` file of ``events`` in ``encoding`` (``evt2``, ``evt21``, ``evt3``)."""
    words = {"evt2": evt2_words, "evt21": evt21_words, "evt3": evt3_words}[encoding](events, **options)
    path.write_bytes(raw_header(encoding, width, height) + words.tobytes())


def dat_file(path, events: np.ndarray, width: int, height: int) -> None:
    """A Prophesee ``.dat`` CD file (version 2) of ``events``."""
    header = (f"% Data file containing CD events\n% Date 2026-01-02 03:04:05\n% Version 2\n"
              f"% Width {width}\n% Height {height}\n").encode()
    records = np.empty(len(events), [("t", "<u4"), ("w", "<u4")])
    records["t"] = events["t"]
    records["w"] = (events["x"].astype(np.uint32) | events["y"].astype(np.uint32) << 14
                    | events["p"].astype(np.uint32) << 28)
    path.write_bytes(header + bytes([0x0C, 8]) + records.tobytes())


def csv_file(path, events: np.ndarray, order: str = "xypt") -> None:
    """A Metavision CSV file: one ``x,y,p,t`` line per event (columns in ``order``)."""
    lines = [",".join(str(int(e[c])) for c in order) for e in events]
    path.write_text("\n".join(lines) + "\n")


def scene_events(n: int, width: int, height: int, *, t0: int = 1_000, seed: int = 0) -> np.ndarray:
    """``n`` time-ordered events with bursts on one row (so that the vector words are used), times that cross
    TIME_HIGH boundaries of every encoding, both polarities, and pixels at the sensor's edges."""
    from cvstereo.model.events import make_events

    rng = np.random.default_rng(seed)
    t = t0 + np.cumsum(rng.choice([0, 0, 0, 1, 7, 70, 5000], size=n))
    x = rng.integers(0, width, n)
    y = rng.integers(0, height, n)
    p = rng.integers(0, 2, n)
    burst = rng.random(n) < 0.5  # half the events continue the previous one's row and time, one pixel on
    for i in np.flatnonzero(burst):
        if i and x[i - 1] + 1 < width:
            t[i], y[i], p[i], x[i] = t[i - 1], y[i - 1], p[i - 1], x[i - 1] + 1
    t = np.maximum.accumulate(t)
    x[:2], y[:2] = [0, width - 1], [height - 1, 0]
    events = make_events(t, x, y, p)
    order = np.lexsort((events["x"], events["p"], events["y"], events["t"]))
    return events[order]
