"""Serve one camera of a recording as a DV network stream through dv-processing's own ``NetworkWriter``: what the
DV software publishes, for trying ``cvstereo live --dv`` and ``record --dv`` without cameras (and for their tests).

Run as ``python -m cvstereo.sensors.dvserve RECORDING.npz {left,right} PORT [--speed S] [--host H]``. The
process builds the camera's packets (:data:`SLICE_US` of stream time each), listens, prints ``ready`` and reads
one line from its standard input: the wall-clock start time (``time.time()`` seconds), so that two such
processes start together. Each packet is then written at ``start + (t - first t) / speed``, from the time a
client has stayed connected for :data:`SETTLE_S` on (so that the reader misses nothing); after the last one,
once the writer's queue is empty and the client has gone or had :data:`LINGER_S` to read the rest, the process
exits and the stream ends.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time

import numpy as np

__all__ = ["SLICE_US", "build_stores", "main", "serve"]

#: Stream time per packet written, us.
SLICE_US = 1_000

#: Longest wait for a client to connect, and for the writer to send what it queued, s.
WAIT_S = 30.0

#: A client connected this long is taken as the reader (not a look at the description), s.
SETTLE_S = 0.2

#: After the last packet left: time the client has to read what is still on its way, s.
LINGER_S = 3.0


def build_stores(dv, events: np.ndarray, slice_us: int = SLICE_US) -> list[tuple[int, object]]:
    """The events as (first time, dv EventStore) packets of ``slice_us`` stream time each (empty ones left out);
    built before streaming, since dv-processing takes events one by one from Python."""
    t = events["t"]
    if not t.size:
        return []
    edges = np.arange(int(t[0]), int(t[-1]) + slice_us + 1, slice_us)
    cuts = np.searchsorted(t, edges)
    out = []
    cols = [events[k].tolist() for k in ("t", "x", "y")]
    on = (events["p"] > 0).tolist()
    for lo, hi in itertools.pairwise(cuts):
        if hi > lo:
            store = dv.EventStore()
            push = store.push_back
            for i in range(lo, hi):
                push(cols[0][i], cols[1][i], cols[2][i], on[i])
            out.append((int(t[lo]), store))
    return out


def serve(events: np.ndarray, resolution: tuple[int, int], port: int, *, host: str = "127.0.0.1",
          speed: float = 1.0, name: str = "cvstereo_dvserve", kind: str = "events", start_line=None,
          log=sys.stdout, slice_us: int = SLICE_US) -> tuple[int, object]:
    """Stream ``events`` on ``host:port`` (see the module docstring); the number of events written, and the
    writer, still open: dv-processing's writer can wait for ever in its destructor (see :func:`main`).

    ``resolution`` is the size the stream's description states; ``kind="frames"`` publishes a frame stream
    instead, which carries none of the events (what a camera's frame output looks like to a reader).
    """
    import dv_processing as dv

    size = tuple(int(v) for v in resolution)
    if kind == "frames":
        events = events[:0]
        stream = dv.io.Stream.FrameStream(0, "frames", name, size)
    else:
        stream = dv.io.Stream.EventStream(0, "events", name, size)
    stores = build_stores(dv, events, slice_us)
    writer = dv.io.NetworkWriter(host, int(port), stream, 10, lambda code, message: None)
    print("ready", flush=True, file=log)
    start = float((start_line or sys.stdin.readline)().strip() or time.time())
    # A reader looks at the description first (a connection that goes at once), then connects to read: wait for
    # a client that stays.
    deadline, since = time.monotonic() + WAIT_S, None
    while time.monotonic() < deadline:
        if writer.getClientCount() == 0:
            since = None
        elif since is None:
            since = time.monotonic()
        elif time.monotonic() - since >= SETTLE_S:
            break
        time.sleep(0.001)
    start = max(start, time.time())
    first = stores[0][0] if stores else 0
    sent = 0
    for t0, store in stores:
        due = start + (t0 - first) / 1e6 / speed
        if (wait := due - time.time()) > 0:
            time.sleep(wait)
        writer.writeEvents(store)
        sent += store.size()
    deadline = time.monotonic() + WAIT_S
    while writer.getQueuedPacketCount() and time.monotonic() < deadline:
        time.sleep(0.005)
    # dv-processing's reader drops what it has not read yet when the writer leaves: stay until the client has
    # gone or has had LINGER_S to read what is still on its way.
    deadline = time.monotonic() + LINGER_S
    while writer.getClientCount() and time.monotonic() < deadline:
        time.sleep(0.005)
    return sent, writer


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cvstereo.sensors.dvserve", description=__doc__.splitlines()[0])
    parser.add_argument("recording")
    parser.add_argument("camera", choices=("left", "right"))
    parser.add_argument("port", type=int)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--speed", type=float, default=1.0, help="stream time per wall time")
    parser.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"), default=None,
                        help="the size the stream states (default: the recording's)")
    parser.add_argument("--slice-us", type=int, default=SLICE_US,
                        help=f"stream time per packet written, us (default {SLICE_US})")
    parser.add_argument("--stream", choices=("events", "frames"), default="events",
                        help="publish the events, or an (empty) frame stream")
    args = parser.parse_args(argv)
    from cvstereo.io.npz import read_recording_npz

    rec = read_recording_npz(args.recording)
    sent, _writer = serve(getattr(rec, args.camera), args.resolution or rec.resolution, args.port, host=args.host,
                 speed=args.speed, name=f"cvstereo_{args.camera}", kind=args.stream, slice_us=args.slice_us)
    print(f"sent {sent}", flush=True)
    # Out without dv-processing's teardown: its writer's destructor closes the connections, then can wait for
    # ever; leaving the process closes the sockets too, which ends the stream for its readers.
    os._exit(0)


if __name__ == "__main__":
    sys.exit(main())
