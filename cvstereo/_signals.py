"""Stop signals: SIGTERM and SIGHUP as a stop like Ctrl-C, and sections a stop must not cut in two (a Dask
cluster starting or closing)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

#: Signals that stop a program and that :func:`held_stop_signals` holds.
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
#: Of those, the ones Python leaves at their default action (end the process at once, no cleanup).
TERMINATING_SIGNALS = tuple(s for s in STOP_SIGNALS if s != signal.SIGINT)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived: raised in the main thread so that cleanup (``finally``, ``except
    BaseException``) runs as for Ctrl-C; code that stops gracefully on KeyboardInterrupt stops so here too."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def stop_exception(signum: int) -> KeyboardInterrupt:
    """The exception a stop by ``signum`` raises: KeyboardInterrupt for SIGINT, :class:`Terminated` otherwise."""
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


def signal_of(stop: KeyboardInterrupt) -> int:
    """The signal a stop exception stands for (SIGINT for a plain KeyboardInterrupt)."""
    return stop.signum if isinstance(stop, Terminated) else signal.SIGINT


@contextlib.contextmanager
def held_stop_signals() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP while the block runs; deliver them when it ends.

    For a section that a stop would leave half done with nothing to undo it: a Dask ``LocalCluster`` stopped
    while it starts is registered but never returned, and Dask's exit hook then fails on it with a traceback.
    Held, the stop arrives once the cluster exists, and the code around it can close it. Only signals with a
    Python handler are held (a default action or an ignored signal stays as it is); outside the main thread the
    block just runs.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    previous = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    previous = {s: h for s, h in previous.items() if callable(h)}
    for s in previous:
        signal.signal(s, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        for s in held:
            signal.raise_signal(s)


@contextlib.contextmanager
def sigint_blocked_for_children() -> Iterator[None]:
    """Block SIGINT in this thread while the block starts threads and processes: they inherit the block.

    A Ctrl-C at the terminal reaches every process of the group; worker processes started here then leave it to
    this process, which still receives it (through another thread, or this one once the block ends) and closes
    them, rather than each printing its own KeyboardInterrupt. Python's multiprocessing resource tracker, when
    it starts, unblocks SIGINT in the thread that starts it, so it is started first.
    """
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    previous_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous_mask)
