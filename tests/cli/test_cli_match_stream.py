"""``cvstereo match`` streams the recording: events are read as they are matched, never the whole file first,
so that memory does not grow with the recording's length (the default rig check holds its prefix, then streams);
``--auto`` reads it twice (whole for the rig check, then streamed); the matches are those of ``match()`` on the
recording in memory."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import cvstereo.io
import cvstereo.run
from cvstereo.cli import main
from cvstereo.io import read_matches, read_recording, write_recording
from cvstereo.model.events import make_events
from cvstereo.model.recording import Recording
from cvstereo.run import match

#: Events per chunk of the counting reader: small, so that a recording of a few seconds is many chunks.
CHUNK = 300
SECONDS, RATE = 4, 10_000  # per camera: 40k events, ~133 chunks


@pytest.fixture(scope="module")
def long_file(tmp_path_factory):
    rng = np.random.default_rng(3)
    n = SECONDS * RATE
    t = np.sort(rng.integers(0, SECONDS * 1_000_000, n))
    x, y, p = rng.integers(20, 100, n), rng.integers(0, 128, n), rng.integers(0, 2, n)
    left = make_events(t, x, y, p)
    right = make_events(t, x - 6, y, p)  # the scene 6 px to the left in the right camera
    path = tmp_path_factory.mktemp("long") / "long.npz"
    write_recording(path, Recording(left, right))
    return path


class _Log:
    """What the counting reader and the feed loop saw: events read and fed so far, and files opened."""

    def __init__(self):
        self.read = 0
        self.fed = 0
        self.opened = 0
        self.held = []  # events read but not yet fed, at every feed: what the run holds in memory

    def open_recording(self, original):
        def opener(*args, **kwargs):
            stream = original(*args, **kwargs)

            def open_chunks(camera):
                self.opened += 1
                for events, truth in stream.open_chunks(camera):
                    for i in range(0, events.size, CHUNK):
                        self.read += events[i:i + CHUNK].size
                        yield events[i:i + CHUNK], None if truth is None else truth[i:i + CHUNK]

            return dataclasses.replace(stream, open_chunks=open_chunks)

        return opener

    def run_iter(self, original):
        def spy(matcher, packets, **kwargs):
            before = self.read  # what a rig check read before the match
            for packet, found in original(matcher, packets, **kwargs):
                if packet is not None:
                    self.fed += packet.left.size + packet.right.size
                    self.held.append(self.read - before - self.fed)
                yield packet, found

        return spy


@pytest.mark.parametrize("mode", ["--no-rig-check", "default", "--auto"])
def test_match_reads_the_recording_as_it_matches(tmp_path, long_file, monkeypatch, mode):
    log = _Log()
    monkeypatch.setattr(cvstereo.io, "open_recording", log.open_recording(cvstereo.io.open_recording))
    monkeypatch.setattr(cvstereo.run, "run_iter", log.run_iter(cvstereo.run.run_iter))
    out = tmp_path / "m.npz"
    argv = ["match", str(long_file), "--method", "frame", "-o", str(out), "--no-progress"]
    assert main(argv + ([] if mode == "default" else [mode])) == 0
    total = 2 * SECONDS * RATE
    assert log.fed == total
    # Streamed: at every packet the run holds at most a packet (40 ms: ~800 events) and a chunk per camera
    # read ahead, not the file (reading it whole first held all 80k at the first packet).
    streaming = 2 * CHUNK + 2 * 0.04 * RATE * 1.5
    if mode == "default":
        # The rig check holds its prefix (the events of its span, both cameras), then the rest streams.
        prefix_s = read_matches(out).meta["rigcheck"]["prefix_us"] / 1e6
        assert prefix_s < SECONDS / 2
        assert max(log.held) <= 2 * RATE * prefix_s * 1.1 + streaming, max(log.held)
        packets_in_prefix = int(prefix_s / 0.04) + 1
        assert max(log.held[packets_in_prefix:]) <= streaming, max(log.held[packets_in_prefix:])
    else:
        assert max(log.held) <= streaming, max(log.held)
    # --auto: the rig check reads both cameras whole, then the match reads them again; else read once.
    auto = mode == "--auto"
    assert log.opened == (4 if auto else 2)
    assert log.read == total * (2 if auto else 1)
    got = read_matches(out)
    expected = match(read_recording(long_file), method="frame", rig_check=mode == "default")
    np.testing.assert_array_equal(got.matches, expected.matches)
    assert got.meta["input"] == [str(long_file)]  # the library's record of what it read
    assert got.meta["fingerprint"] == expected.meta["fingerprint"]
