"""The harness of the hostile corpora: run the CLI in-process and classify what went wrong.

A failing case names the kind of failure in its message, so that a run of a corpus against an older version
gives the tally of an issue's closing note (``python bench/hostile_tally.py``):

- ``TRACEBACK``: an exception escaped ``main`` or a traceback was printed;
- ``HANG``: the command did not end within its time limit;
- ``DATALOSS``: a file present before the run changed or vanished, or a published output is incomplete;
- ``SILENT``: exit 0 (or a value) where an error, or another value, was expected;
- ``MESSAGE``: the right refusal in the wrong words (exit code, not one line, the file or option not named);
- ``LEFTOVER``: a temporary ``.part`` file or an output of a failed run was left behind.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import stat
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

from cvstereo.cli import main

KINDS = ("TRACEBACK", "HANG", "DATALOSS", "SILENT", "MESSAGE", "LEFTOVER")


def snapshot(folder: Path) -> dict[str, str]:
    """sha256 of every regular file; the kind of everything else (a device, FIFO or symlink replaced by a
    regular file is a change), the link's target for symlinks. Devices and FIFOs are not opened."""
    out = {}
    for p in folder.rglob("*"):
        st = os.lstat(p)
        key = str(p.relative_to(folder))
        if stat.S_ISREG(st.st_mode):
            out[key] = hashlib.sha256(p.read_bytes()).hexdigest()
        elif stat.S_ISLNK(st.st_mode):
            out[key] = "symlink -> " + os.readlink(p)
        else:
            out[key] = stat.filemode(st.st_mode)[0] + (f" {os.major(st.st_rdev)},{os.minor(st.st_rdev)}"
                                                       if stat.S_ISCHR(st.st_mode) else "")
    return out


def leftovers(folder: Path) -> list[str]:
    """Temporary files of the atomic writers left in ``folder``."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if ".part" in p.name)


def null_device(path: Path) -> None:
    """A character device like /dev/null at ``path``, so that a writer that replaces devices (as root) harms
    only the test's folder, never the system's /dev/null. Without the right to make one, a symlink to
    /dev/null: a process that cannot make device nodes cannot replace /dev/null either."""
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        with open(path, "wb") as fh:  # a folder mounted nodev refuses to open device nodes
            fh.write(b"x")
    except OSError:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        if os.geteuid() == 0:
            pytest.skip("cannot make a device node in the test folder (as root /dev/null itself is not risked)")
        os.symlink(os.devnull, path)


def run_cli(argv: Iterable[str]) -> tuple[int, str]:
    """``main(argv)`` -> (exit code, ``"TRACEBACK: ..."`` when an exception escaped, else ``""``)."""
    try:
        return main(list(argv)), ""
    except SystemExit as exc:
        return int(exc.code or 0) if not isinstance(exc.code, str) else 2, ""
    except BaseException as exc:  # the point is to see what escapes
        return -1, f"TRACEBACK: {type(exc).__name__}: {exc}"


@dataclass(frozen=True)
class Case:
    """One command line and what it must do.

    ``code`` 0: it succeeds; 1: a user error, one line ``cvstereo CMD: error: ...`` holding every fragment of
    ``err``; 2: a usage error. ``writes``: the files it may create or change (anything else must keep its
    bytes); ``absent``: files that must not exist afterwards (outputs of a refused run).
    """

    argv: tuple[str, ...]
    code: int
    err: tuple[str, ...] = ()
    out: tuple[str, ...] = ()
    writes: tuple[str, ...] = ()
    absent: tuple[str, ...] = ()
    no_out: tuple[str, ...] = ("nan", "NaN")


def case(cmd: str | Iterable[str], code: int, err=(), out=(), writes=(), absent=(), no_out=("nan", "NaN")) -> Case:
    """A :class:`Case` from a command line (split on white space when given as one string)."""

    def as_tuple(v):
        return (v,) if isinstance(v, str) else tuple(v)

    argv = tuple(cmd.split()) if isinstance(cmd, str) else tuple(cmd)
    return Case(argv, code, as_tuple(err), as_tuple(out), as_tuple(writes), as_tuple(absent), as_tuple(no_out))


def check_case(c: Case, work: Path, capsys) -> tuple[str, str]:
    """Run ``c`` in ``work`` (the current folder) and assert everything it promises; return (stdout, stderr).

    Every assertion message starts with the kind of failure (:data:`KINDS`).
    """
    before = snapshot(work)
    code, escaped = run_cli(c.argv)
    out, err = capsys.readouterr()
    assert not escaped, escaped
    assert "Traceback" not in err, f"TRACEBACK: {err}"
    after = snapshot(work)
    changed = sorted(k for k, h in before.items() if after.get(k) != h and k not in c.writes)
    assert not changed, f"DATALOSS: {changed} changed or removed"
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    if c.code != 0:
        assert code != 0, f"SILENT: exit 0, expected {c.code}; stdout {out!r}"
        stray = [name for name in c.absent if (work / name).exists() and name not in before]
        assert not stray, f"LEFTOVER: {stray} written by a refused run"
    assert code == c.code, f"MESSAGE: exit {code}, expected {c.code}: {err}"
    if code == 1:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"cvstereo {c.argv[0]}: error: "), f"MESSAGE: {err!r}"
    for fragment in c.err:
        assert fragment in err, f"MESSAGE: {fragment!r} not in {err!r}"
    for fragment in c.out:
        assert fragment in out, f"MESSAGE: {fragment!r} not in stdout {out!r}"
    for word in c.no_out:
        assert word not in out, f"SILENT: {word!r} printed: {out!r}"
    assert "\x1b" not in err + out and "\x07" not in err + out, "MESSAGE: raw terminal codes printed"
    return out, err
