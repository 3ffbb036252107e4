"""Hostile calls of the Python API, classified as ``tests/_hostile.py`` classifies command lines.

A call that must be refused fails with ``SILENT`` when it returns, ``TRACEBACK`` when it raises something
other than the library's errors (a ValueError, OSError or TimeoutError subclass, or a TypeError for a misused
argument), and ``MESSAGE`` when the message lacks a fragment, spans lines or shows a number as a cast wrote it.
A value that must be right fails with ``SILENT`` when it is not.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

#: What the library raises for bad input (design: subclasses of these built-ins), and TypeError for argument misuse.
LIBRARY_ERRORS = (ValueError, OSError, TimeoutError, TypeError)
#: What a reader raises for a bad file: the errors the CLI reports in one line (a TypeError would be a traceback).
FILE_ERRORS = (ValueError, OSError)


def refused(call, *fragments: str, absent: tuple[str, ...] = (), errors: tuple = LIBRARY_ERRORS) -> str:
    """Run ``call()``; assert it raises one of ``errors`` whose one-line message holds every fragment; return it."""
    try:
        got = call()
    except errors as exc:
        message = str(exc)
    except BaseException as exc:  # the point is to see what escapes
        raise AssertionError(f"TRACEBACK: {type(exc).__name__}: {exc}") from None
    else:
        raise AssertionError(f"SILENT: returned {_brief(got)} instead of refusing")
    assert "\n" not in message, f"MESSAGE: not one line: {message!r}"
    for fragment in fragments:
        assert fragment in message, f"MESSAGE: {fragment!r} not in {message!r}"
    for fragment in absent:
        assert fragment not in message, f"MESSAGE: {fragment!r} in {message!r}"
    return message


def accepted(call):
    """Run ``call()``; a library error is a ``MESSAGE`` failure (a refusal of good input), anything else escaping a
    ``TRACEBACK``. Returns what the call returned."""
    try:
        return call()
    except LIBRARY_ERRORS as exc:
        raise AssertionError(f"MESSAGE: good input refused: {type(exc).__name__}: {exc}") from None
    except BaseException as exc:
        raise AssertionError(f"TRACEBACK: {type(exc).__name__}: {exc}") from None


def same_events(got: np.ndarray, want: dict[str, np.ndarray], what: str) -> None:
    """Assert that ``got`` holds exactly the columns ``want`` (t, x, y, p), else a ``SILENT`` failure naming the
    first differing field and index."""
    assert got.size == len(want["t"]), f"SILENT: {what}: {got.size} events, expected {len(want['t'])}"
    for field in ("t", "x", "y", "p"):
        diff = np.flatnonzero(got[field].astype(np.int64) != np.asarray(want[field]).astype(np.int64))
        assert diff.size == 0, (f"SILENT: {what}: field {field} at index {diff[0]} is {got[field][diff[0]]}, "
                                f"expected {want[field][diff[0]]}")


def working_copy(base: Path, folder: Path, monkeypatch) -> Path:
    """Copy every file and folder of ``base`` (a module's files, made once) into ``folder`` and work there."""
    for p in base.iterdir():
        (shutil.copytree if p.is_dir() else shutil.copy2)(p, folder / p.name)
    monkeypatch.chdir(folder)
    return folder


def _brief(value) -> str:
    text = repr(value)
    return text if len(text) < 200 else text[:197] + "..."
