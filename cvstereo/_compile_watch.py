"""Numba compilations watched, said once on stderr and timed, and a matcher's kernels made ready before a clock.

The matchers' kernels are numba functions that numba caches on disk (:mod:`cvstereo._numba_cache`): the first
use on a machine compiles them, every later process loads them. :func:`prepare` runs a copy of a matcher just
built on a small built-in clip, once per process and compiled path (:func:`compiled_path`: its class, variant,
the parameter values that choose branches and its thread count), so that the kernels that very matcher runs are
compiled (or loaded) before the caller's clock starts: :func:`cvstereo.matchers.registry.create_matcher` calls
it, so ``match()``'s ``elapsed_s``, the benchmark's figures and ``cvstereo live`` (which builds its matcher
before it opens the sensors) never include it. A compilation that happens says so once per group on stderr
(:data:`COMPILE_MESSAGE`); loading from the cache says nothing. :mod:`cvstereo.warmup` fills the cache for
every method ahead of time.

This module imports no matcher, so that the registry can use it.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import sys
import threading
import time

__all__ = ["COMPILE_MESSAGE", "compile_seconds", "compiled_path", "prepare", "tiny_clip", "watch_compiles"]

#: What is printed (once per group of kernels and process) when numba compiles instead of loading its cache.
COMPILE_MESSAGE = "compiling {group} kernels (first use, cached afterwards)..."
#: The clip :func:`prepare` runs: long enough for several 40 ms windows, events on both cameras that match
#: (shifted by CLIP_SHIFT_PX, or a quarter of a narrower sensor's width).
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
_PREPARED: set[tuple] = set()


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


def tiny_clip(resolution: tuple[int, int] = CLIP_SIZE):
    """A small stereo recording that every matcher finds matches in: random textured events seen by the right
    camera :data:`CLIP_SHIFT_PX` px to the left (a quarter of a narrower sensor), over :data:`CLIP_US` us
    (several windows), on a sensor of ``resolution`` (width, height)."""
    import numpy as np

    from cvstereo.model.events import make_events
    from cvstereo.model.recording import Recording

    width, height = int(resolution[0]), int(resolution[1])
    shift = min(CLIP_SHIFT_PX, width // 4)
    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, CLIP_US, CLIP_EVENTS))
    x = rng.integers(shift, width, CLIP_EVENTS)
    y = rng.integers(0, height, CLIP_EVENTS)
    p = rng.integers(0, 2, CLIP_EVENTS)
    right_t = np.sort(t + rng.integers(0, 200, CLIP_EVENTS))
    return Recording(make_events(t, x, y, p), make_events(right_t, x - shift, y, p), resolution=(width, height))


def compiled_path(matcher) -> tuple:
    """What selects the compiled kernels ``matcher`` runs: its class, each parameter's type and, for numbers,
    their sign (a scale of 0 switches a stage off; a size only goes into the kernels as an argument), the other
    parameters as they are (variant choices, flags), and whether it runs on more than one thread (the parallel
    kernels are compiled apart; every count above one runs the same ones).

    Two matchers with the same path run the same kernels with the same argument types: preparing one prepares
    both. The built-in matchers choose kernels by strings, flags and zeros only (a count such as fused's
    ``sgm_paths`` is a kernel argument); preparing per parameter value instead would run the clip again for every
    value a sweep tries.
    """
    params = matcher.params
    fields = [(f.name, _branch_value(getattr(params, f.name))) for f in dataclasses.fields(params)]
    return (type(matcher).__module__, type(matcher).__qualname__, tuple(fields),
            (getattr(matcher, "threads", None) or 1) > 1)


def _branch_value(value) -> object:
    """The part of a parameter value that can choose a compiled branch (see :func:`compiled_path`)."""
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, int | float):
        return type(value).__name__, "nan" if math.isnan(value) else (value > 0) - (value < 0)
    return type(value).__name__, repr(value)  # anything else (a tuple of values): as it is


def _twin(matcher):
    """A copy of ``matcher`` as it is, to feed without touching it: a deep copy, or where it holds an object of
    a C library that cannot be copied (OpenCV's, dv-processing's), one built anew from its class, parameters and
    resolution that gets its public attributes (the parameter set, the thread count)."""
    try:
        return copy.deepcopy(matcher)
    except TypeError:
        twin = type(matcher)(matcher.params, resolution=matcher.resolution)
        for name, value in vars(matcher).items():
            if not name.startswith("_"):
                setattr(twin, name, value)
        return twin


def prepare(matcher, group: str) -> bool:
    """Compile (or load from the cache) the kernels ``matcher`` runs, once per process and :func:`compiled_path`,
    by feeding :func:`tiny_clip` (at the matcher's resolution) to a copy of it and flushing the copy.

    ``matcher`` itself is left as it was (nothing fed, no watermark). A compilation that happens meanwhile is
    announced under ``group`` (the method's name).

    Returns
    -------
    bool
        True when this call ran the clip, False when the process had prepared that path already.
    """
    key = compiled_path(matcher)
    if key in _PREPARED:
        return False
    watch_compiles()
    from cvstereo.model.events import iter_stereo_packets

    clip = tiny_clip(matcher.resolution)
    twin = _twin(matcher)
    before, _WATCH.group = _WATCH.group, group
    try:
        for packet in iter_stereo_packets([(clip.left, None)], [(clip.right, None)], CLIP_PACKET_US):
            twin.feed(packet.left, packet.right, until=packet.until)
        twin.flush()
    finally:
        _WATCH.group = before
    _PREPARED.add(key)
    return True
