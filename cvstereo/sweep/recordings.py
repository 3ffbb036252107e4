"""The recordings of a sweep: specs (files, globs, presets, suites) turned into files the workers can read.

Every spec is checked before any is simulated or hashed: a file must be a regular file in a format the
readers know (a FIFO would block the hashing, ``/dev/zero`` never end), a preset must exist with a length
the simulator accepts. A spec that fails is refused in one line naming it; nothing has run yet.
"""

from __future__ import annotations

import glob
import math
import os
from collections.abc import Callable, Iterable

__all__ = ["check_recording_file", "resolve_recordings"]

#: A checked spec: generates (presets, suites) or lists (files) its recordings when called.
_Source = Callable[[bool], list[str]]


def resolve_recordings(specs: Iterable[str], *, progress: bool = False) -> list[str]:
    """Turn recording specs into file paths, in the order given (duplicates dropped).

    A spec is a path, a glob (``data/*.npz``), ``preset:NAME`` or ``preset:NAME:SECONDS`` (a simulated
    preset, generated once and cached, see :func:`cvstereo.simulate.presets.cached_preset`), or
    ``suite:NAME`` (every recording of a simulated suite; ``suite:NAME:tune`` or ``suite:NAME:eval`` one half
    of a suite that has a tuning and an evaluation half). Every spec is checked before any recording is
    generated, so that a typo in the last one does not cost the simulation of the first.

    Raises
    ------
    FileNotFoundError
        A path or glob that matches nothing.
    IsADirectoryError, OSError
        A path that is a directory, FIFO, device or socket (the readers' message).
    ValueError
        A file whose format cannot be told, an unknown preset or suite, or a length the simulator refuses.
    """
    sources = [_source(spec) for spec in specs]
    out: list[str] = []
    for source in sources:
        out.extend(source(progress))
    return list(dict.fromkeys(out))


def _source(spec: str) -> _Source:
    if spec.startswith("preset:"):
        return _preset(spec)
    if spec.startswith("suite:"):
        return _suite(spec)
    if any(ch in spec for ch in "*?["):
        found = sorted(glob.glob(spec))
        if not found:
            raise FileNotFoundError(f"recording pattern '{spec}' matches no file.")
    else:
        if not os.path.exists(spec):
            raise FileNotFoundError(f"recording '{spec}' does not exist.")
        found = [spec]
    for path in found:
        check_recording_file(path)
    return lambda progress: found


def check_recording_file(path: str | os.PathLike) -> None:
    """Refuse, as the readers do, a recording that is no regular file or whose format cannot be told."""
    from cvstereo.io import detect_format
    from cvstereo.io.files import require_regular_file

    require_regular_file(path)
    detect_format(path)


def _preset(spec: str) -> _Source:
    """``preset:NAME[:SECONDS]``, checked: a known preset and a length in the simulator's range."""
    from cvstereo.simulate.core import MAX_SECONDS
    from cvstereo.simulate.presets import cached_preset, get_preset

    _, *parts = spec.split(":")
    if len(parts) not in (1, 2):
        raise ValueError(f"recording '{spec}': write preset:NAME or preset:NAME:SECONDS.")
    try:
        get_preset(parts[0])
    except ValueError as exc:
        raise ValueError(f"recording '{spec}': {exc}") from None
    seconds = None
    if len(parts) == 2:
        try:
            seconds = float(parts[1])
        except ValueError:
            seconds = math.nan
        if not (math.isfinite(seconds) and 0 < seconds <= MAX_SECONDS):
            raise ValueError(f"recording '{spec}': seconds must be a number in (0, {MAX_SECONDS:g}], got "
                             f"'{parts[1]}'.")
    return lambda progress: [os.fspath(cached_preset(parts[0], seconds=seconds, progress=progress))]


def _suite(spec: str) -> _Source:
    """``suite:NAME[:HALF]``, checked by the simulator itself (a known suite, a half it has) without generating
    a recording (``only=[]``)."""
    from cvstereo.simulate import suite_recordings

    name, _, half = spec.partition(":")[2].partition(":")  # NAME, or NAME:HALF (tune, eval)
    extra = {"half": half} if half else {}
    try:
        suite_recordings(name, only=[], **extra)
    except ValueError as exc:
        raise ValueError(f"recording '{spec}': {exc}") from None

    def generate(progress: bool) -> list[str]:
        return [os.fspath(path) for _, path in suite_recordings(name, progress=progress, **extra)]

    return generate
