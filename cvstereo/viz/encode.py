"""Video encoding through PyAV (the ``video`` extra): H.264, else VP9, in MP4 -- codecs that browsers play.

PyAV's wheels ship FFmpeg with its encoders, so the codec does not depend on how OpenCV was built. Which encoder
works is found by encoding a few frames (an encoder can be listed and still fail to open).
"""

from __future__ import annotations

import contextlib
import functools
import os
import tempfile
from fractions import Fraction
from pathlib import Path

import numpy as np

from cvstereo.errors import require_extra
from cvstereo.io.atomic import atomic_path, inspect_target

__all__ = ["CODECS", "CODEC_NAMES", "VideoEncoder", "require_av", "video_codec", "video_writer"]

#: Encoders tried in order, by FFmpeg name: H.264 (every browser plays it), then VP9 (Chrome, Firefox, Edge).
CODECS = ("libx264", "libvpx-vp9")
#: What each encoder writes, for messages.
CODEC_NAMES = {"libx264": "H.264", "libvpx-vp9": "VP9"}
#: Encoder options: constant quality (x264's default level; VP9's equivalent needs a zero bit rate cap).
_OPTIONS = {"libx264": {"crf": "23", "preset": "medium"}, "libvpx-vp9": {"crf": "32", "b": "0"}}
#: Pixel format of the stream: 4:2:0, the one browsers decode (hence even frame sides).
PIX_FMT = "yuv420p"


def require_av():
    """Import PyAV (the ``video`` extra) or raise MissingExtraError naming the extra."""
    return require_extra("av", "video")


@functools.cache
def video_codec() -> str:
    """The first of :data:`CODECS` that this PyAV build encodes (tried once, on a tiny video in memory).

    Raises
    ------
    OSError
        No encoder works (a PyAV built without them).
    """
    require_av()
    with tempfile.TemporaryDirectory() as folder:
        for codec in CODECS:
            try:
                with VideoEncoder(os.path.join(folder, f"probe-{codec}.mp4"), 25.0, (16, 16), codec=codec) as enc:
                    enc.write(np.zeros((16, 16, 3), np.uint8))
                return codec
            except Exception:  # any failure to open or encode means: try the next codec
                continue
    raise OSError(f"this PyAV build encodes none of {', '.join(CODECS)}; reinstall it from its wheel: "
                  "pip install --force-reinstall 'cvstereo[video]'.")


class VideoEncoder:
    """Frames (RGB, uint8, ``height x width x 3``) into an MP4 file, one :meth:`write` per frame.

    Parameters
    ----------
    path : path-like
        The file to write (its name's extension does not matter: the container is MP4).
    fps : float
        Frames per second (kept as a fraction: 29.97 stays 2997/100).
    size : (width, height)
        Even numbers (4:2:0 colour).
    codec : str, optional, keyword-only
        An FFmpeg encoder name; default :func:`video_codec`.
    """

    def __init__(self, path: str | os.PathLike, fps: float, size: tuple[int, int], *, codec: str | None = None):
        av = require_av()
        self.codec = codec or video_codec()
        width, height = size
        if width % 2 or height % 2:
            raise ValueError(f"video frames must have even sides for 4:2:0 colour, got {width}x{height}.")
        self.size = (int(width), int(height))
        self._container = av.open(os.fspath(path), mode="w", format="mp4")
        try:
            self._stream = self._container.add_stream(self.codec, rate=Fraction(fps).limit_denominator(1001),
                                                      options=_OPTIONS.get(self.codec, {}))
            self._stream.width, self._stream.height = self.size
            self._stream.pix_fmt = PIX_FMT
        except BaseException:
            self._container.close()
            raise
        self.frames = 0

    def write(self, rgb: np.ndarray) -> None:
        """Encode one frame (RGB uint8, the size given)."""
        import av

        if rgb.shape != (self.size[1], self.size[0], 3) or rgb.dtype != np.uint8:
            raise ValueError(f"a video frame must be {self.size[1]}x{self.size[0]}x3 uint8, got "
                             f"{'x'.join(map(str, rgb.shape))} {rgb.dtype}.")
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
        for packet in self._stream.encode(frame):
            self._container.mux(packet)
        self.frames += 1

    def close(self) -> None:
        """Flush the encoder and finish the file."""
        for packet in self._stream.encode(None):
            self._container.mux(packet)
        self._container.close()

    def abort(self) -> None:
        """Close the file without flushing (it is discarded)."""
        with contextlib.suppress(Exception):
            self._container.close()

    def __enter__(self) -> VideoEncoder:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


@contextlib.contextmanager
def video_writer(path: str | os.PathLike, fps: float, size: tuple[int, int]):
    """A :class:`VideoEncoder` on a temporary file that becomes ``path`` when the block completes.

    Raises
    ------
    ValueError
        ``path`` names another format than MP4.
    OSError
        The encoder cannot be opened (named with the file).
    """
    target = Path(path)
    if target.suffix and target.suffix.lower() != ".mp4" and not inspect_target(target)[2]:
        raise ValueError(f"{target}: the video is written as MP4; give a file name ending in .mp4 (or none).")
    codec = video_codec()
    with atomic_path(target) as tmp:
        try:
            encoder = VideoEncoder(tmp, fps, size, codec=codec)
        except (OSError, ValueError) as exc:
            raise OSError(f"{target}: cannot open a video encoder ({CODEC_NAMES.get(codec, codec)}, "
                          f"{size[0]}x{size[1]}): {exc}") from exc
        with encoder:
            yield encoder
