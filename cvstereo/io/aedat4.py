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

The cameras of a file are listed from the XML description in the file's header (the ``source`` of every
``EVTS`` output), because dv-processing opens the first camera only unless told a name.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterator

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io.stream import MONO, Chunk, RecordingStream
from cvstereo.recording import CAMERAS

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
    FileNotFoundError
    CorruptFileError
        Not an AEDAT 4.0 file, or no event stream in it.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(_HEADER_BYTES)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file.") from None
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
            cameras.append((meta["source"], (int(meta.get("sizeX", 0)), int(meta.get("sizeY", 0)))))
    if not cameras:
        raise CorruptFileError(f"{path}: no event stream in this AEDAT4 file (frames or IMU only?).")
    return cameras


def _camera_chunks(path: str, camera: str, resolution: tuple[int, int], label: str) -> Iterator[Chunk]:
    dv = _dv()
    reader = dv.io.MonoCameraRecording(str(path), camera)
    check = ChunkChecker(resolution=resolution, source=f"{path} [{label}: {camera}]")
    while True:
        batch = reader.getNextEventBatch()
        if batch is None:
            return
        if batch.isEmpty():
            continue
        raw = batch.numpy()
        events = np.empty(raw.shape[0], dtype=[("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])
        events["t"], events["x"], events["y"], events["p"] = (raw["timestamp"], raw["x"], raw["y"],
                                                              raw["polarity"])
        yield check(events), None


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
