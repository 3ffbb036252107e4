"""Reading and writing recordings and matches.

:func:`read_recording`, :func:`open_recording` (streaming) and :func:`write_recording` choose the format
from ``format=`` or from the file (content, then extension; :func:`detect_format`). Per-format modules:
:mod:`~cvstereo.io.npz`, :mod:`~cvstereo.io.edvs_text`, :mod:`~cvstereo.io.aedat2`; the streaming object
is :class:`~cvstereo.io.stream.RecordingStream`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from cvstereo.io.aedat2 import open_aedat2, write_aedat2
from cvstereo.io.edvs_text import open_edvs_merged, open_edvs_text, read_text_header, write_edvs_merged, write_edvs_pair
from cvstereo.io.npz import read_matches, read_recording_npz, write_matches, write_recording_npz
from cvstereo.io.stream import RecordingStream, open_npz
from cvstereo.recording import Recording

#: File extensions of the text formats (which of the two is told by the column count).
TEXT_SUFFIXES = (".txt", ".dat", ".csv")
AEDAT_SUFFIXES = (".aedat", ".aedat2")


@dataclass(frozen=True)
class Format:
    """One recording format: how it is opened, read and written, and which options it takes.

    Attributes
    ----------
    open : callable
        ``open(path, **options) -> RecordingStream``, called with exactly the reader options in ``options``.
    write : callable or None
        ``write(path, recording, **write_options)``; None: the format is read-only.
    options : tuple of str
        Reader options that apply (``right``, ``left_retina``, ``one_based``, ``resolution``); any other
        option given is reported as a mistake.
    suffixes : tuple of str
        Extensions that imply the format (for writing, and for reading where the content need not be checked).
    write_options : tuple of str
        Options of ``write`` (``right``: the format writes one file per camera; ``left_retina``).
    read : callable, optional
        ``read(path) -> Recording``, where it is faster than ``open(path).read()``.
    """

    open: Callable[..., RecordingStream]
    write: Callable[..., None] | None
    options: tuple[str, ...] = ()
    suffixes: tuple[str, ...] = ()
    write_options: tuple[str, ...] = ()
    read: Callable[[str | os.PathLike], Recording] | None = None


def _open_aedat2(path, right=None, *, resolution=None) -> RecordingStream:
    if resolution is not None and tuple(resolution) != (128, 128):
        raise ValueError(f"{path}: AEDAT 2.0 DVS128 files are 128x128; resolution {resolution} does not apply.")
    return open_aedat2(path, right)


def _write_edvs_pair(path, recording: Recording, *, right) -> None:
    write_edvs_pair(path, right, recording)


#: Every recording format by its name (``format=``, the CLI's ``--format``). Adding a format is one entry.
FORMAT_TABLE: dict[str, Format] = {
    "npz": Format(open_npz, write_recording_npz, (), (".npz",), read=read_recording_npz),
    "edvs-text": Format(open_edvs_text, _write_edvs_pair, ("right", "one_based", "resolution"), TEXT_SUFFIXES,
                        ("right",)),
    "edvs-merged": Format(open_edvs_merged, write_edvs_merged, ("left_retina", "one_based", "resolution"),
                          TEXT_SUFFIXES, ("left_retina",)),
    "aedat2": Format(_open_aedat2, write_aedat2, ("right", "resolution"), AEDAT_SUFFIXES),
}

#: Format names accepted by ``format=`` and the CLI's ``--format``.
FORMATS = tuple(FORMAT_TABLE)


def detect_format(path: str | os.PathLike) -> str:
    """Tell a file's format from its content and extension.

    ``#!AER-DAT`` at the start means AEDAT (jAER also used ``.dat`` for it); ``.txt`` / ``.dat`` / ``.csv``
    are eDVS text, ``edvs-text`` when the first event line has 4 columns and ``edvs-merged`` when it has 5;
    any other extension names the format whose ``suffixes`` hold it (``.npz``: a recording archive).

    Raises
    ------
    FileNotFoundError
        A text or AEDAT file that does not exist.
    ValueError
        Unknown extension or column count; the message lists the ``--format`` values.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in TEXT_SUFFIXES + AEDAT_SUFFIXES:
        for name, fmt in FORMAT_TABLE.items():
            if suffix in fmt.suffixes:
                return name
        raise ValueError(f"{path}: cannot tell the format from '{suffix}'; give --format ({', '.join(FORMATS)}).")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file.")
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
    name = format or detect_format(path)
    fmt = _format(name, path, right=right, left_retina=left_retina, one_based=one_based, resolution=resolution)
    given = {"right": right, "left_retina": left_retina, "one_based": one_based, "resolution": resolution}
    return fmt.open(path, **{k: given[k] for k in fmt.options})


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
    name = format or detect_format(path)
    fmt = _format(name, path, right=right, left_retina=left_retina, one_based=one_based, resolution=resolution)
    if fmt.read is not None:
        return fmt.read(path)
    return open_recording(path, right, format=name, left_retina=left_retina, one_based=one_based,
                          resolution=resolution).read()


def _format(name: str, path, **given) -> Format:
    """The table entry of format ``name``, after checking that the options ``given`` apply to it."""
    if name not in FORMAT_TABLE:
        raise ValueError(f"unknown format '{name}'; choose one of: {', '.join(FORMATS)}.")
    fmt = FORMAT_TABLE[name]
    wrong = [k for k, v in given.items() if v is not None and k not in fmt.options]
    if wrong:
        what = " and ".join("a second file" if k == "right" else k for k in wrong)
        raise ValueError(f"{path}: {what} do(es) not apply to format '{name}' (it takes: "
                         f"{', '.join(fmt.options) or 'no options'}).")
    return fmt


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
    name = format
    if name is None:
        candidates = [n for n, f in FORMAT_TABLE.items() if suffix in f.suffixes and f.write is not None]
        # The text extensions serve two formats: the one that writes a file per camera when a right file is given.
        fitting = [n for n in candidates if ("right" in FORMAT_TABLE[n].write_options) == (right is not None)]
        name = (fitting or candidates or [None])[0]
    if name is None:
        raise ValueError(f"{path}: cannot tell the output format from '{suffix}'; give one of: {', '.join(FORMATS)}.")
    fmt = FORMAT_TABLE.get(name)
    if fmt is None or fmt.write is None:
        raise ValueError(f"cannot write format '{name}'; choose one of: "
                         f"{', '.join(n for n, f in FORMAT_TABLE.items() if f.write is not None)}.")
    if ("right" in fmt.write_options) != (right is not None):
        raise ValueError(f"{path}: format 'edvs-text' and only it writes two files: give the right camera's file "
                         f"exactly for it (format here: '{name}').")
    options = {"right": right, "left_retina": left_retina}
    fmt.write(path, recording, **{k: options[k] for k in fmt.write_options})


__all__ = [
    "FORMATS",
    "FORMAT_TABLE",
    "Format",
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
