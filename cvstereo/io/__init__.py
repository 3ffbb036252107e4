"""Reading and writing recordings and matches.

:func:`read_recording`, :func:`open_recording` (streaming) and :func:`write_recording` choose the format
from ``format=`` or from the file (content, then extension; :func:`detect_format`). Per-format modules:
:mod:`~cvstereo.io.npz`, :mod:`~cvstereo.io.edvs_text`, :mod:`~cvstereo.io.aedat2`; the streaming object
is :class:`~cvstereo.io.stream.RecordingStream`.
"""

from __future__ import annotations

import os
from pathlib import Path

from cvstereo.io._source import require_regular_file
from cvstereo.io.aedat2 import open_aedat2, write_aedat2
from cvstereo.io.edvs_text import open_edvs_merged, open_edvs_text, read_text_header, write_edvs_merged, write_edvs_pair
from cvstereo.io.npz import read_matches, read_recording_npz, write_matches, write_recording_npz
from cvstereo.io.stream import RecordingStream, open_npz
from cvstereo.recording import Recording

#: Format names accepted by ``format=`` and the CLI's ``--format``.
FORMATS = ("npz", "edvs-text", "edvs-merged", "aedat2")

#: File extensions of the text formats (which of the two is told by the column count).
TEXT_SUFFIXES = (".txt", ".dat", ".csv")
AEDAT_SUFFIXES = (".aedat", ".aedat2")

# Which reader options apply to which format; anything else given is a mistake worth reporting.
_OPTIONS = {
    "npz": (),
    "edvs-text": ("right", "one_based", "resolution"),
    "edvs-merged": ("left_retina", "one_based", "resolution"),
    "aedat2": ("right", "resolution"),
}


def detect_format(path: str | os.PathLike) -> str:
    """Tell a file's format from its content and extension.

    ``#!AER-DAT`` at the start means AEDAT (jAER also used ``.dat`` for it); ``.npz`` is a recording
    archive; ``.txt`` / ``.dat`` / ``.csv`` are eDVS text, ``edvs-text`` when the first event line has 4
    columns and ``edvs-merged`` when it has 5.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, OSError
        A text or AEDAT file that does not exist, is a directory, or is not a regular file (FIFO, device).
    ValueError
        Unknown extension or column count; the message lists the ``--format`` values.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return "npz"
    if suffix not in TEXT_SUFFIXES + AEDAT_SUFFIXES:
        raise ValueError(f"{path}: cannot tell the format from '{suffix}'; give --format ({', '.join(FORMATS)}).")
    require_regular_file(path)
    with open(path, "rb") as fh:
        if fh.read(9) == b"#!AER-DAT" or suffix in AEDAT_SUFFIXES:
            return "aedat2"
    columns = read_text_header(path).columns
    if columns in (4, 5):
        return "edvs-text" if columns == 4 else "edvs-merged"
    what = "no event lines" if columns is None else f"{columns} columns"
    raise ValueError(
        f"{path}: has {what}; eDVS text files have 4 ('t x y p') or 5 ('t x y p retina'). "
        f"Give --format ({', '.join(FORMATS)}) if it is something else."
    )


def open_recording(path: str | os.PathLike, right: str | os.PathLike | None = None, *, format: str | None = None,
                   left_retina: int | None = None, one_based: bool | None = None,
                   resolution: tuple[int, int] | None = None) -> RecordingStream:
    """Open a recording for streaming with bounded memory, in any supported format.

    Parameters
    ----------
    path : path-like
        The recording, or the left camera's file for one-file-per-camera formats.
    right : path-like, optional
        The right camera's file (``edvs-text``, two mono ``aedat2`` files).
    format : str, optional, keyword-only
        One of :data:`FORMATS`; default: :func:`detect_format`.
    left_retina, one_based, resolution : keyword-only
        Options of the text formats (see :mod:`cvstereo.io.edvs_text`); None: from the file or detected.

    Returns
    -------
    RecordingStream
        ``.resolution``, ``.meta``, ``.has_truth``, ``.packets(packet_us)``, ``.read()``. A single-camera
        file opened alone gives a one-camera stream (``.cameras``), whose packets need the other file.

    Examples
    --------
    >>> stream = open_recording("Fan_disp8.dat")  # doctest: +SKIP
    >>> for packet in stream.packets(10_000):  # doctest: +SKIP
    ...     matcher.feed(packet.left, packet.right)
    """
    fmt = format or detect_format(path)
    _check_options(fmt, path, right=right, left_retina=left_retina, one_based=one_based, resolution=resolution)
    if fmt == "npz":
        return open_npz(path)
    if fmt == "edvs-text":
        return open_edvs_text(path, right, one_based=one_based, resolution=resolution)
    if fmt == "edvs-merged":
        return open_edvs_merged(path, left_retina=left_retina, one_based=one_based, resolution=resolution)
    return open_aedat2(path, right)


def read_recording(path: str | os.PathLike, right: str | os.PathLike | None = None, *, format: str | None = None,
                   left_retina: int | None = None, one_based: bool | None = None,
                   resolution: tuple[int, int] | None = None) -> Recording:
    """Read a stereo recording whole, in any supported format.

    Parameters
    ----------
    path : path-like
        The recording, or the left camera's file for one-file-per-camera formats.
    right : path-like, optional
        The right camera's file.
    format : str, optional
        One of :data:`FORMATS`; default: :func:`detect_format`.
    left_retina, one_based, resolution
        Format options (see :func:`open_recording`).

    Returns
    -------
    Recording
        For text and AEDAT input, ``meta`` says how undetermined properties were decided.
    """
    fmt = format or detect_format(path)
    if fmt == "npz":
        _check_options(fmt, path, right=right, left_retina=left_retina, one_based=one_based, resolution=resolution)
        return read_recording_npz(path)
    return open_recording(path, right, format=fmt, left_retina=left_retina, one_based=one_based,
                          resolution=resolution).read()


def _check_options(fmt: str, path, **given) -> None:
    if fmt not in _OPTIONS:
        raise ValueError(f"unknown format '{fmt}'; choose one of: {', '.join(FORMATS)}.")
    wrong = [k for k, v in given.items() if v is not None and k not in _OPTIONS[fmt]]
    if wrong:
        what = " and ".join("a second file" if k == "right" else k for k in wrong)
        raise ValueError(f"{path}: {what} do(es) not apply to format '{fmt}' (it takes: "
                         f"{', '.join(_OPTIONS[fmt]) or 'no options'}).")
    if fmt == "aedat2" and given["resolution"] is not None and tuple(given["resolution"]) != (128, 128):
        raise ValueError(f"{path}: AEDAT 2.0 DVS128 files are 128x128; resolution {given['resolution']} "
                         "does not apply.")


def write_recording(path: str | os.PathLike, recording: Recording, *, format: str | None = None,
                    right: str | os.PathLike | None = None, left_retina: int = 0) -> None:
    """Write a recording (atomically) in the format given or implied by the extension.

    Parameters
    ----------
    path : path-like
        Output file (the left camera's file for ``edvs-text``).
    recording : Recording
    format : str, optional, keyword-only
        One of :data:`FORMATS`. Default: ``.npz`` -> npz, ``.aedat`` -> aedat2, text extensions ->
        ``edvs-text`` when ``right`` is given, else ``edvs-merged``.
    right : path-like, optional, keyword-only
        The right camera's file for ``edvs-text``.
    left_retina : {0, 1}, keyword-only
        ``edvs-merged``: the retina id of the left camera (stated in the file's header).

    Notes
    -----
    Ground truth is kept by ``npz`` only; ``aedat2`` needs a 128x128 recording with timestamps below 2**32.
    """
    suffix = Path(path).suffix.lower()
    fmt = format or {".npz": "npz", **dict.fromkeys(AEDAT_SUFFIXES, "aedat2"),
                     **dict.fromkeys(TEXT_SUFFIXES, "edvs-merged" if right is None else "edvs-text")}.get(suffix)
    if fmt is None:
        raise ValueError(f"{path}: cannot tell the output format from '{suffix}'; give one of: {', '.join(FORMATS)}.")
    if (fmt == "edvs-text") != (right is not None):
        raise ValueError(f"{path}: format 'edvs-text' and only it writes two files: give the right camera's file "
                         f"exactly for it (format here: '{fmt}').")
    if fmt == "npz":
        return write_recording_npz(path, recording)
    if fmt == "edvs-text":
        return write_edvs_pair(path, right, recording)
    if fmt == "edvs-merged":
        return write_edvs_merged(path, recording, left_retina=left_retina)
    if fmt == "aedat2":
        return write_aedat2(path, recording)
    raise ValueError(f"cannot write format '{fmt}'; choose one of: {', '.join(FORMATS)}.")


__all__ = [
    "FORMATS",
    "RecordingStream",
    "detect_format",
    "open_recording",
    "read_matches",
    "read_recording",
    "read_recording_npz",
    "write_matches",
    "write_recording",
    "write_recording_npz",
]
