"""AEDAT 4.0 files of iniVation DV cameras (DAVIS, DVXplorer), read through dv-processing (the ``aedat4`` extra).

A file holds one or more cameras, each with an event stream named after the camera (its ``source``):

- a stereo file (DV's stereo recorder, :class:`dv_processing.io.StereoCameraWriter`) holds two cameras; the
  left is the one named by ``left_camera=``, else the first event stream of the file (the writer stores the
  left camera first); ``meta["left_camera_from"]`` says which rule decided;
- one file per camera: ``open_aedat4(left_file, right_file)``; a file opened alone with one camera gives a
  single-camera stream.

Events are read batch by batch (``getNextEventBatch``), so memory stays bounded whatever the file's length.
Polarity: DV's ``True`` is ON, i.e. ``p = 1``. Timestamps are DV's microseconds (usually since the UNIX
epoch), kept as they are.

dv-processing's reader runs in a worker process under a watchdog (:mod:`cvstereo.io._watchdog`): on a damaged
file it can spin for ever without letting its own process handle a signal, so each camera is decoded in a
process that streams the batches back and is killed when it stalls (a one-line error naming the file) or when
the read is stopped (Ctrl-C, SIGTERM). Its failures are reported in our words, with its own in brackets.

The cameras of a file are listed from the XML description in the file's header (the ``source`` of every
``EVTS`` output), because dv-processing opens the first camera only unless told a name.
"""

from __future__ import annotations

import json
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterator

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io._watchdog import worker_frames
from cvstereo.io.files import open_regular
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.model.events import EVENT_DTYPE, check_resolution
from cvstereo.model.recording import CAMERAS

__all__ = ["MAGIC", "OPEN_CPU_S_PER_BYTE", "aedat4_cameras", "open_aedat4"]

MAGIC = b"#!AER-DAT4.0"
#: How much of the file's start is searched for the XML header (it is a few KB).
_HEADER_BYTES = 1 << 20


def _dv():
    try:
        import dv_processing
    except ImportError as exc:
        raise ImportError("reading AEDAT4 needs dv-processing: pip install 'cvstereo[aedat4]'") from exc
    return dv_processing


def aedat4_cameras(path: str | os.PathLike) -> list[tuple[str, tuple[int, int]]]:
    """The cameras with an event stream in an AEDAT4 file, in file order, with their resolution.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    list of (name, (width, height))

    Raises
    ------
    FileNotFoundError, IsADirectoryError, OSError
        Missing, a directory, or not a regular file (a FIFO would block).
    CorruptFileError
        Not an AEDAT 4.0 file, no event stream in it, or a stream whose size is not a sensor's (up to
        2048x2048, as everywhere).
    """
    with open_regular(path) as fh:
        head = fh.read(_HEADER_BYTES)
    if not head.startswith(MAGIC):
        raise CorruptFileError(f"{path}: not an AEDAT 4.0 file (it does not start with '#!AER-DAT4.0').")
    found = re.search(rb"<dv[ >].*?</dv>", head, re.S)
    if found is None:
        raise CorruptFileError(f"{path}: the AEDAT4 header holds no stream description (<dv> ... </dv>).")
    try:
        root = ET.fromstring(found.group(0).decode("utf-8", "replace"))
    except ET.ParseError as exc:
        raise CorruptFileError(f"{path}: the AEDAT4 header's stream description is not valid XML ({exc}).") from None
    cameras = []
    for node in root.iter("node"):
        attrs = {a.get("key"): a.text for a in node.findall("attr")}
        info = node.find("node[@name='info']")
        if attrs.get("typeIdentifier") != "EVTS" or info is None:
            continue
        meta = {a.get("key"): a.text for a in info.findall("attr")}
        if meta.get("source"):
            size = check_resolution((_number(meta.get("sizeX")), _number(meta.get("sizeY"))),
                                    source=f"{path}: AEDAT4 event stream '{meta['source']}' size (sizeX, sizeY)",
                                    error=CorruptFileError)
            cameras.append((meta["source"], size))
    if not cameras:
        raise CorruptFileError(f"{path}: no event stream in this AEDAT4 file (frames or IMU only?).")
    return cameras


def _number(text: str | None):
    """An XML attribute's number as written (an int where it is one), or the text itself for the message."""
    try:
        return int(text)
    except (TypeError, ValueError):
        return text


#: The record layout the worker sends: the event dtype, as JSON.
_LAYOUT = json.dumps(EVENT_DTYPE.descr)
#: CPU seconds per byte of file that dv-processing may take to open a file (it reads the packet table): about
#: 1e-11 s here for a 76 MB file of 1,000 packets, allowed ten times over, so a file of 10 GB gets one more second.
OPEN_CPU_S_PER_BYTE = 1e-10


def _camera_chunks(path: str, camera: str, resolution: tuple[int, int], label: str) -> Iterator[Chunk]:
    """One camera's events, decoded by dv-processing in a watched worker process, each batch checked here."""
    check = ChunkChecker(resolution=resolution, source=f"{path} [{label}: {camera}]")
    frames = worker_frames([str(path), camera, _LAYOUT], source=f"{path} (AEDAT4, camera {camera})",
                           decoder="dv-processing's AEDAT4 reader",
                           open_cpu_s=os.path.getsize(path) * OPEN_CPU_S_PER_BYTE)
    for _, payload in frames:
        yield check.adopt(np.frombuffer(payload, EVENT_DTYPE)), None


def open_aedat4(path: str | os.PathLike, right: str | os.PathLike | None = None, *, left_camera: str | None = None,
                resolution: tuple[int, int] | None = None) -> RecordingStream:
    """Open an AEDAT4 recording (a stereo file, two mono files, or one mono file) for streaming.

    Parameters
    ----------
    path : path-like
        A stereo file, or the left camera's file.
    right : path-like, optional
        The right camera's file (each file then holds one camera, or the first camera is used).
    left_camera : str, optional, keyword-only
        Stereo file: the name of the left camera (default: the first event stream in the file).
    resolution : (width, height), optional, keyword-only
        Must match the file's, if given.

    Returns
    -------
    RecordingStream
        ``meta`` names the cameras (``cameras``) and how the left one was chosen (``left_camera_from``).

    Raises
    ------
    ImportError
        dv-processing is not installed.
    CorruptFileError, ValueError
        Not AEDAT4, not named ``*.aedat4``, more than two cameras, an unknown ``left_camera``, cameras of
        different resolutions.
    """
    _dv()
    path = os.fspath(path)
    for file in (path,) + (() if right is None else (os.fspath(right),)):
        aedat4_cameras(file)  # not AEDAT4, or missing: say so before dv-processing does
        if not file.lower().endswith(".aedat4"):
            # dv-processing refuses other extensions with an opaque error.
            raise ValueError(f"{file}: an AEDAT4 file must end in '.aedat4' to be read (dv-processing requires "
                             "it); rename or link it.")
    if right is not None:
        if left_camera is not None:
            raise ValueError(f"{path}: left_camera applies to a stereo file, not to two files (left, right).")
        files = (path, os.fspath(right))
        picks = [aedat4_cameras(f)[0] for f in files]
        sources = dict(zip(CAMERAS, zip(files, picks, strict=True), strict=True))
        cameras, how = CAMERAS, "two files"
    else:
        files = (path,)
        found = aedat4_cameras(path)
        if len(found) > 2:
            raise ValueError(f"{path}: holds {len(found)} cameras ({', '.join(n for n, _ in found)}); "
                             "cvstereo reads one or two.")
        if len(found) == 1:
            if left_camera is not None:
                raise ValueError(f"{path}: holds one camera ({found[0][0]}); left_camera applies to stereo files.")
            sources, cameras, how = {MONO: (path, found[0])}, (MONO,), "one camera"
        else:
            names = [n for n, _ in found]
            if left_camera is None:
                order, how = found, "first event stream of the file"
            elif left_camera in names:
                order, how = sorted(found, key=lambda c: c[0] != left_camera), "left_camera option"
            else:
                raise ValueError(f"{path}: no camera '{left_camera}'; the file holds {', '.join(names)}.")
            sources = {cam: (path, c) for cam, c in zip(CAMERAS, order, strict=True)}
            cameras = CAMERAS
    sizes = {c[1] for _, c in sources.values()}
    if len(sizes) > 1:
        raise ValueError(f"{path}: the cameras have different resolutions {sorted(sizes)}; rectify or crop them "
                         "to one size first.")
    size = sizes.pop()
    if resolution is not None and tuple(resolution) != size:
        raise ValueError(f"{path}: the file says {size[0]}x{size[1]}, not {resolution[0]}x{resolution[1]}.")
    meta = {"source": list(files), "format": "aedat4", "cameras": {cam: c[0] for cam, (_, c) in sources.items()},
            "left_camera_from": how}

    def open_chunks(camera: str) -> Iterator[Chunk]:
        file, (name, _) = sources[camera]
        return _camera_chunks(file, name, size, camera)

    return RecordingStream("aedat4", files, cameras, size, meta, False, open_chunks)
