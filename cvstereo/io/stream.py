"""Recordings opened for streaming: metadata at once, events chunk by chunk with bounded memory.

Every format module returns a :class:`RecordingStream` from its ``open_*`` function; the format-agnostic
entry point is :func:`cvstereo.io.open_recording`. The ``.npz`` opener lives here, built on the archive
readers of :mod:`cvstereo.io.npz` (header and raw chunks).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.io._checked import ChunkChecker
from cvstereo.io.npz import iter_npz_chunks, read_npz_header
from cvstereo.model.events import StereoPacket, empty_events, iter_stereo_packets
from cvstereo.model.recording import CAMERAS, Recording

__all__ = ["MONO", "Chunk", "RecordingStream", "open_npz"]

#: Camera name of a stream read from a file that holds a single camera.
MONO = "mono"

#: A chunk as the streams yield it: events of EVENT_DTYPE and their ground truth (float32) or None.
Chunk = tuple[np.ndarray, "np.ndarray | None"]


@dataclass(frozen=True, eq=False)
class RecordingStream:
    """A recording (or a single camera's file) opened for streaming.

    Each call of :meth:`chunks` or :meth:`packets` opens the file(s) anew, so a stream can be walked
    more than once; nothing is held in memory between calls.

    Parameters
    ----------
    format : str
        Format name (one of :data:`cvstereo.io.FORMATS`).
    files : tuple of str
        The file(s) read.
    cameras : tuple of str
        ``("left", "right")`` for a stereo recording, ``(MONO,)`` = ``("mono",)`` for a file that
        holds a single camera.
    resolution : (width, height)
    meta : dict
        The recording's metadata; for formats that must guess, also how ambiguous properties were
        decided (e.g. ``left_retina`` and ``left_retina_from``).
    has_truth : bool
        Whether chunks carry per-event ground truth.
    open_chunks : callable
        ``open_chunks(camera)`` returns a fresh iterator of validated ``(events, truth)`` chunks.
    given : tuple of str
        The path(s) as the user named them (:func:`cvstereo.io.open_recording` fills it: a DSEC sequence's
        folder, where ``files`` are its two event files); empty where the stream was made otherwise.
        A matches file's ``meta["input"]`` is this, else ``files``.
    """

    format: str
    files: tuple[str, ...]
    cameras: tuple[str, ...]
    resolution: tuple[int, int]
    meta: dict
    has_truth: bool
    open_chunks: Callable[[str], Iterator[Chunk]] = field(repr=False)
    given: tuple[str, ...] = ()

    @property
    def is_stereo(self) -> bool:
        """True when the stream holds a left and a right camera."""
        return self.cameras == CAMERAS

    def chunks(self, camera: str) -> Iterator[Chunk]:
        """Iterate over ``(events, truth)`` chunks of one camera (time-ordered across chunks)."""
        if camera not in self.cameras:
            raise ValueError(f"no camera '{camera}' in this stream; it holds {', '.join(self.cameras)}.")
        return self.open_chunks(camera)

    def packets(self, packet_us: int = 10_000) -> Iterator[StereoPacket]:
        """Time-aligned packets of both cameras (see :func:`cvstereo.model.events.iter_stereo_packets`).

        Parameters
        ----------
        packet_us : int
            Packet length in microseconds; packets cover ``[k*P, (k+1)*P)`` on the absolute clock.
        """
        self._require_stereo()
        return iter_stereo_packets(self.chunks("left"), self.chunks("right"), packet_us)

    def read_camera(self, camera: str) -> tuple[np.ndarray, np.ndarray | None]:
        """All events of one camera and their ground truth (or None), concatenated."""
        events, truth = [empty_events()], []
        for ev, tr in self.chunks(camera):
            events.append(ev)
            truth.append(tr)
        if not self.has_truth:
            return np.concatenate(events), None
        return np.concatenate(events), np.concatenate([np.empty(0, np.float32), *truth])

    def read(self) -> Recording:
        """The whole stereo recording in memory."""
        self._require_stereo()
        (left, ld), (right, rd) = (self.read_camera(cam) for cam in CAMERAS)
        return Recording(left, right, ld, rd, self.resolution, dict(self.meta))

    def swapped(self) -> RecordingStream:
        """The same stream with the cameras exchanged, as :meth:`Recording.swapped
        <cvstereo.model.recording.Recording.swapped>` (truth negated, so that it stays x_left - x_right).

        ``files`` stay as given: they name what is read, and the swap is recorded by whoever asked for it.
        """
        self._require_stereo()
        other = {"left": "right", "right": "left"}

        def open_chunks(camera: str) -> Iterator[Chunk]:
            for events, truth in self.open_chunks(other[camera]):
                yield events, None if truth is None else -truth

        return replace(self, open_chunks=open_chunks, meta=dict(self.meta))

    def _require_stereo(self) -> None:
        if not self.is_stereo:
            raise ValueError(
                f"{self.files[0]} holds one camera only; give both cameras' files "
                "(left and right) to read a stereo recording."
            )


def open_npz(path: str | os.PathLike, *, chunk_rows: int = 1 << 16) -> RecordingStream:
    """Open a stereo recording ``.npz`` for streaming straight out of the archive.

    Parameters
    ----------
    path : path-like
    chunk_rows : int, keyword-only
        Events per chunk.

    Returns
    -------
    RecordingStream
        Chunks are validated (dtype, range, time order across chunks); errors name the key and index.
    """
    resolution, meta, has_truth = read_npz_header(path)

    def open_chunks(camera: str) -> Iterator[Chunk]:
        check = ChunkChecker(resolution=resolution, source=f"{path} [{camera}]")
        truths = iter_npz_chunks(path, f"{camera}_disparity", chunk_rows) if has_truth else None
        for raw in iter_npz_chunks(path, camera, chunk_rows):
            events = check(raw)
            truth = None
            if truths is not None:
                truth = np.asarray(next(truths, np.empty(0)), np.float32)
                if truth.shape != events.shape:
                    raise CorruptFileError(
                        f"{path}: key '{camera}_disparity' does not hold one value per '{camera}' event "
                        f"(mismatch near event {check.count}); rewrite the file with one disparity per event."
                    )
            yield events, truth
        if truths is not None and next(truths, None) is not None:
            raise CorruptFileError(
                f"{path}: key '{camera}_disparity' holds more values than '{camera}' has events "
                f"({check.count}); rewrite the file with one disparity per event."
            )

    return RecordingStream("npz", (str(path),), CAMERAS, resolution, meta, has_truth, open_chunks)
