"""DV network streams for the tests: each camera of a recording served by dv-processing's own NetworkWriter in a
process of its own (``python -m cvstereo.sensors.dvserve``).

A process, not a thread of the test: dv-processing's writer, destroyed while a reader of the same process is
connected to it, waits for ever holding the GIL, and the reader's own process is the point of these tests.
"""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

#: Wall time between the writers being told to start and their first packet, s: the reader connects meanwhile
#: (a writer waits for its first client in any case).
LEAD_S = 0.3
#: Stream time per packet the tests' writers send, us.
SLICE_US = 10_000


def free_port() -> int:
    """A TCP port nothing listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def served(recording: Path, *, speed: float = 2.0, slice_us: int = SLICE_US, cameras=("left", "right"),
           extra=((), ())) -> Iterator[list[str]]:
    """Serve ``cameras`` of ``recording`` (``extra``: more dvserve options per camera); yield their addresses
    ``tcp://127.0.0.1:PORT``. The writers are ready (listening) when this yields, and killed afterwards.

    ``slice_us`` (10 ms of stream time a packet) and ``speed``: few packets a second, because dv-processing's
    reader drops packets it is not asked for in time, which a test worker sharing its cores with another may
    not be (a loss of one packet in a clean-clone run at 1 ms a packet and 4x real time); the 1 M events/s
    case is bench/bench_dv_live.py's."""
    procs, addresses = [], []
    try:
        for cam, more in zip(cameras, extra, strict=True):
            port = free_port()
            procs.append(subprocess.Popen([sys.executable, "-m", "cvstereo.sensors.dvserve", str(recording), cam,
                                           str(port), "--speed", str(speed), "--slice-us", str(slice_us), *more],
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True))
            addresses.append(f"tcp://127.0.0.1:{port}")
        for proc in procs:
            assert proc.stdout.readline().strip() == "ready", "the DV writer did not start"
        start = time.time() + LEAD_S
        for proc in procs:
            proc.stdin.write(f"{start}\n")
            proc.stdin.flush()
        yield addresses
    finally:
        for proc in procs:
            proc.kill()
            proc.communicate()  # and its pipes closed
