"""The worker process that runs dv-processing's AEDAT4 reader for :mod:`cvstereo.io.aedat4`, and its frames.

dv-processing's batch reader can spin for ever on a damaged file (4 KB overwritten in the middle of a stream
keeps it at full CPU inside ``getNextEventBatch``), holding the GIL, so that neither a thread nor a signal
handler of the reading process can stop it. It therefore runs here, in a process of its own that the parent
(:mod:`cvstereo.io._watchdog`) kills on a stall, on Ctrl-C and on SIGTERM, and that streams the events back
through a pipe as they are decoded.

On Linux the parent forks and calls :func:`serve` (the decoder is imported already); elsewhere it runs this
file as a script (``python _aedat4_worker.py PARENT_PID FD FILE CAMERA LAYOUT`` with the pipe's write end
``FD`` inherited), so that it starts without importing cvstereo. A frame is :data:`FRAME_HEADER` (one kind
byte, then the payload's length) followed by the payload:

- :data:`OPENED`: the reader is open (it has read the file's packet table);
- :data:`EVENTS`: up to :data:`FRAME_EVENTS` events as packed records of ``LAYOUT`` (the parent's event dtype,
  as JSON);
- :data:`FAILED`: the decoder raised; the payload is its message (UTF-8);
- :data:`DONE`: the stream ended.
"""

from __future__ import annotations

import json
import os
import signal
import struct
import sys

#: One kind byte and the payload's length in bytes.
FRAME_HEADER = struct.Struct("<cQ")
OPENED, EVENTS, FAILED, DONE = b"O", b"E", b"F", b"D"

#: dv-processing's name of each event field (its EventStore's numpy() record).
DV_FIELDS = {"t": "timestamp", "x": "x", "y": "y", "p": "polarity"}

#: Events sent in one frame at most: dv-processing's batches (a few thousand events) are joined up to this, so
#: that the parent checks a few large chunks rather than many small ones (each check has a fixed cost).
FRAME_EVENTS = 1 << 17

#: prctl(PR_SET_PDEATHSIG): Linux sends the child a signal when its parent dies.
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent_pid: int) -> None:
    """Ask Linux to kill this process if the parent dies (a SIGKILLed parent cannot stop a spinning decoder);
    elsewhere, or without the call, the parent's own cleanup is the only stop."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent_pid:  # the parent died before the request
        os._exit(1)


def _send(out, kind: bytes, payload=b"") -> None:
    out.write(FRAME_HEADER.pack(kind, len(payload)))
    if len(payload):
        out.write(payload)


def serve(fd: int, parent_pid: int, path: str, camera: str, layout: str) -> int:
    """Decode one camera's events of an AEDAT4 file and send them as frames on ``fd``; the exit code.

    Ctrl-C reaches the whole process group: the parent decides when the read stops (and kills this process),
    so SIGINT is ignored here and SIGTERM does its default (a forked worker inherits the CLI's handlers).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL)
    _die_with_parent(parent_pid)
    with open(fd, "wb", closefd=True) as out:
        try:
            import dv_processing as dv
            import numpy as np

            dtype = np.dtype([tuple(field) for field in json.loads(layout)])
            reader = dv.io.MonoCameraRecording(path, camera)
            _send(out, OPENED)
            frame, filled = np.empty(FRAME_EVENTS, dtype), 0
            while (batch := reader.getNextEventBatch()) is not None:
                raw = batch.numpy()
                for lo in range(0, raw.shape[0], FRAME_EVENTS):
                    part = raw[lo:lo + FRAME_EVENTS]
                    if filled + part.shape[0] > FRAME_EVENTS:
                        _send(out, EVENTS, frame[:filled].view(np.uint8).data)
                        filled = 0
                    for ours, theirs in DV_FIELDS.items():
                        frame[ours][filled:filled + part.shape[0]] = part[theirs]
                    filled += part.shape[0]
            if filled:
                _send(out, EVENTS, frame[:filled].view(np.uint8).data)
            _send(out, DONE)
        except BrokenPipeError:  # the parent stopped reading
            return 0
        except Exception as exc:  # everything the decoder raises goes to the parent, which words the error
            _send(out, FAILED, f"{type(exc).__name__}: {exc}".encode("utf-8", "replace"))
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(serve(int(sys.argv[2]), int(sys.argv[1]), *sys.argv[3:6]))
