"""eDVS text files, the writers: one file per camera (``t x y p``) or both in one merged file with the retina id.

The header comments they write (``# resolution``, ``# fields``, ``# left_retina``) are what
:mod:`cvstereo.io.edvs_text`'s readers take back.
"""


import os

import numpy as np

from cvstereo.io.atomic import atomic_path
from cvstereo.io.edvs_text_parse import CHUNK_LINES
from cvstereo.model.events import DEFAULT_RESOLUTION, validate_events
from cvstereo.model.recording import Recording

__all__ = ["write_edvs_merged", "write_edvs_pair", "write_edvs_text"]


def write_edvs_text(path: str | os.PathLike, events: np.ndarray, *,
                    resolution: tuple[int, int] = DEFAULT_RESOLUTION) -> None:
    """Write one camera's events as a four-column text file (atomically).

    Parameters
    ----------
    path : path-like
    events : (N,) ndarray of EVENT_DTYPE
    resolution : (width, height), keyword-only
        Stated in the ``# resolution`` header.
    """
    validate_events(events, resolution=resolution, source=f"writing {path}")
    _write_rows(path, ["fields t x y p", "t in microseconds, p 1 = ON, 0 = OFF", _resolution_line(resolution)],
                [events["t"], events["x"], events["y"], events["p"]])


def write_edvs_pair(left_path: str | os.PathLike, right_path: str | os.PathLike, recording: Recording) -> None:
    """Write a stereo recording as two single-camera text files (each atomically)."""
    write_edvs_text(left_path, recording.left, resolution=recording.resolution)
    write_edvs_text(right_path, recording.right, resolution=recording.resolution)


def write_edvs_merged(path: str | os.PathLike, recording: Recording, *, left_retina: int = 0) -> None:
    """Write a stereo recording as one merged five-column text file (atomically), in time order.

    Parameters
    ----------
    path : path-like
    recording : Recording
    left_retina : {0, 1}, keyword-only
        Retina id given to the left camera; stated in the ``# left_retina`` header so readers need not
        detect it.
    """
    if left_retina not in (0, 1):
        raise ValueError(f"left_retina must be 0 or 1, got {left_retina!r}.")
    both = np.concatenate([recording.left, recording.right])
    retina = np.repeat(np.array([left_retina, 1 - left_retina], np.int8), [recording.left.size, recording.right.size])
    order = np.argsort(both["t"], kind="stable")
    both, retina = both[order], retina[order]
    _write_rows(path, ["fields t x y p retina", "t in microseconds, p 1 = ON, 0 = OFF, retina = camera id",
                       _resolution_line(recording.resolution), f"left_retina {left_retina}"],
                [both["t"], both["x"], both["y"], both["p"], retina])


def _resolution_line(resolution) -> str:
    return f"resolution {int(resolution[0])} {int(resolution[1])}"


def _write_rows(path, header: list[str], columns: list[np.ndarray], chunk_rows: int = CHUNK_LINES) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", encoding="ascii", newline="\n") as fh:
        fh.write("".join(f"# {line}\n" for line in ["eDVS text recording written by cvstereo", *header]))
        n = len(columns[0])
        for start in range(0, n, chunk_rows):
            block = np.column_stack([np.asarray(c[start:start + chunk_rows], np.int64) for c in columns])
            np.savetxt(fh, block, fmt="%d")
