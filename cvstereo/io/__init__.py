"""Reading and writing recordings and matches.

:func:`read_recording` and :func:`write_recording` choose the format from ``format=`` or from the file
(extension, then content). Per-format modules: :mod:`~cvstereo.io.npz`, :mod:`~cvstereo.io.edvs_text`,
:mod:`~cvstereo.io.aedat2`.
"""

from __future__ import annotations

import os
from pathlib import Path

from cvstereo.io.npz import read_matches, read_recording_npz, write_matches, write_recording_npz
from cvstereo.recording import Recording

#: Format names accepted by ``format=`` and the CLI's ``--format``.
FORMATS = ("npz",)


def detect_format(path: str | os.PathLike) -> str:
    """Guess a file's format from its extension.

    Raises
    ------
    ValueError
        Unknown extension; the message lists the ``--format`` values.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".npz":
        return "npz"
    raise ValueError(f"{path}: cannot tell the format from '{suffix}'; give --format ({', '.join(FORMATS)}).")


def read_recording(path: str | os.PathLike, right: str | os.PathLike | None = None, *, format: str | None = None,
                   **options) -> Recording:
    """Read a stereo recording in any supported format.

    Parameters
    ----------
    path : path-like
        The recording, or the left camera's file for one-file-per-camera formats.
    right : path-like, optional
        The right camera's file.
    format : str, optional
        One of :data:`FORMATS`; default: from the extension.
    **options
        Format options (``left_retina``, ``one_based``, ``resolution``, ...).

    Returns
    -------
    Recording
    """
    fmt = format or detect_format(path)
    if fmt == "npz":
        if right is not None or options:
            raise ValueError(f"{path}: an .npz recording holds both cameras and takes no options.")
        return read_recording_npz(path)
    raise ValueError(f"unknown format '{fmt}'; choose one of: {', '.join(FORMATS)}.")


def write_recording(path: str | os.PathLike, recording: Recording, *, format: str | None = None) -> None:
    """Write a recording (atomically) in the format given or implied by the extension."""
    fmt = format or detect_format(path)
    if fmt == "npz":
        return write_recording_npz(path, recording)
    raise ValueError(f"cannot write format '{fmt}'; choose one of: {', '.join(FORMATS)}.")


__all__ = [
    "FORMATS",
    "detect_format",
    "read_matches",
    "read_recording",
    "read_recording_npz",
    "write_matches",
    "write_recording",
    "write_recording_npz",
]
