"""Reading and writing recordings and matches.

:func:`read_recording`, :func:`open_recording` (streaming) and :func:`write_recording` choose the format
from ``format=`` or from the file (content, then extension; :func:`detect_format`). Per-format modules:
:mod:`~cvstereo.io.npz`, :mod:`~cvstereo.io.edvs_text`, :mod:`~cvstereo.io.aedat2`, and with the extras
:mod:`~cvstereo.io.aedat4` (``aedat4``), :mod:`~cvstereo.io.hdf5` (``hdf5``: DSEC, MVSEC) and
:mod:`~cvstereo.io.prophesee` (``prophesee``: EVT 2.0 / 2.1 / 3.0 ``.raw``, Prophesee ``.dat``; EVT 2.1 needs no
extra), :mod:`~cvstereo.io.metavision_csv`, and :mod:`~cvstereo.io.rosbag` (``ros``: ROS 1 and ROS 2 bags of
``dvs_msgs`` / ``event_camera_msgs`` events); the streaming object is :class:`~cvstereo.io.stream.RecordingStream`.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from cvstereo.io.aedat2 import open_aedat2, write_aedat2
from cvstereo.io.edvs_text import open_edvs_merged, open_edvs_text, read_text_header, write_edvs_merged, write_edvs_pair
from cvstereo.io.files import is_ros2_folder, require_regular_file
from cvstereo.io.metavision_csv import is_comma_separated, open_metavision_csv, sniff_metavision_csv
from cvstereo.io.npz import read_matches, read_recording_npz, write_matches, write_recording_npz
from cvstereo.io.prophesee import ENCODINGS, HEADER_LIMIT, open_prophesee, read_prophesee_header, sniff_prophesee
from cvstereo.io.rosbag import open_rosbag, sniff_rosbag
from cvstereo.io.stream import RecordingStream, open_npz
from cvstereo.model.recording import Recording

#: File extensions of the text formats (which of the two is told by the column count).
TEXT_SUFFIXES = (".txt", ".dat", ".csv")
AEDAT_SUFFIXES = (".aedat", ".aedat2")
AEDAT4_SUFFIXES = (".aedat4",)
HDF5_SUFFIXES = (".h5", ".hdf5")
#: ROS 1 bags and ROS 2 storage files (a ROS 2 bag folder is told by its metadata.yaml).
ROSBAG_SUFFIXES = (".bag", ".db3", ".mcap")


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
        Reader options that apply (``right``, ``left_retina``, ``one_based``, ``resolution``, ``columns``,
        ``topics``); any other
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


# The readers of the optional extras are imported when a file of theirs is opened, so that the core imports
# without h5py or dv-processing.
def _open_aedat4(path, right=None, *, resolution=None) -> RecordingStream:
    from cvstereo.io.aedat4 import open_aedat4

    return open_aedat4(path, right, resolution=resolution)


def _open_dsec(path, right=None, *, resolution=None) -> RecordingStream:
    from cvstereo.io.hdf5 import open_dsec

    if os.path.isdir(path):  # a sequence folder: both cameras' files, its name
        from cvstereo.io.dsec_sequence import find_dsec_sequence

        if right is not None:
            raise ValueError(f"{path}: a DSEC sequence folder holds both cameras; give no second file ({right}).")
        seq = find_dsec_sequence(path)
        stream = open_dsec(seq.left, seq.right, resolution=resolution)
        stream.meta.update(sequence=seq.name, sequence_folder=os.fspath(path),
                           ground_truth_maps=len(seq.disparity))
        return stream
    return open_dsec(path, right, resolution=resolution)


def _open_mvsec(path, *, resolution=None) -> RecordingStream:
    from cvstereo.io.hdf5 import open_mvsec

    return open_mvsec(path, resolution=resolution)


def _open_m3ed(path, *, resolution=None) -> RecordingStream:
    from cvstereo.io.hdf5 import open_m3ed

    return open_m3ed(path, resolution=resolution)


def _prophesee_opener(name: str) -> Callable[..., RecordingStream]:
    """The opener of one Prophesee format: the header must name that format."""
    def open_format(path, right=None, *, resolution=None) -> RecordingStream:
        return open_prophesee(path, right, format=name, resolution=resolution)

    return open_format


#: Every recording format by its name (``format=``, the CLI's ``--format``). Adding a format is one entry.
FORMAT_TABLE: dict[str, Format] = {
    "npz": Format(open_npz, write_recording_npz, (), (".npz",), read=read_recording_npz),
    "edvs-text": Format(open_edvs_text, _write_edvs_pair, ("right", "one_based", "resolution"), TEXT_SUFFIXES,
                        ("right",)),
    "edvs-merged": Format(open_edvs_merged, write_edvs_merged, ("left_retina", "one_based", "resolution"),
                          TEXT_SUFFIXES, ("left_retina",)),
    "aedat2": Format(_open_aedat2, write_aedat2, ("right", "resolution"), AEDAT_SUFFIXES),
    "aedat4": Format(_open_aedat4, None, ("right", "resolution"), AEDAT4_SUFFIXES),
    # DSEC, MVSEC and M3ED share .h5/.hdf5: detect_format tells them apart by the layout inside.
    "dsec": Format(_open_dsec, None, ("right", "resolution")),
    "mvsec": Format(_open_mvsec, None, ("resolution",)),
    "m3ed": Format(_open_m3ed, None, ("resolution",)),
    # Prophesee's files are told by their header (.raw holds any EVT encoding; .dat is also eDVS text's name).
    **{name: Format(_prophesee_opener(name), None, ("right", "resolution")) for name in ENCODINGS},
    "metavision-csv": Format(open_metavision_csv, None, ("right", "resolution", "columns")),
    "rosbag": Format(open_rosbag, None, ("topics", "resolution"), ROSBAG_SUFFIXES),
}

#: Format names accepted by ``format=`` and the CLI's ``--format``.
FORMATS = tuple(FORMAT_TABLE)


def detect_format(path: str | os.PathLike) -> str:
    """Tell a file's format from its content and extension.

    ``#!AER-DAT4.0`` at the start (or ``.aedat4``) means AEDAT4, other ``#!AER-DAT`` AEDAT 2.0 (jAER also
    used ``.dat`` for it); a Prophesee ``% `` header names its format (EVT 2.0 / 2.1 / 3.0 ``.raw``, Prophesee
    ``.dat``) whatever the extension (:func:`cvstereo.io.prophesee.sniff_prophesee`); ``#ROSBAG V2.0`` at the
    start, an MCAP or SQLite ``.db3`` file or a folder holding ``metadata.yaml`` is a ROS bag
    (:func:`cvstereo.io.rosbag.sniff_rosbag`); ``.npz`` is a recording
    archive; ``.h5`` / ``.hdf5`` are DSEC, MVSEC or M3ED (told by the layout, :func:`cvstereo.io.hdf5.hdf5_layout`),
    a folder with ``events/left`` / ``events/right`` is a DSEC sequence (:mod:`cvstereo.io.dsec_sequence`);
    ``.txt`` / ``.dat`` / ``.csv`` are Metavision CSV when their content says so
    (:func:`cvstereo.io.metavision_csv.sniff_metavision_csv`), else eDVS text, ``edvs-text`` when the first
    event line has 4 columns and ``edvs-merged`` when it has 5.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, OSError
        A text or AEDAT file that does not exist, is a directory, or is not a regular file (FIFO, device).
    ValueError
        Unknown extension or column count, or a Prophesee header naming an encoding cvstereo does not read; the
        message lists the ``--format`` values.
    """
    path = Path(path)
    from cvstereo.io.dsec_sequence import is_dsec_sequence

    if is_dsec_sequence(path):
        return "dsec"
    suffix = path.suffix.lower()
    if is_ros2_folder(path):
        return "rosbag"
    if suffix in HDF5_SUFFIXES:
        from cvstereo.io.hdf5 import hdf5_layout

        return hdf5_layout(path)
    known = suffix in TEXT_SUFFIXES + AEDAT_SUFFIXES + AEDAT4_SUFFIXES + ROSBAG_SUFFIXES
    if not known:
        for name, fmt in FORMAT_TABLE.items():
            if suffix in fmt.suffixes:
                return name
    require_regular_file(path)
    with open(path, "rb") as fh:
        head = fh.read(HEADER_LIMIT)
    if head.startswith(b"#!AER-DAT4.0"):
        return "aedat4"
    if head.startswith(b"#!AER-DAT"):
        return "aedat2"
    if sniff_rosbag(path, head) or suffix in ROSBAG_SUFFIXES:
        return "rosbag"  # a .bag that is no bag is told so by the reader, naming what it found
    prophesee = sniff_prophesee(head)
    if prophesee is not None:
        if prophesee.startswith("unknown"):
            read_prophesee_header(path)  # raises, naming the encoding
        return prophesee
    if suffix in AEDAT4_SUFFIXES:
        return "aedat4"
    if suffix in AEDAT_SUFFIXES:
        return "aedat2"
    if not known:
        raise ValueError(f"{path}: cannot tell the format from '{suffix}' nor from the content (no Prophesee "
                         f"'% ' header); give --format ({', '.join(FORMATS)}).")
    if sniff_metavision_csv(path):
        return "metavision-csv"
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
                   resolution: tuple[int, int] | None = None, columns: str | None = None,
                   topics: str | tuple[str, str] | None = None) -> RecordingStream:
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
    columns : str, optional, keyword-only
        ``metavision-csv``: the column order, e.g. ``"t,x,y,p"`` (default ``x,y,p,t``).
    topics : str or (str, str), optional, keyword-only
        ``rosbag``: the left and right cameras' event topics, ``"LEFT,RIGHT"`` (default: found by name).

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
    name = _chosen_format(path, format, columns)
    fmt = _format(name, path, right=right, left_retina=left_retina, one_based=one_based, resolution=resolution,
                  columns=columns, topics=topics)
    given = {"right": right, "left_retina": left_retina, "one_based": one_based, "resolution": resolution,
             "columns": columns, "topics": topics}
    stream = fmt.open(path, **{k: given[k] for k in fmt.options})
    return replace(stream, given=tuple(os.fspath(p) for p in (path, right) if p is not None))


def read_recording(path: str | os.PathLike, right: str | os.PathLike | None = None, *, format: str | None = None,
                   left_retina: int | None = None, one_based: bool | None = None,
                   resolution: tuple[int, int] | None = None, columns: str | None = None,
                   topics: str | tuple[str, str] | None = None) -> Recording:
    """Read a stereo recording whole, in any supported format.

    Parameters
    ----------
    path : path-like
        The recording, or the left camera's file for one-file-per-camera formats.
    right : path-like, optional
        The right camera's file.
    format : str, optional
        One of :data:`FORMATS`; default: :func:`detect_format`.
    left_retina, one_based, resolution, columns, topics
        Format options (see :func:`open_recording`).

    Returns
    -------
    Recording
        For text and AEDAT input, ``meta`` says how undetermined properties were decided. Its
        :attr:`~cvstereo.model.recording.Recording.origin_us` (the file's ``meta["origin_us"]``, else the earliest
        event of both cameras) is what times shown count from.
    """
    name = _chosen_format(path, format, columns)
    fmt = _format(name, path, right=right, left_retina=left_retina, one_based=one_based, resolution=resolution,
                  columns=columns, topics=topics)
    if fmt.read is not None:
        return fmt.read(path)
    return open_recording(path, right, format=name, left_retina=left_retina, one_based=one_based,
                          resolution=resolution, columns=columns, topics=topics).read()


def _chosen_format(path, format: str | None, columns: str | None) -> str:
    """``format``, else :func:`detect_format`'s; but ``columns=``, which only Metavision CSV takes, makes a
    comma-separated file that detection took for eDVS text (its columns in another order than ``x,y,p,t``) the
    Metavision CSV the user has just described."""
    if format is not None:
        return format
    name = detect_format(path)
    if columns is not None and name in ("edvs-text", "edvs-merged") and is_comma_separated(path):
        return "metavision-csv"
    return name


def _format(name: str, path, **given) -> Format:
    """The table entry of format ``name``, after checking that the options ``given`` apply to it."""
    if name not in FORMAT_TABLE:
        raise ValueError(f"unknown format '{name}'; choose one of: {', '.join(FORMATS)}.")
    fmt = FORMAT_TABLE[name]
    wrong = [k for k, v in given.items() if v is not None and k not in fmt.options]
    if wrong:
        what = " and ".join("a second file" if k == "right" else k for k in wrong)
        verb = "does" if len(wrong) == 1 else "do"
        raise ValueError(f"{path}: {what} {verb} not apply to format '{name}' (it takes: "
                         f"{', '.join(fmt.options) or 'no options'}).")
    return fmt


#: Output extensions -> the formats a reader takes a file of that name for (.dat is also jAER's AEDAT).
_SUFFIX_FORMATS = {".npz": ("npz",), **dict.fromkeys(AEDAT_SUFFIXES, ("aedat2",)),
                   **dict.fromkeys(TEXT_SUFFIXES, ("edvs-text", "edvs-merged")),
                   ".dat": ("edvs-text", "edvs-merged", "aedat2")}


def output_format(path: str | os.PathLike, *, format: str | None = None,
                  right: str | os.PathLike | None = None) -> str:
    """The format :func:`write_recording` writes to ``path`` (and ``right``), checked before any work.

    The format follows the extension; a ``format`` given must agree with a known extension (an ``.aedat``
    name holding eDVS text could not be read back). Names without a known extension take ``format``.

    Raises
    ------
    ValueError
        No format given or implied; a format the extension contradicts; two files for a one-file format.
    """
    suffix = Path(path).suffix.lower()
    fmt = format
    if fmt is None:
        candidates = [n for n, f in FORMAT_TABLE.items() if suffix in f.suffixes and f.write is not None]
        # The text extensions serve two formats: the one that writes a file per camera when a right file is given.
        fitting = [n for n in candidates if ("right" in FORMAT_TABLE[n].write_options) == (right is not None)]
        fmt = (fitting or candidates or [None])[0]
    if fmt is None:
        raise ValueError(f"{path}: cannot tell the output format from '{suffix}'; give one of: {', '.join(FORMATS)}.")
    if fmt not in FORMAT_TABLE or FORMAT_TABLE[fmt].write is None:
        raise ValueError(f"cannot write format '{fmt}'; choose one of: "
                         f"{', '.join(n for n, f in FORMAT_TABLE.items() if f.write is not None)}.")
    if ("right" in FORMAT_TABLE[fmt].write_options) != (right is not None):
        raise ValueError(f"{path}: format 'edvs-text' and only it writes two files (one per camera, named "
                         f"{'/'.join(TEXT_SUFFIXES)}): give the right camera's file exactly for it (format here: "
                         f"'{fmt}', from {'the name' if format is None else 'the option'}).")
    if right is not None:
        from cvstereo.io.paths import refuse_output_over_input

        refuse_output_over_input(right, [path], option="the right camera's output", what="left camera's output")
    for p in (path, right):
        if p is None:
            continue
        allowed = _SUFFIX_FORMATS.get(Path(p).suffix.lower())
        if allowed is not None and fmt not in allowed:
            raise ValueError(f"{p}: a '{Path(p).suffix}' file is read as {' or '.join(allowed)}, but format '{fmt}' "
                             "would be written into it; name the file for its format or choose the format its "
                             "name says.")
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
    name = output_format(path, format=format, right=right)
    fmt = FORMAT_TABLE[name]
    if fmt.write is None:
        raise ValueError(f"cannot write format '{name}'; choose one of: "
                         f"{', '.join(n for n, f in FORMAT_TABLE.items() if f.write is not None)}.")
    options = {"right": right, "left_retina": left_retina}
    fmt.write(path, recording, **{k: options[k] for k in fmt.write_options})


__all__ = ["FORMATS", "FORMAT_TABLE", "Format", "RecordingStream", "detect_format", "open_recording", "output_format",
           "read_matches", "read_recording", "read_recording_npz", "write_matches", "write_recording",
           "write_recording_npz"]
