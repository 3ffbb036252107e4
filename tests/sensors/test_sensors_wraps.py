"""Hidden 16-bit wraps from arrival times, on a fake clock: exact for a prompt reader, counted (never guessed
silently) for a reader that was descheduled for more than a wrap, or bytes the OS held back.

The fake link: event i reaches the host's OS buffer at ``EPOCH + t_i + LINK_US`` (plus a hold where the OS
keeps bytes from the reader); the fake reader looks at the buffer at given host times, as
:class:`cvstereo.sensors.edvs.EDVS` does: a look that finds nothing sets ``after_t``, a look that finds
bytes reads them all with ``host_t`` = the look's time, ``fresh`` if the look before it found nothing.
"""

from __future__ import annotations

import numpy as np

from cvstereo.model.events import make_events
from cvstereo.sensors.decoder import StreamDecoder
from cvstereo.sensors.protocol import ProtocolSettings, encode_events

WRAP = 1 << 16
EPOCH = 5_000_000  # host us at which the board's clock read 0
LINK_US = 500  # board clock to the host's OS buffer
E2 = ProtocolSettings(event_format="E2")


def paced(pauses, burst=10, step=1000):
    """Bursts of ``burst`` events ``step`` us apart, with the given pauses (us) before each further burst."""
    t, now = [], 0
    for pause in [0, *pauses]:
        now += pause
        t.extend(now + step * np.arange(burst))
        now = t[-1]
    t = np.array(t, np.int64)
    i = np.arange(t.size)
    return make_events(t, i % 128, (i // 128) % 128, i % 2)


def read_like_the_reader(ev, looks, *, held=(), after_t=True):
    """Decode ``ev`` as the reader would, looking at the buffer at host times ``looks``; ``held`` lists
    (from, to) host-time spans during which bytes that reached the OS are not yet visible to the reader."""
    data = encode_events(ev, E2)
    size = len(data) // ev.size
    visible = EPOCH + ev["t"].astype(np.int64) + LINK_US
    for lo, hi in held:
        visible = np.where((visible >= lo) & (visible < hi), hi, visible)
    dec = StreamDecoder(E2)
    dec.reset_time(EPOCH)
    out, done, empty_at, was_empty, last_read = [], 0, None, False, None
    for look in np.sort(np.asarray(looks, np.int64)):
        n = int(np.searchsorted(visible, look, side="right"))
        if n == done:
            empty_at, was_empty = int(look), True
            if last_read is not None and look - last_read >= 20_000:  # the reader's release after a pause
                out.append(dec.decode(b"", host_t=int(look), release=True))
                last_read = None
            continue
        out.append(dec.decode(data[done * size:n * size], host_t=int(look), fresh=was_empty,
                              after_t=empty_at if after_t else None))
        done, was_empty, last_read = n, False, int(look)
    out.append(dec.flush())
    got = np.concatenate(out)
    assert got.size == ev.size  # every event delivered, whatever the timing
    return got, dec


def every_ms(ev, *, skip=()):
    """Looks every millisecond over the stream (a waiting reader), minus the spans in ``skip`` (descheduled)."""
    looks = np.arange(EPOCH - 10_000, EPOCH + int(ev["t"][-1]) + 100_000, 1000)
    for lo, hi in skip:
        looks = looks[(looks < lo) | (looks >= hi)]
    return looks


PAUSES = [70_000, 300_000, 131_072, 95_000, 200_000, 65_600, 150_000]


def test_prompt_reader_gets_every_hidden_wrap_exactly():
    ev = paced(PAUSES)
    got, dec = read_like_the_reader(ev, every_ms(ev))
    np.testing.assert_array_equal(got["t"], ev["t"])
    assert dec.hidden_wraps == sum(p // WRAP for p in PAUSES) == 14
    assert dec.ambiguous_wraps == 0 and dec.ambiguous == []


def burst_after_the_long_pause(ev):
    """Host time at which the first event after the 300 ms pause reaches the OS buffer, and its index."""
    i = 20  # bursts of 10: the third burst follows the 300 ms pause
    assert ev["t"][i] - ev["t"][i - 1] == 300_000
    return EPOCH + int(ev["t"][i]) + LINK_US, i


def test_reader_descheduled_at_a_burst_is_counted_not_guessed():
    # The reader looked (empty) 5 ms before the burst came, then did not run for 90 ms: the whole burst is
    # read at once, 90 ms late, and nothing timely follows before the next pause (a still scene).
    ev = paced(PAUSES)
    arrive, i = burst_after_the_long_pause(ev)
    looks = every_ms(ev, skip=[(arrive - 4_000, arrive + 90_000)])
    got, dec = read_like_the_reader(ev, looks)
    # The look before the burst bounds its time from below: 4 wraps certainly passed, 5 at most.
    assert dec.ambiguous_wraps == 1
    assert dec.ambiguous[0] == (i, 4, 4, 5)
    np.testing.assert_array_equal(got["t"], ev["t"])  # the fewest was the truth here
    # Without the empty look (the information the decoder had before), the late read time alone put the
    # burst a wrap late: this case does test something.
    old, _ = read_like_the_reader(ev, looks, after_t=False)
    wrong = np.flatnonzero(old["t"] != ev["t"])
    assert wrong.size and set(((old["t"] - ev["t"])[wrong]).tolist()) == {WRAP}


def test_reader_descheduled_for_long_says_where_times_may_be_off():
    # Descheduled from the middle of the 300 ms pause until 100 ms after the burst: the bounds leave 2..6
    # wraps; the decoder takes 2 and counts the gap; the times before it are exact, the burst after it is off by
    # whole wraps, and the next burst (read promptly again) is anchored exactly once more.
    ev = paced(PAUSES)
    arrive, i = burst_after_the_long_pause(ev)
    got, dec = read_like_the_reader(ev, every_ms(ev, skip=[(arrive - 150_000, arrive + 100_000)]))
    assert dec.ambiguous_wraps == 1
    index, taken, fewest, most = dec.ambiguous[0]
    assert index == i and taken == fewest and fewest <= 4 <= most  # the truth (4) lies within the bounds
    err = got["t"] - ev["t"]
    assert not err[:i].any()
    assert set(err[i:i + 10].tolist()) == {(taken - 4) * WRAP} != {0}  # whole wraps, from the listed event on
    assert not err[i + 10:].any()


def test_bytes_the_os_held_back_are_counted():
    # The OS keeps the burst from the reader for 100 ms although the reader kept looking: the lower bound
    # (a look found nothing) then contradicts the upper one; the decoder says so instead of trusting either.
    ev = paced(PAUSES)
    arrive, i = burst_after_the_long_pause(ev)
    got, dec = read_like_the_reader(ev, every_ms(ev), held=[(arrive, arrive + 100_000)])
    assert dec.ambiguous_wraps >= 1 and dec.ambiguous[0][0] == i
    err = got["t"] - ev["t"]
    assert not err[:i].any() and not (err % WRAP).any()


def test_continuous_stream_read_late_keeps_its_times():
    # 10k events/s with the reader away for 200 ms several times: the bytes pile up and are read in bursts.
    rng = np.random.default_rng(7)
    t = np.sort(rng.integers(0, 3_000_000, 30_000))
    ev = make_events(t, rng.integers(0, 128, t.size), rng.integers(0, 128, t.size), rng.integers(0, 2, t.size))
    skips = [(EPOCH + s, EPOCH + s + 200_000) for s in (400_000, 1_100_000, 2_000_000)]
    got, dec = read_like_the_reader(ev, every_ms(ev, skip=skips))
    np.testing.assert_array_equal(got["t"], ev["t"])
    assert dec.hidden_wraps == 0
