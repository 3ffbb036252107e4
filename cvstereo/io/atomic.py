"""Atomic file writing: write to a temporary file beside the target, then rename over it.

The rename applies where it can: the target is a regular file or absent. Character devices and FIFOs
(``-o /dev/null``, ``-o fifo``) are not replaced: the complete output is written into them, so they stay
what they are; a symlink is followed and its target replaced (the link stays). Temporary files are named
``.NAME.pidPID-XXXXXXXX[SUFFIX].part`` in the target's folder; one left behind by a process that no longer
runs (SIGKILL, power loss) is removed by the next write of the same output (:func:`remove_stale_temporaries`).

One output is one :class:`Staged` file: :func:`stage` makes its temporary file, :func:`publish` puts a set of
them in place together (restoring the previous versions if one of them cannot be), :func:`discard` removes
them. :func:`atomic_path` does the three for one output; inside an :class:`~cvstereo.io.output_plan.OutputPlan`
it hands the plan's temporary file of a declared output instead, and the plan publishes every output at its
end. Errors name the user's file, never the temporary one (:func:`naming_target`).
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import re
import shutil
import stat
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ACTIVE_PLAN", "LEGACY_STALE_S", "Staged", "atomic_path", "discard", "inspect_target", "naming_target",
           "publish", "remove_stale_temporaries", "stage", "write_text_atomic"]

#: A temporary file without a process id (written by cvstereo 0.1) is stale once untouched this long:
#: a live writer keeps appending to it.
LEGACY_STALE_S = 600.0

#: The output plan in force (:class:`cvstereo.io.output_plan.OutputPlan`), or None: :func:`atomic_path` asks it
#: for the temporary file of an output it declared, and leaves the publishing to it.
ACTIVE_PLAN: contextvars.ContextVar = contextvars.ContextVar("cvstereo_output_plan", default=None)


@dataclass
class Staged:
    """One output being written: the user's name, the file it replaces and the temporary file written first.

    Attributes
    ----------
    name : str
        The path as the user gave it: what messages name.
    target : Path
        The file that is replaced (symlinks followed) or, for a device or FIFO, written into.
    tmp : Path
        The temporary file the writer writes.
    stream : bool
        The target is a character device or FIFO: its content is copied into it, it is not replaced.
    mode : int or None
        The target's mode before the write; None when it does not exist yet.
    """

    name: str
    target: Path
    tmp: Path
    stream: bool
    mode: int | None


def inspect_target(path: str | os.PathLike) -> tuple[Path, int | None, bool]:
    """Where an output goes: (target with symlinks followed, its mode or None, whether it is streamed into).

    Raises
    ------
    IsADirectoryError
        ``path`` is a folder.
    FileNotFoundError
        Its folder does not exist.
    NotADirectoryError
        Its folder is a file.
    OSError
        ``path`` is a block device, socket or other special file.
    """
    name = os.fspath(path)
    target = Path(os.path.realpath(name))  # follow symlinks: replace what the link points at
    mode = _mode(target)
    if mode is not None and not stat.S_ISREG(mode):
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(f"{name}: is a directory; give a file name to write.")
        if not (stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):
            raise OSError(f"{name}: is not a regular file, a character device or a FIFO; refusing to replace it.")
        return target, mode, True
    if not target.parent.exists():
        raise FileNotFoundError(f"{name}: folder {target.parent} does not exist; create it first.")
    if not target.parent.is_dir():
        raise NotADirectoryError(f"{name}: {target.parent} is not a folder.")
    return target, mode, False


def stage(path: str | os.PathLike, *, suffix: str | None = None) -> Staged:
    """Create the temporary file of one output (:func:`inspect_target` first); errors name ``path``.

    A device or FIFO is not replaced but written into, and writers may seek (zip, MP4), which a FIFO cannot:
    its temporary file goes to the temporary folder (not /dev).
    """
    name = os.fspath(path)
    target, mode, stream = inspect_target(name)
    folder = Path(tempfile.gettempdir()) if stream else target.parent
    remove_stale_temporaries(folder / target.name)
    with naming_target(name, folder=folder):
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.pid{os.getpid()}-",
                                   suffix=(suffix if suffix is not None else target.suffix) + ".part", dir=folder)
    os.close(fd)
    return Staged(name, target, Path(tmp), stream, mode)


def publish(staged: Sequence[Staged]) -> None:
    """Put written outputs in place together: all of them, or none (the previous versions restored).

    Devices and FIFOs are written first (their content cannot be taken back, so nothing is replaced before
    they have taken it), then each regular file is renamed over its target. Before a rename that another
    one follows, the target's previous version is kept as a hard link (or a copy), so that a failing later
    rename can put it back; a target that did not exist is removed again.

    Raises
    ------
    OSError
        Naming the user's file that could not be put in place.
    """
    done: list[tuple[Staged, Path | None]] = []
    backups: list[Path] = []
    regular = [s for s in staged if not s.stream]
    try:
        for s in staged:
            if s.stream:
                with naming_target(s.name, s.tmp), open(s.tmp, "rb") as src, open(s.target, "wb") as dst:
                    shutil.copyfileobj(src, dst, 1 << 20)
                s.tmp.unlink()
        for i, s in enumerate(regular):
            with naming_target(s.name, s.tmp):
                _give_permissions(s)
                backup = _keep_previous(s) if i < len(regular) - 1 else None
                if backup is not None:
                    backups.append(backup)
                os.replace(s.tmp, s.target)
            done.append((s, backup))
    except BaseException:
        for s, backup in reversed(done):
            with contextlib.suppress(OSError):
                if backup is not None:
                    os.replace(backup, s.target)
                elif s.mode is None:
                    s.target.unlink()
        discard(staged)
        raise
    finally:
        for backup in backups:
            with contextlib.suppress(FileNotFoundError):
                backup.unlink()


def discard(staged: Sequence[Staged]) -> None:
    """Remove the temporary files of outputs that are not published."""
    for s in staged:
        with contextlib.suppress(FileNotFoundError):
            s.tmp.unlink()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a path to write; on success it becomes ``path``.

    For a regular file (or a new one) the yielded path is a temporary file in the target's folder, renamed
    over the target once the block completes: a crash or exception leaves the target untouched (an older
    version stays whole) and removes the temporary file, so no half-written output ever looks complete.
    For a character device or FIFO the temporary file is in the temporary folder and its complete content
    is written into the device once the block completes (the device node stays). A symlink is followed: its
    target is replaced atomically and the link stays. Inside an output plan (:data:`ACTIVE_PLAN`) that
    declared ``path``, the plan's temporary file is yielded and the plan publishes it with its other outputs.

    Parameters
    ----------
    path : path-like
        The final file.
    suffix : str, optional
        Suffix of the temporary file (some writers, e.g. numpy's savez, insist on one); default: the target's.

    Raises
    ------
    OSError
        Where the output cannot go (:func:`inspect_target`: a folder, a missing folder, a special file), or
        writing failed (disk full, no permission), said with ``path``, never the temporary file's name.
    """
    plan = ACTIVE_PLAN.get()
    if plan is not None and plan.holds(path):
        with plan.staged(path) as tmp:
            yield tmp
        return
    staged = stage(path, suffix=suffix)
    try:
        with naming_target(staged.name, staged.tmp):
            yield staged.tmp
        publish([staged])
    except BaseException:
        discard([staged])
        raise


@contextlib.contextmanager
def naming_target(name: str, tmp: Path | None = None, *, folder: Path | None = None) -> Iterator[None]:
    """Re-raise an OSError of writing ``name`` so that it names ``name``, never the temporary file ``tmp``.

    A full disk says "[Errno 28] No space left on device" and names no file; a read-only folder names the
    temporary file the user never asked for. Both become ``NAME: cannot write it: REASON`` (with the
    folder where the temporary file could not be created), of the same class and errno. An error that
    names ``name`` already (and not the temporary file) is left as it is.
    """
    try:
        yield
    except OSError as exc:
        if not _about_temporary(exc, name, tmp, folder):
            raise
        where = f" in folder {folder}" if folder is not None else ""
        message = f"{name}: cannot write it{where}: {exc.strerror or exc}"
        try:
            renamed = type(exc)(message)
        except Exception:  # an OSError subclass with another signature: keep the family
            renamed = OSError(message)
        renamed.errno = exc.errno
        raise renamed from None


def _about_temporary(exc: OSError, name: str, tmp: Path | None, folder: Path | None) -> bool:
    """Whether ``exc`` is about writing the temporary file of ``name`` rather than about something else: it
    names the temporary file (or one in ``folder``, where it was to be created), or it is a system error that
    names no file at all (a full disk) and does not name ``name`` either."""
    text = str(exc)
    if tmp is not None and (str(tmp) in text or tmp.name in text):
        return True
    if exc.filename is not None:
        filename = os.fspath(exc.filename)
        return (tmp is not None and filename == str(tmp)) or (
            folder is not None and os.path.dirname(filename) == str(folder))
    return exc.errno is not None and name not in text


def _give_permissions(s: Staged) -> None:
    # mkstemp creates the file readable by its owner only: keep the replaced file's permissions, else give the
    # ones a plain open() would.
    if s.mode is not None:
        os.chmod(s.tmp, stat.S_IMODE(s.mode))
    else:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(s.tmp, 0o666 & ~umask)


def _keep_previous(s: Staged) -> Path | None:
    """A hard link (or, where the file system has none, a copy) of the target's current version beside it,
    named as a temporary file of this process; None when there is no previous version."""
    if s.mode is None:
        return None
    fd, name = tempfile.mkstemp(prefix=f".{s.target.name}.pid{os.getpid()}-", suffix=".old.part",
                                dir=s.target.parent)
    os.close(fd)
    backup = Path(name)
    backup.unlink()
    try:
        os.link(s.target, backup)
    except OSError:
        shutil.copy2(s.target, backup)
    return backup


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
