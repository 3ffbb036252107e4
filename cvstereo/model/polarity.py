"""Polarity: what an event's ``p`` means, the polarity modes of the matchers, and the frame slot of each.

One rule everywhere: an array indexed by polarity is indexed by ``p``. ``p = 1`` (:data:`ON`, brightness up,
sign +1) and ``p = 0`` (:data:`OFF`, sign -1), so ``counts[ON]`` are the ON counts
(:func:`cvstereo.frames.accumulate.polarity_counts`) and, with separate frames, frame ``p`` holds the events of
polarity ``p``: the OFF frame is slot 0, the ON frame slot 1, in the frames of a window
(:mod:`cvstereo.frames.accumulate`) and in the dynamic frames (:mod:`cvstereo.frames.dynamic`) alike.

A matcher's ``polarity`` parameter (docs/formats.md's variant names of ``frame`` and ``event-time``) says how ON and
OFF events enter its frames:

- ``shared``: one frame, ON adds +1 and OFF -1 (the thesis' default);
- ``separate``: one frame per polarity (slot = p), each matched on its own;
- ``on`` / ``off``: one frame of that polarity only; the other polarity's events are dropped.

>>> slot_of_p("separate")[1].tolist(), slot_of_p("on")[1].tolist()
([0, 1], [-1, 0])
>>> frame_signs("separate")
((-1,), (1,))
"""

from __future__ import annotations

from typing import Literal

import numpy as np

__all__ = ["OFF", "ON", "POLARITY_MODES", "Polarity", "check_polarity", "frame_signs", "sign", "slot_of_p"]

#: ``p`` of an ON event (brightness up) and of an OFF event.
ON, OFF = 1, 0

#: The polarity modes (a matcher's ``polarity`` parameter).
Polarity = Literal["shared", "separate", "on", "off"]
POLARITY_MODES: tuple[str, ...] = ("shared", "separate", "on", "off")

# The frames of each mode in slot order, each as the event signs it holds (+1 ON, -1 OFF).
_FRAME_SIGNS: dict[str, tuple[tuple[int, ...], ...]] = {
    "shared": ((1, -1),),
    "separate": ((-1,), (1,)),
    "on": ((1,),),
    "off": ((-1,),),
}


def sign(p):
    """The sign an event of polarity ``p`` adds to a frame: +1.0 for ON (``p = 1``), -1.0 for OFF (``p = 0``).

    The one place where docs/formats.md's stored ``p`` (1 / 0) becomes the thesis' sign s (+1 / -1,
    docs/algorithms.md). ``p`` is a scalar or an array (an array of signs comes back, float64). Plain arithmetic
    rather than a branch, so that numba kernels compile this same function
    (:data:`cvstereo.frames.accumulate.polarity_sign`).

    >>> sign(ON), sign(OFF)
    (1.0, -1.0)
    >>> sign(np.array([1, 0, 1], np.int8)).tolist()
    [1.0, -1.0, 1.0]
    """
    return 2.0 * (p > OFF) - 1.0


def check_polarity(mode: str, where: str = "polarity") -> None:
    """Raise ValueError unless ``mode`` is one of :data:`POLARITY_MODES`; ``where`` names the parameter's owner."""
    if mode not in _FRAME_SIGNS:
        raise ValueError(f"{where}: polarity must be one of {', '.join(POLARITY_MODES)}; got {mode!r}.")


def frame_signs(mode: str) -> tuple[tuple[int, ...], ...]:
    """The frames of a polarity mode, in slot order, as the signs of the events each holds (+1 ON, -1 OFF).

    Raises
    ------
    ValueError
        Unknown mode; the message lists the modes.
    """
    check_polarity(mode)
    return _FRAME_SIGNS[mode]


def slot_of_p(mode: str) -> tuple[int, np.ndarray]:
    """Number of frames per camera, and the frame slot of an event of each ``p`` under a polarity mode.

    Parameters
    ----------
    mode : {"shared", "separate", "on", "off"}

    Returns
    -------
    n_frames : int
        1, or 2 for ``"separate"``.
    slots : (2,) int64 ndarray
        ``slots[p]``: the frame of an event with that ``p``; -1 where that polarity is dropped.
    """
    slots = np.full(2, -1, dtype=np.int64)
    signs_of_frames = frame_signs(mode)
    for slot, signs in enumerate(signs_of_frames):
        for s in signs:
            slots[ON if s > 0 else OFF] = slot
    return len(signs_of_frames), slots
