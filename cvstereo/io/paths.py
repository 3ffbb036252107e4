"""Checks on the files a command reads and writes, before anything is read or written.

:func:`refuse_output_over_input` stops a command whose output would replace one of its inputs (also through
a symlink or a hard link). Inputs that are not regular files (a folder, a FIFO, a device) are refused by
:func:`cvstereo.io.files.require_regular_file`, the one check every reader uses too.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable

__all__ = ["OutputIsInputError", "refuse_output_over_input", "same_file"]


class OutputIsInputError(ValueError):
    """An output path names the same file as an input (or as another output of the same command)."""


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether two paths name one file: the same inode (symlinks followed, hard links seen), or, for paths
    that do not exist yet, the same resolved path."""
    try:
        sa, sb = os.stat(a), os.stat(b)
    except (FileNotFoundError, NotADirectoryError):
        return os.path.realpath(a) == os.path.realpath(b)
    except OSError:
        return False
    return (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)


def refuse_output_over_input(output: str | os.PathLike | None, inputs: Iterable[str | os.PathLike | None], *,
                             option: str = "-o", what: str = "input") -> None:
    """Raise :class:`OutputIsInputError` when ``output`` is one of ``inputs``.

    Symlinks are followed and hard links recognised (same device and inode), so ``-o link.npz`` where
    ``link.npz`` points at the input is refused like ``-o in.npz``. Character devices and FIFOs
    (``-o /dev/null``) never count as an input being overwritten.

    Parameters
    ----------
    output : path-like or None
        The file the command will write; None: nothing to check.
    inputs : iterable of path-like or None
        The files it reads (None entries are skipped).
    option : str, keyword-only
        The option that named ``output``, for the message (``-o``, ``--journal``, ...).
    what : str, keyword-only
        What ``inputs`` are, for the message (``input``, ``other output``, ...).

    Raises
    ------
    OutputIsInputError
        A ValueError naming both paths and saying how to fix it.
    """
    if output is None:
        return
    with_mode = _mode(output)
    if with_mode is not None and (stat.S_ISCHR(with_mode) or stat.S_ISFIFO(with_mode)):
        return
    for source in inputs:
        if source is None:
            continue
        if same_file(output, source):
            same = "" if os.fspath(output) == os.fspath(source) else f" {os.fspath(source)}"
            raise OutputIsInputError(
                f"{option} {os.fspath(output)} is the {what}{same} (the same file): writing it would destroy "
                f"the {what}; choose another output name."
            )


def _mode(path: str | os.PathLike) -> int | None:
    try:
        return os.stat(path).st_mode
    except OSError:
        return None
