"""One output plan per command: every file it reads and writes declared and checked before any work, the outputs
published together once all are written.

A command declares its inputs (:meth:`OutputPlan.read`) and outputs (:meth:`OutputPlan.write`,
:meth:`OutputPlan.write_folder`), then does its work inside ``with plan:``. Entering checks everything at once,
before a possibly long computation: every input is a regular file (or a ROS 2 bag folder); no output is an input or
another output (also through ``..``, symlinks and hard links); each output's name fits what is written into it (a
known extension of its kind, or none: a name without extension gets the command's own format; devices and FIFOs are
streams, whatever their names); its folder exists (or is a folder the plan creates) and a temporary file can be made
there, so that a read-only folder is reported before the work, not after. Inside the block the writers write as they
always do (:func:`cvstereo.io.atomic.atomic_path`), into the plan's temporary files. Leaving the block publishes
every output that was written (:func:`cvstereo.io.atomic.publish`: all or none, previous versions restored); an
exception or a signal instead removes the temporary files and the folders the plan created, so that a failed run
leaves no output, half or whole. Every error names the user's path.

>>> import os, tempfile
>>> from pathlib import Path
>>> from cvstereo.io.atomic import write_text_atomic
>>> a, b = (os.path.join(tempfile.mkdtemp(), name) for name in ("a.txt", "b.txt"))
>>> plan = OutputPlan()
>>> plan.write(a, ANY_FILE)
>>> plan.write(b, ANY_FILE)
>>> with plan:
...     write_text_atomic(a, "one")
...     print(os.path.exists(a))  # written, not yet published: b is still to come
...     write_text_atomic(b, "two")
False
>>> Path(a).read_text(), Path(b).read_text()
('one', 'two')
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from cvstereo.io.atomic import (
    ACTIVE_PLAN,
    Staged,
    discard,
    inspect_target,
    naming_target,
    publish,
    stage,
)
from cvstereo.io.files import require_input
from cvstereo.io.paths import OutputIsInputError, refuse_output_over_input, same_file


class OutputKind(NamedTuple):
    """What an output holds, for messages, and the extensions its name may have (empty: any)."""

    what: str
    suffixes: tuple[str, ...] = ()


#: The kinds of output the commands write. A name without extension is taken as the kind's format.
MATCHES_FILE = OutputKind("a matches file", (".npz",))
POINT_CLOUD = OutputKind("a PLY point cloud", (".ply",))
DEPTH_MODEL_FILE = OutputKind("a depth-model file", (".json",))
#: The picture formats matplotlib writes without extra packages.
FIGURE = OutputKind("a picture", (".png", ".pdf", ".svg", ".svgz", ".eps", ".ps", ".jpg", ".jpeg", ".tif",
                                  ".tiff", ".webp"))
VIDEO = OutputKind("an MP4 video", (".mp4",))
RERUN_FILE = OutputKind("a rerun recording", (".rrd",))
#: Files whose format another check settles (``convert``: the format table), or whose names the command makes.
ANY_FILE = OutputKind("a file")


@dataclass
class _Output:
    path: str
    kind: OutputKind
    option: str
    staged: Staged | None = None
    written: bool = False


@dataclass
class OutputPlan:
    """The inputs and outputs of one command (see the module doc).

    Attributes
    ----------
    inputs : list of str
        The files read.
    outputs : list
        The files written, in the order declared (the order they are published in).
    folders : list of Path
        Folders the outputs go into that the plan creates when missing.
    """

    inputs: list[str] = field(default_factory=list)
    outputs: list[_Output] = field(default_factory=list)
    folders: list[Path] = field(default_factory=list)
    _what: dict[str, str] = field(default_factory=dict)
    _created: list[Path] = field(default_factory=list)
    _checked: bool = False
    _token: object = None

    def read(self, *paths: str | os.PathLike | None, what: str | None = None) -> None:
        """Declare input files (None entries are skipped); ``what`` they are, where a missing one should say so
        (e.g. ``"depth-model file (write one with `cvstereo depth-fit -o`)"``)."""
        from cvstereo.io.dsec_sequence import find_dsec_sequence, is_dsec_sequence

        for p in paths:
            if p is not None and is_dsec_sequence(p):  # a folder read as one input: its files are the inputs
                self.inputs.extend(os.fspath(f) for f in find_dsec_sequence(p).files())
            elif p is not None:
                self.inputs.append(os.fspath(p))
                if what is not None:
                    self._what[os.fspath(p)] = what

    def write(self, path: str | os.PathLike | None, kind: OutputKind, *, option: str = "-o") -> None:
        """Declare an output file (None: nothing), of ``kind``, named on the command line by ``option``."""
        if path is not None:
            self.outputs.append(_Output(os.fspath(path), kind, option))

    def write_folder(self, folder: str | os.PathLike, names: Iterable[str], kind: OutputKind, *,
                     option: str = "-o") -> list[Path]:
        """Declare a folder (created when missing) and the files written into it; return their paths.

        Raises
        ------
        NotADirectoryError
            ``folder`` exists and is not a folder.
        """
        folder = Path(folder)
        if folder.exists() and not folder.is_dir():
            raise NotADirectoryError(f"{option} {folder}: exists and is not a folder; this command writes its "
                                     "files into a folder.")
        paths = [folder / name for name in names]
        for p in [folder, *sorted({p.parent for p in paths} - {folder})]:  # subfolders the names give too
            if p not in self.folders:
                self.folders.append(p)
        for p in paths:
            self.outputs.append(_Output(os.fspath(p), kind, option))
        return paths

    def check(self) -> None:
        """Check every input and output (see the module doc) and make the outputs' temporary files.

        Raises
        ------
        FileNotFoundError, IsADirectoryError, NotADirectoryError, OSError
            An input that is not a regular file; an output whose folder is missing or that is a folder or a
            special file; a folder where no file can be created (read-only, full).
        ValueError
            An output named for another format (:class:`OutputIsInputError` for one that is an input or
            another output).
        """
        for path in self.inputs:
            try:
                require_input(path)
            except FileNotFoundError:
                if path not in self._what:
                    raise
                raise FileNotFoundError(f"{path}: no such {self._what[path]}.") from None
        for i, out in enumerate(self.outputs):
            refuse_output_over_input(out.path, self.inputs, option=out.option)
            for other in self.outputs[:i]:
                if _collide(out.path, other.path):
                    same = "" if out.path == other.path else f" {other.option} {other.path}"
                    raise OutputIsInputError(f"{out.option} {out.path} and{same or ' itself'}: the same file is "
                                             "given as two outputs; one would destroy the other: give two names.")
            self._check_name(out)
        try:
            for folder in self.folders:
                self._make_folder(folder)
            for out in self.outputs:
                out.staged = stage(out.path)
        except BaseException:
            self._abandon()
            raise
        self._checked = True

    def holds(self, path: str | os.PathLike) -> bool:
        """Whether ``path`` is an output of this plan that has not been written yet."""
        return self._find(path) is not None

    @contextlib.contextmanager
    def staged(self, path: str | os.PathLike) -> Iterator[Path]:
        """The temporary file of output ``path``; written once the block completes (published at the end)."""
        out = self._find(path)
        if out is None or out.staged is None:
            raise RuntimeError(f"{os.fspath(path)}: not an output of this command's plan (an internal error).")
        with naming_target(out.path, out.staged.tmp):
            yield out.staged.tmp
        out.written = True

    def __enter__(self) -> OutputPlan:
        if not self._checked:
            self.check()
        self._token = ACTIVE_PLAN.set(self)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        ACTIVE_PLAN.reset(self._token)
        if exc_type is not None:
            self._abandon()
            return
        written = [out.staged for out in self.outputs if out.written]
        discard([out.staged for out in self.outputs if not out.written and out.staged is not None])
        try:
            publish(written)
        except BaseException:
            self._abandon()
            raise
        for out in self.outputs:
            out.staged = None
        self._checked = False

    def _check_name(self, out: _Output) -> None:
        """An output's name must not say another format than its kind's (devices and FIFOs are streams)."""
        _, _, stream = inspect_target(out.path) if _exists(out.path) else (None, None, False)
        suffix = Path(out.path).suffix.lower()
        if stream or not out.kind.suffixes or not suffix or suffix in out.kind.suffixes:
            return
        raise ValueError(f"{out.option} {out.path}: this writes {out.kind.what}, and '{suffix}' names something "
                         f"else; name it {' or '.join(out.kind.suffixes)} (or leave the extension out).")

    def _make_folder(self, folder: Path) -> None:
        missing = []
        p = folder
        while not p.exists():
            missing.append(p)
            p = p.parent
        for p in reversed(missing):
            p.mkdir()
            self._created.append(p)

    def _find(self, path) -> _Output | None:
        name = os.fspath(path)
        pending = [out for out in self.outputs if out.staged is not None and not out.written]
        return next((o for o in pending if o.path == name), None) or next(
            (o for o in pending if os.path.realpath(o.path) == os.path.realpath(name)), None)

    def _abandon(self) -> None:
        """Remove every temporary file and every folder this plan created (those left empty)."""
        discard([out.staged for out in self.outputs if out.staged is not None])
        for out in self.outputs:
            out.staged, out.written = None, False
        self._checked = False
        for folder in reversed(self._created):
            with contextlib.suppress(OSError):
                folder.rmdir()
        self._created.clear()


def _exists(path: str) -> bool:
    return os.path.lexists(path)


def _collide(a: str, b: str) -> bool:
    """Two outputs that would land in one file (a character device such as /dev/null takes any number)."""
    if not same_file(a, b):
        return False
    with contextlib.suppress(OSError):
        return not stat.S_ISCHR(os.stat(a).st_mode)
    return True


__all__ = ["ANY_FILE", "DEPTH_MODEL_FILE", "FIGURE", "MATCHES_FILE", "POINT_CLOUD", "RERUN_FILE", "VIDEO", "OutputKind",
           "OutputPlan"]
