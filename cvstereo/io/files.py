"""Input files as the readers need them: regular files only, named clearly when they are something else.

Every format is read by seeking or in several passes (the zip directory of an ``.npz`` sits at its end;
text and AEDAT files are opened once for the header and again per camera), so a FIFO would block or be
drained by the first pass, and a device such as ``/dev/zero`` never ends. Both are refused up front
rather than hanging or filling memory.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

__all__ = ["ROS2_METADATA", "is_ros2_folder", "open_regular", "printable", "require_input", "require_regular_file"]

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def require_regular_file(path: str | os.PathLike) -> Path:
    """Return ``path`` as a Path if it names a regular file (after symlinks), else raise.

    Raises
    ------
    FileNotFoundError
        Nothing there.
    IsADirectoryError
        A directory.
    OSError
        A FIFO, device or socket: "not a regular file", with what it is and what to do.
    """
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file.") from None
    except NotADirectoryError:
        raise FileNotFoundError(f"{path}: no such file (a parent is not a directory).") from None
    if stat.S_ISREG(mode):
        return path
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(f"{path}: is a directory; give a recording file (or a DSEC sequence folder, which "
                                "holds events/left/events.h5 and events/right/events.h5).")
    kind = next((name for test, name in _KINDS if test(mode)), "not a file")
    raise OSError(f"{path}: is {kind}, not a regular file; recordings are read by seeking and in several passes, "
                  "so save the stream to a file first.")


#: The file that makes a folder a ROS 2 bag (the one recording format that is a folder).
ROS2_METADATA = "metadata.yaml"


def is_ros2_folder(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a folder holding a ROS 2 bag (its ``metadata.yaml``)."""
    return Path(path).is_dir() and (Path(path) / ROS2_METADATA).is_file()


def require_input(path: str | os.PathLike) -> Path:
    """Return ``path`` as a Path if it names a recording input: a regular file, or a ROS 2 bag folder.

    Raises
    ------
    FileNotFoundError, IsADirectoryError, OSError
        As :func:`require_regular_file`, for anything else (a folder: one that holds no ROS 2 bag).
    """
    if is_ros2_folder(path):
        return Path(path)
    if Path(path).is_dir():
        raise IsADirectoryError(f"{path}: is a directory, neither a DSEC sequence folder (events/left/events.h5 and "
                                f"events/right/events.h5) nor a ROS 2 bag folder ({ROS2_METADATA}); give a recording "
                                "file or one of those folders.")
    return require_regular_file(path)


def open_regular(path: str | os.PathLike):
    """Open a regular file for binary reading (see :func:`require_regular_file`)."""
    return open(require_regular_file(path), "rb")


_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def printable(text: str) -> str:
    r"""``text`` with control characters shown as ``\xNN``, so that file contents quoted in an error cannot
    drive the terminal (escape sequences, carriage returns).

    >>> printable("ab\x1b[2Jc")
    'ab\\x1b[2Jc'
    """
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", text)
