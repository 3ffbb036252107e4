"""A third-party decoder in a worker process that the reading process can always stop.

A decoder that spins inside compiled code while holding the GIL cannot be stopped from its own process: no
thread runs, and a Python signal handler (the CLI's Ctrl-C and SIGTERM) never gets its turn. Such a decoder runs
in a worker process (:mod:`cvstereo.io._aedat4_worker`) that sends its output in frames through a pipe; the
parent waits for each frame in short slices, so that Ctrl-C and SIGTERM are handled at once, and kills the worker

- when it burns :data:`STALL_CPU_S` of CPU time without sending anything (a decoder answers a batch in
  milliseconds; a damaged file makes it spin at full speed for ever; its first answer may be given more, as
  opening a file can take time in proportion to its size), or :data:`STALL_WALL_S` of wall time where its CPU
  time cannot be read or it sits blocked;
- when the consumer stops early, is interrupted, or fails (``finally``), so no worker outlives its read.

CPU time rather than wall time decides a stall, because a loaded machine stretches wall time but a spinning
decoder burns CPU whatever the load.

On Linux the worker is forked: it inherits the decoder already imported, where a fresh interpreter would spend
about a quarter of a 10 M-event read importing numpy and the decoder again. The fork happens while other threads
may exist (numpy's BLAS pool, a progress bar's monitor); the child runs only the decoder and numpy copies and
leaves with ``os._exit``, and a lock left held by another thread could only block it, which the wall limit turns
into an error. Elsewhere the worker is started as a script.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import tempfile
import time
import warnings
from collections.abc import Iterator

from cvstereo.errors import CorruptFileError
from cvstereo.io import _aedat4_worker as worker
from cvstereo.io._aedat4_worker import DONE, FAILED, FRAME_HEADER, OPENED

#: CPU seconds a worker may burn without sending a frame before it counts as stalled (hundreds of times what a
#: batch takes; on a machine loaded ten times over its cores this is still reached within about 5 s).
STALL_CPU_S = 1.0
#: Wall seconds without a frame after which a worker counts as stalled whatever its CPU time.
STALL_WALL_S = 30.0
#: How long the parent waits at a time (so that signals are handled within this).
POLL_S = 0.1
#: The end of the worker's stderr quoted when it dies.
_STDERR_TAIL = 300
#: Bytes the pipe from the worker holds (Linux; with the default 64 KiB the worker waits for the parent at every
#: 64 KiB, a context switch each).
PIPE_BYTES = 1 << 20
#: fcntl's F_SETPIPE_SZ (Linux), for Pythons whose fcntl module does not name it.
_F_SETPIPE_SZ = 1031
#: Fork the worker (Linux) rather than start it as a script (elsewhere); see the module doc.
FORK = sys.platform.startswith("linux")


def _widen_pipe(fd: int) -> None:
    """Let the pipe hold :data:`PIPE_BYTES` where the system allows it (it keeps its size otherwise)."""
    try:
        import fcntl

        fcntl.fcntl(fd, getattr(fcntl, "F_SETPIPE_SZ", _F_SETPIPE_SZ), PIPE_BYTES)
    except (ImportError, OSError):
        pass


def _cpu_seconds(pid: int) -> float | None:
    """User plus system CPU time of process ``pid`` (Linux /proc), or None where it cannot be read."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            fields = fh.read().rsplit(b")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def _start(args: list[str], stderr) -> tuple[int, int]:
    """Start the worker on ``args``; return its pid and the read end of its pipe."""
    read_fd, write_fd = os.pipe()
    _widen_pipe(read_fd)
    parent = os.getpid()
    try:
        if FORK:
            with warnings.catch_warnings():  # Python >= 3.12 warns of fork with threads: see the module doc
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
            if pid == 0:  # the worker: never returns into the parent's stack
                code = 1
                try:
                    os.close(read_fd)
                    os.dup2(stderr.fileno(), 2)
                    code = worker.serve(write_fd, parent, *args)
                finally:
                    os._exit(code)
        else:
            os.set_inheritable(write_fd, True)
            actions = [(os.POSIX_SPAWN_OPEN, 0, os.devnull, os.O_RDONLY, 0),
                       (os.POSIX_SPAWN_OPEN, 1, os.devnull, os.O_WRONLY, 0), (os.POSIX_SPAWN_DUP2, stderr.fileno(), 2)]
            pid = os.posix_spawn(sys.executable, [sys.executable, worker.__file__, str(parent), str(write_fd), *args],
                                 os.environ, file_actions=actions)
    except BaseException:
        os.close(read_fd)
        raise
    finally:
        os.close(write_fd)
    return pid, read_fd


class _Frames:
    """Frames read from a worker's pipe, with the stall rules of the module."""

    def __init__(self, pid: int, fd: int, source: str, decoder: str, first_cpu_s: float):
        self.pid, self.fd, self.source, self.decoder = pid, fd, source, decoder
        self.limit = first_cpu_s  # CPU seconds allowed before the next frame (STALL_CPU_S after the first)
        self.poller = select.poll()
        self.poller.register(fd, select.POLLIN | select.POLLHUP | select.POLLERR)
        self.wall = time.monotonic()  # when the last bytes arrived
        self.cpu: float | None = None  # the worker's CPU time at the first wait since then
        self.progressed = True

    def _stalled(self) -> str | None:
        """Why the worker counts as stalled after a wait without bytes, or None.

        The CPU baseline is taken at the first empty wait after progress, not at every read: reading /proc for
        each of the thousands of reads of a long file would cost more than the watch is worth.
        """
        cpu = _cpu_seconds(self.pid)
        if self.progressed or self.cpu is None:
            self.cpu, self.progressed = cpu, False
        elif cpu is not None and cpu - self.cpu >= self.limit:
            return (f"burnt {cpu - self.cpu:.1f} s of CPU time without an answer and was stopped; the file is "
                    "damaged (a packet cannot be decoded).")
        if time.monotonic() - self.wall >= STALL_WALL_S:
            return (f"gave no answer for {STALL_WALL_S:g} s and was stopped; the file is damaged, or cannot be "
                    "read from where it is.")
        return None

    def read_exact(self, size: int) -> bytearray | None:
        """``size`` bytes, or None at the end of the stream; raises when the worker stalls."""
        buf = bytearray(size)
        view, got = memoryview(buf), 0
        while got < size:
            if not self.poller.poll(POLL_S * 1000):
                why = self._stalled()
                if why:
                    raise CorruptFileError(f"{self.source}: {self.decoder} {why}")
                continue
            n = os.readv(self.fd, [view[got:]])
            if n == 0:
                return None
            got += n
            self.wall, self.progressed = time.monotonic(), True
        return buf

    def __iter__(self) -> Iterator[tuple[bytes, bytearray]]:
        while True:
            header = self.read_exact(FRAME_HEADER.size)
            if header is None:
                raise CorruptFileError(f"{self.source}: {self.decoder} ended without finishing ({self._death()}); "
                                       "the file is damaged or the decoder crashed.")
            kind, size = FRAME_HEADER.unpack(header)
            self.limit = STALL_CPU_S
            payload = self.read_exact(size) if size else bytearray()
            if payload is None:
                raise CorruptFileError(f"{self.source}: {self.decoder} stopped in the middle of a batch "
                                       f"({self._death()}).")
            if kind == DONE:
                return
            if kind == FAILED:
                raise CorruptFileError(f"{self.source}: {self.decoder} failed "
                                       f"({payload.decode('utf-8', 'replace').strip()}); the file is damaged or "
                                       "truncated.")
            if kind != OPENED:
                yield kind, payload

    def _death(self) -> str:
        """How the worker ended (it closed its pipe: it has ended, or is about to)."""
        deadline = time.monotonic() + POLL_S * 50
        while time.monotonic() < deadline:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.pid = 0  # reaped
                code = os.waitstatus_to_exitcode(status)
                return f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
            time.sleep(POLL_S / 10)
        return "no exit code"


def _stop(pid: int) -> None:
    """Kill and reap the worker (SIGKILL: a spinning decoder has nothing to save, and may not see SIGTERM)."""
    if not pid:
        return
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    os.waitpid(pid, 0)


def worker_frames(args: list[str], *, source: str, decoder: str,
                  open_cpu_s: float = 0.0) -> Iterator[tuple[bytes, bytearray]]:
    """Run the AEDAT4 worker (:mod:`cvstereo.io._aedat4_worker`) on ``args`` and yield its frames.

    The worker is killed when the consumer stops, fails or is interrupted, and when it stalls (module doc).

    Parameters
    ----------
    args : list of str
        The worker's arguments after the parent's pid: file, camera, layout.
    source : str
        Named first in error messages (the file being read).
    decoder : str
        What the worker runs, for messages ("dv-processing's AEDAT4 reader").
    open_cpu_s : float, keyword-only
        CPU seconds allowed before the first frame on top of :data:`STALL_CPU_S` (opening a large file takes
        longer than a batch).

    Yields
    ------
    (kind, payload)
        Every frame but OPENED and DONE.

    Raises
    ------
    CorruptFileError
        The worker reported a failure, stalled, or died.
    """
    with tempfile.TemporaryFile() as stderr:
        # stderr goes to a file, never to a pipe nobody reads (a full pipe would block the worker) nor to the
        # terminal (the CLI prints one line per error).
        pid, fd = _start(args, stderr)
        frames = _Frames(pid, fd, source, decoder, STALL_CPU_S + open_cpu_s)
        try:
            yield from frames
        except CorruptFileError as exc:
            tail = _tail(stderr)
            raise CorruptFileError(f"{exc}{' Its last words: ' + tail if tail else ''}") from None
        finally:
            os.close(fd)
            _stop(frames.pid)


def _tail(stderr) -> str:
    stderr.seek(0, os.SEEK_END)
    stderr.seek(max(0, stderr.tell() - _STDERR_TAIL))
    lines = stderr.read().decode("utf-8", "replace").strip().splitlines()
    return lines[-1] if lines else ""
