"""Atomic file writing: write to a temporary file beside the target, then rename over it.

The rename applies where it can: the target is a regular file or absent. Character devices and FIFOs
(``-o /dev/null``, ``-o fifo``) are not replaced: the complete output is written into them, so they stay
what they are; a symlink is followed and its target replaced (the link stays). Temporary files are named
``.NAME.pidPID-XXXXXXXX[SUFFIX].part`` in the target's folder; one left behind by a process that no longer
runs (SIGKILL, power loss) is removed by the next write of the same output (:func:`remove_stale_temporaries`).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

#: A temporary file without a process id (written by cvstereo 0.1) is stale once untouched this long:
#: a live writer keeps appending to it.
LEGACY_STALE_S = 600.0


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a path to write; on success it becomes ``path``.

    For a regular file (or a new one) the yielded path is a temporary file in the target's folder, renamed
    over the target once the block completes: a crash or exception leaves the target untouched (an older
    version stays whole) and removes the temporary file, so no half-written output ever looks complete.
    For a character device or FIFO the temporary file is in the temporary folder and its complete content
    is written into the device once the block completes (the device node stays). A symlink is followed: its
    target is replaced atomically and the link stays.

    Parameters
    ----------
    path : path-like
        The final file.
    suffix : str, optional
        Suffix of the temporary file (some writers, e.g. numpy's savez, insist on one); default: the target's.

    Raises
    ------
    IsADirectoryError
        ``path`` is a folder.
    FileNotFoundError
        Its folder does not exist.
    OSError
        ``path`` is a block device, socket or other special file.
    """
    name = os.fspath(path)
    target = Path(os.path.realpath(name))  # follow symlinks: replace what the link points at
    mode = _mode(target)
    stream = False
    if mode is not None and not stat.S_ISREG(mode):
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(f"{name}: is a directory; give a file name to write.")
        if not (stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):
            raise OSError(f"{name}: is not a regular file, a character device or a FIFO; refusing to replace it.")
        stream = True
    elif not target.parent.is_dir():
        raise FileNotFoundError(f"{name}: folder {target.parent} does not exist; create it first.")
    # A device or FIFO is not replaced: the complete output is copied into it. Writers may seek (zip, MP4),
    # which a FIFO cannot, so they still write a temporary file, in the temporary folder (not in /dev).
    folder = Path(tempfile.gettempdir()) if stream else target.parent
    remove_stale_temporaries(folder / target.name)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.pid{os.getpid()}-",
                               suffix=(suffix if suffix is not None else target.suffix) + ".part", dir=folder)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if stream:
            with open(tmp_path, "rb") as src, open(target, "wb") as dst:
                shutil.copyfileobj(src, dst, 1 << 20)
            tmp_path.unlink()
            return
        # mkstemp creates the file readable by its owner only: keep the replaced file's permissions, else give
        # the ones a plain open() would.
        if mode is not None:
            os.chmod(tmp_path, stat.S_IMODE(mode))
        else:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp_path, 0o666 & ~umask)
        os.replace(tmp_path, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def _mode(path: Path) -> int | None:
    try:
        return os.stat(path).st_mode
    except OSError:
        return None


def remove_stale_temporaries(target: str | os.PathLike) -> list[Path]:
    """Remove temporary files of ``target`` that an earlier, killed write left in its folder.

    Only temporaries of this output name are considered. One tagged with a process id (``.NAME.pidPID-...``)
    is removed when that process no longer runs (a running one may still be writing it, so it stays; so
    do this process' own). An untagged one (cvstereo 0.1's ``.NAME.XXXXXXXX.part``) is removed once
    unmodified for :data:`LEGACY_STALE_S` seconds.

    Returns
    -------
    list of Path
        The files removed.
    """
    target = Path(target)
    name = re.escape(target.name)
    tagged = re.compile(rf"\.{name}\.pid(\d+)-[a-z0-9_]{{8}}[^/]*\.part(\.[A-Za-z0-9]+)?")
    legacy = re.compile(rf"\.{name}\.[a-z0-9_]{{8}}{re.escape(target.suffix)}\.part(\.[A-Za-z0-9]+)?")
    removed = []
    try:
        entries = list(os.scandir(target.parent))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        m = tagged.fullmatch(entry.name)
        try:
            if m is not None:
                stale = _process_gone(int(m.group(1)))
            elif legacy.fullmatch(entry.name):
                stale = now - entry.stat(follow_symlinks=False).st_mtime > LEGACY_STALE_S
            else:
                continue
            if stale and entry.is_file(follow_symlinks=False):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue  # not ours to remove (permissions) or already gone
    return removed


def _process_gone(pid: int) -> bool:
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (PermissionError, OverflowError, ValueError):
        return False  # another user's process, or a number no process has: leave the file alone
    return False


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write a text file atomically (temporary file, then rename)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
