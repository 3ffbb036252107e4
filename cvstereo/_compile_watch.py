"""Numba compilations watched, said once on stderr and timed, and a method's kernels made ready before a clock.

The matchers' kernels are numba functions that numba caches on disk (:mod:`cvstereo._numba_cache`): the first
use on a machine compiles them, every later process loads them. :func:`prepare` runs a matcher on a small
built-in clip once per process and method, so that its kernels are compiled (or loaded) before the caller's
clock starts: :func:`cvstereo.matchers.registry.create_matcher` calls it, so ``match()``'s ``elapsed_s``, the
benchmark's figures and ``cvstereo live`` (which builds its matcher before it opens the sensors) never include
it. A compilation that happens says so once per group on stderr (:data:`COMPILE_MESSAGE`); loading from the
cache says nothing. :mod:`cvstereo.warmup` fills the cache for every method ahead of time.

This module imports no matcher, so that the registry can use it.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

__all__ = ["COMPILE_MESSAGE", "compile_seconds", "prepare", "tiny_clip", "watch_compiles"]

#: What is printed (once per group of kernels and process) when numba compiles instead of loading its cache.
COMPILE_MESSAGE = "compiling {group} kernels (first use, cached afterwards)..."
#: The clip :func:`prepare` runs: long enough for several 40 ms windows, events on both cameras that match.
CLIP_EVENTS, CLIP_US, CLIP_SHIFT_PX, CLIP_SIZE = 6000, 200_000, 8, (128, 128)
#: Packets the clip is fed in (the run core's default length).
CLIP_PACKET_US = 40_000


class _Watch:
    """The numba ``numba:compile`` listener: announces compilations and adds up their time (outermost only)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.depth = 0
        self.started = 0.0
        self.total = 0.0
        self.announced: set[str] = set()
        self.group: str | None = None  # the method being prepared, else told from the kernel's module

    def on_start(self, event) -> None:
        with self.lock:
            self.depth += 1
            if self.depth > 1:
                return  # a kernel compiling the kernels it calls: one compilation
            self.started = time.perf_counter()
            group = self.group or _module_group(getattr(event.data["dispatcher"].py_func, "__module__", ""))
            if group not in self.announced:
                self.announced.add(group)
                print(COMPILE_MESSAGE.format(group=group), file=sys.stderr, flush=True)

    def on_end(self, event) -> None:
        with self.lock:
            self.depth -= 1
            if self.depth == 0:
                self.total += time.perf_counter() - self.started


_WATCH = _Watch()
_REGISTERED = False
_PREPARED: set[tuple[str, str, bool]] = set()


def _module_group(module: str) -> str:
    """A kernel's group as the user knows it: its matcher's name, else the package part (``frames``)."""
    parts = module.split(".")
    if len(parts) > 3 and parts[1] == "matchers" and not parts[2].startswith("_"):
        return parts[2].replace("_", "-")
    return "shared matcher" if parts[1:3] == ["matchers", "_shared"] else " ".join(parts[1:2]) or module


def watch_compiles() -> None:
    """Listen to numba's compilations from now on in this process (idempotent): see the module's description."""
    global _REGISTERED
    if _REGISTERED:
        return
    from numba.core import event

    listener = type("CompileListener", (event.Listener,), {"on_start": lambda self, e: _WATCH.on_start(e),
                                                           "on_end": lambda self, e: _WATCH.on_end(e)})()
    event.register("numba:compile", listener)
    _REGISTERED = True


def compile_seconds() -> float:
    """Seconds this process has spent compiling kernels since :func:`watch_compiles` (0 while all load from the
    cache): a clock that subtracts its increase counts no compilation."""
    return _WATCH.total


def tiny_clip():
    """A small stereo recording that every matcher finds matches in: random textured events seen by the right
    camera :data:`CLIP_SHIFT_PX` px to the left, over :data:`CLIP_US` us (several windows)."""
    import numpy as np

    from cvstereo.model.events import make_events
    from cvstereo.model.recording import Recording

    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, CLIP_US, CLIP_EVENTS))
    x = rng.integers(CLIP_SHIFT_PX, CLIP_SIZE[0], CLIP_EVENTS)
    y = rng.integers(0, CLIP_SIZE[1], CLIP_EVENTS)
    p = rng.integers(0, 2, CLIP_EVENTS)
    right_t = np.sort(t + rng.integers(0, 200, CLIP_EVENTS))
    return Recording(make_events(t, x, y, p), make_events(right_t, x - CLIP_SHIFT_PX, y, p), resolution=CLIP_SIZE)


def prepare(method: str, param_set: str, build: Callable[[tuple[int, int]], object], *, parallel: bool = False) -> bool:
    """Compile (or load from the cache) the kernels of ``method`` under ``param_set``, once per process, by feeding
    :func:`tiny_clip` to ``build(resolution)`` (a new matcher of the clip's size) and flushing it.

    ``parallel``: ``build`` gives a matcher of more than one thread, whose parallel kernels are compiled apart
    from the serial ones (docs/guide/threads.md), so each path is prepared once.

    Returns
    -------
    bool
        True when this call ran the clip, False when the process had prepared them already.
    """
    key = (method, param_set, parallel)
    if key in _PREPARED:
        return False
    _PREPARED.add(key)
    watch_compiles()
    from cvstereo.model.events import iter_stereo_packets

    clip = tiny_clip()
    matcher = build(CLIP_SIZE)
    before, _WATCH.group = _WATCH.group, method
    try:
        for packet in iter_stereo_packets([(clip.left, None)], [(clip.right, None)], CLIP_PACKET_US):
            matcher.feed(packet.left, packet.right, until=packet.until)
        matcher.flush()
    finally:
        _WATCH.group = before
    return True
