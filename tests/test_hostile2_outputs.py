"""Hostile outputs (issue 27): every output declared up front and checked against every input and every other
output, published only once all are written, refused when its name says another format, and every write error
naming the user's file rather than a hidden temporary.

Cases run ``cvstereo.cli.main`` in-process (``tests/_hostile.py``); the failures of a full disk or a read-only
folder are simulated by making the write or the temporary file's creation fail with the error the system gives.
Every failure message starts with its kind (TRACEBACK, DATALOSS, SILENT, MESSAGE, LEFTOVER).
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from cvstereo.depth import DepthModel
from cvstereo.depth_file import save_depth_model

from cvstereo.io import read_matches, write_matches, write_recording
from tests._hostile import Case, case, check_case, leftovers, null_device, run_cli, snapshot
from tests._io_helpers import textured_blobs

pytestmark = pytest.mark.timeout(120)

W = 40_000
#: A depth model for the cases that need one: d = 16.5/Z.
DEPTH = ("--depth", "16.5", "0")


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """The files every case reads, made once."""
    from calibration_free import match

    d = tmp_path_factory.mktemp("outputs-base")
    rec = textured_blobs(0, 4, disparity=13, window_us=W)
    write_recording(d / "rec.npz", rec)
    result = match(d / "rec.npz", method="frame")
    assert len(result) > 20
    write_matches(d / "m.npz", result.matches, result.meta)
    far = result.matches.copy()
    far["disparity"] /= 2
    write_matches(d / "m_far.npz", far, result.meta)
    save_depth_model(d / "model.json", DepthModel(a=16.5, c=0.0))
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    for p in base.iterdir():
        shutil.copy2(p, tmp_path / p.name)
    (tmp_path / "sub").mkdir()
    (tmp_path / "dir.ply").mkdir()
    (tmp_path / "old.npz").write_bytes(b"old matches")
    os.link(tmp_path / "old.npz", tmp_path / "old-hard.ply")
    os.symlink("old.npz", tmp_path / "old-link.ply")
    null_device(tmp_path / "null.dev")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _cmd(*parts: str) -> tuple[str, ...]:
    return tuple(p for part in parts for p in part.split())


SAME = "the same file"
CASES = {
    # --- two outputs of one command naming one file -------------------------------------------------------
    "match-pointcloud-npz-is-o": case(_cmd("match rec.npz --point-cloud pc.npz -o pc.npz", *DEPTH), 1,
                                      ("--point-cloud pc.npz",), absent="pc.npz"),
    "match-pointcloud-is-o-no-suffix": case(_cmd("match rec.npz --point-cloud out -o out", *DEPTH), 1,
                                            (SAME, "out"), absent="out"),
    "match-pointcloud-is-o-dotdot": case(_cmd("match rec.npz --point-cloud sub/../out -o out", *DEPTH), 1,
                                         SAME, absent="out"),
    "match-pointcloud-symlink-to-o": case(_cmd("match rec.npz --point-cloud old-link.ply -o old.npz", *DEPTH), 1,
                                          (SAME, "old-link.ply")),
    "match-pointcloud-hardlink-of-o": case(_cmd("match rec.npz --point-cloud old-hard.ply -o old.npz", *DEPTH), 1,
                                           (SAME, "old-hard.ply")),
    # --- outputs over inputs the old checks did not see ------------------------------------------------------
    "match-o-depth-model-file": case(_cmd("match rec.npz --depth model.json -o model.json"), 1, "model.json"),
    "match-pointcloud-over-recording": case(_cmd("match rec.npz --point-cloud rec.npz -o m2.npz", *DEPTH), 1,
                                            "rec.npz", absent="m2.npz"),
    # --- a name that says another format ----------------------------------------------------------------------
    "match-o-ply": case("match rec.npz -o m.ply", 1, ("-o m.ply", ".npz"), absent="m.ply"),
    "match-o-unknown-suffix": case("match rec.npz -o m.final", 1, ("-o m.final", ".npz"), absent="m.final"),
    "match-o-json": case("match rec.npz -o m.json", 1, ("-o m.json", ".npz"), absent="m.json"),
    "match-o-no-suffix": case("match rec.npz -o mfile", 0, out="-> mfile", writes="mfile"),
    "match-pointcloud-txt": case(_cmd("match rec.npz --point-cloud pc.txt -o m2.npz", *DEPTH), 1,
                                 ("--point-cloud pc.txt", ".ply"), absent=("pc.txt", "m2.npz")),
    "match-pointcloud-folder": case(_cmd("match rec.npz --point-cloud dir.ply -o m2.npz", *DEPTH), 1,
                                    ("dir.ply", "directory"), absent="m2.npz"),
    "match-pointcloud-missing-folder": case(_cmd("match rec.npz --point-cloud nofolder/pc.ply -o m2.npz", *DEPTH),
                                            1, ("nofolder", "does not exist"), absent="m2.npz"),
    "match-pointcloud-null-device": case(_cmd("match rec.npz --point-cloud null.dev -o m2.npz", *DEPTH), 0,
                                         out="-> null.dev", writes="m2.npz"),
    "depth-fit-o-npz": case("depth-fit m.npz:0.5 m_far.npz:1 -o d.npz", 1, ("-o d.npz", ".json"), absent="d.npz"),
    "depth-fit-o-no-suffix": case("depth-fit m.npz:0.5 m_far.npz:1 -o dmodel", 0, out="dmodel", writes="dmodel"),
    "plot-o-npz": case("plot events rec.npz -o p.npz", 1, ("-o p.npz", ".png"), absent="p.npz"),
    "plot-o-txt": case("plot events rec.npz -o p.txt", 1, ("-o p.txt", ".png"), absent="p.txt"),
    "video-o-no-suffix": case("video rec.npz -o vid --scale 1", 0, out="-> vid", writes="vid"),
    "video-o-null-device": case("video rec.npz -o null.dev --scale 1", 0, out="-> null.dev"),
    "video-o-npz": case("video rec.npz -o v.npz --scale 1", 1, ("-o v.npz", ".mp4"), absent="v.npz"),
    # --- --focal-px ----------------------------------------------------------------------------------------------
    "match-focal-inf": case(_cmd("match rec.npz --point-cloud pc.ply --focal-px inf -o m2.npz", *DEPTH), 1,
                            "--focal-px", absent=("pc.ply", "m2.npz")),
    "match-focal-nan": case(_cmd("match rec.npz --point-cloud pc.ply --focal-px nan -o m2.npz", *DEPTH), 1,
                            "--focal-px", absent=("pc.ply", "m2.npz")),
    "match-focal-zero": case(_cmd("match rec.npz --point-cloud pc.ply --focal-px 0 -o m2.npz", *DEPTH), 1,
                             "--focal-px", absent=("pc.ply", "m2.npz")),
    "match-focal-without-pointcloud": case(_cmd("match rec.npz --focal-px 200 -o m2.npz", *DEPTH), 2,
                                           "--point-cloud", absent="m2.npz"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_output(hostile: Case, work: Path, capsys):
    pytest.importorskip("plyfile")
    if hostile.argv[0] == "plot":
        pytest.importorskip("matplotlib")
    check_case(hostile, work, capsys)


# ------------------------------------------------------------------------------------------------ effects

def _enospc(*args, **kwargs):
    """A write on a full disk: ENOSPC, and no file name (the system names none)."""
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _savez_on_full_disk(fh, *args, **kwargs):
    """``np.savez_compressed`` on a full disk: part of the archive is written, then ENOSPC."""
    fh.write(b"PK partial")
    _enospc()


def _run(argv, capsys) -> tuple[int, str, str]:
    code, escaped = run_cli(argv)
    out, err = capsys.readouterr()
    assert not escaped, escaped
    assert "Traceback" not in err, f"TRACEBACK: {err}"
    return code, out, err


def _one_line_naming(err: str, command: str, name: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"cvstereo {command}: error: "), f"MESSAGE: {err!r}"
    assert name in err, f"MESSAGE: {name!r} not named: {err!r}"
    assert ".part" not in err, f"MESSAGE: the hidden temporary is named: {err!r}"


def test_full_disk_on_the_matches_file_publishes_no_point_cloud(work, monkeypatch, capsys):
    pytest.importorskip("plyfile")
    monkeypatch.setattr(np, "savez_compressed", _savez_on_full_disk)
    code, _, err = _run(_cmd("match rec.npz --point-cloud pc.ply -o m2.npz", *DEPTH), capsys)
    assert code == 1, f"SILENT: exit {code}"
    assert not (work / "pc.ply").exists(), "LEFTOVER: the point cloud of a failed run was published"
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    _one_line_naming(err, "match", "m2.npz")
    assert "No space left" in err, f"MESSAGE: the reason is not said: {err!r}"


def test_full_disk_on_the_point_cloud_publishes_no_matches(work, monkeypatch, capsys):
    plyfile = pytest.importorskip("plyfile")
    monkeypatch.setattr(plyfile.PlyData, "write", _enospc)
    code, _, err = _run(_cmd("match rec.npz --point-cloud pc.ply -o m2.npz", *DEPTH), capsys)
    assert code == 1, f"SILENT: exit {code}"
    assert not (work / "m2.npz").exists(), "LEFTOVER: the matches of a failed run were published"
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    _one_line_naming(err, "match", "pc.ply")


def test_full_disk_keeps_the_previous_outputs_whole(work, monkeypatch, capsys):
    pytest.importorskip("plyfile")
    (work / "pc.ply").write_bytes(b"previous cloud")
    shutil.copy(work / "m.npz", work / "m2.npz")
    before = snapshot(work)
    monkeypatch.setattr(np, "savez_compressed", _savez_on_full_disk)
    code, _, err = _run(_cmd("match rec.npz --point-cloud pc.ply -o m2.npz", *DEPTH), capsys)
    assert code == 1, f"SILENT: exit {code}"
    changed = sorted(k for k, v in before.items() if snapshot(work).get(k) != v)
    assert not changed, f"DATALOSS: {changed} changed by a failed run"
    _one_line_naming(err, "match", "m2.npz")


@pytest.mark.parametrize("failing", ["m2.npz", "pc.ply"])
def test_a_failed_publication_restores_the_outputs_already_replaced(work, monkeypatch, capsys, failing):
    """The last step, replacing the old files by the new ones, fails for one output: the other keeps its old
    version too (the run's outputs come as a set)."""
    pytest.importorskip("plyfile")
    (work / "pc.ply").write_bytes(b"previous cloud")
    shutil.copy(work / "m.npz", work / "m2.npz")
    before = snapshot(work)
    real_replace, failed = os.replace, []

    def replace(src, dst, *args, **kwargs):
        if os.path.basename(os.fspath(dst)) == failing and not failed:
            failed.append(dst)
            raise OSError(errno.EIO, os.strerror(errno.EIO))
        return real_replace(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", replace)
    code, _, err = _run(_cmd("match rec.npz --point-cloud pc.ply -o m2.npz", *DEPTH), capsys)
    assert failed, "SILENT: the output was never replaced"
    assert code == 1, f"SILENT: exit {code}"
    changed = sorted(k for k, v in before.items() if snapshot(work).get(k) != v)
    assert not changed, f"DATALOSS: {changed} left changed by a failed run"
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    _one_line_naming(err, "match", failing)


def test_read_only_folder_is_named_as_the_users_path(work, monkeypatch, capsys):
    """A folder the process may not write in (simulated: the temporary file cannot be created, as the system
    says for a read-only folder, whatever the user's rights here)."""
    real_mkstemp = tempfile.mkstemp

    def mkstemp(suffix=None, prefix=None, dir=None, text=False):
        if dir is not None and os.path.samefile(dir, work / "sub"):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES),
                                  os.path.join(dir, f"{prefix}abcdefgh{suffix}"))
        return real_mkstemp(suffix=suffix, prefix=prefix, dir=dir, text=text)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    code, _, err = _run(["match", "rec.npz", "-o", "sub/m2.npz"], capsys)
    assert code == 1, f"SILENT: exit {code}"
    _one_line_naming(err, "match", "sub/m2.npz")
    assert "Permission denied" in err, f"MESSAGE: the reason is not said: {err!r}"


def test_full_disk_in_convert_publishes_neither_camera(work, monkeypatch, capsys):
    """``convert -o a.txt b.txt``: the right camera's file cannot be written, so the left one is not kept."""
    import cvstereo.io.edvs_text_write as text_write

    real_open, calls = open, []

    def full_open(path, mode="r", *args, **kwargs):
        fh = real_open(path, mode, *args, **kwargs)
        if "w" in mode and ".part" in os.fspath(path):
            calls.append(path)
            if len(calls) == 2:
                fh.close()
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return fh

    monkeypatch.setattr(text_write, "open", full_open, raising=False)
    code, _, err = _run(["convert", "rec.npz", "-o", "a.txt", "b.txt"], capsys)
    assert code == 1, f"SILENT: exit {code}"
    assert not (work / "a.txt").exists() and not (work / "b.txt").exists(), \
        "LEFTOVER: one camera's file of a failed conversion was published"
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    _one_line_naming(err, "convert", "b.txt")


def test_plot_all_that_fails_leaves_no_folder(work, monkeypatch, capsys):
    """``plot all -o figs``: the third picture cannot be written; no picture and no new folder stay."""
    pytest.importorskip("matplotlib")
    import matplotlib.figure

    real_savefig, calls = matplotlib.figure.Figure.savefig, []

    def savefig(self, fname, *args, **kwargs):
        calls.append(fname)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_savefig(self, fname, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    code, _, err = _run(["plot", "all", "rec.npz", "m.npz", "-o", "figs"], capsys)
    assert code == 1, f"SILENT: exit {code}"
    assert not (work / "figs").exists(), \
        f"LEFTOVER: {sorted(p.name for p in (work / 'figs').iterdir())} of a failed run"
    _one_line_naming(err, "plot", "figs")


def test_point_cloud_without_depth_is_refused_before_matching(work, monkeypatch, capsys):
    import cvstereo.pipeline

    def never(*args, **kwargs):
        raise AssertionError("SILENT: matched before refusing an output it cannot write")

    monkeypatch.setattr(cvstereo.pipeline, "match", never)
    code, _, err = _run(["match", "rec.npz", "--point-cloud", "pc.ply", "-o", "m2.npz"], capsys)
    assert code == 1, f"SILENT: exit {code}"
    assert "depth model" in err, f"MESSAGE: {err!r}"
    assert not (work / "m2.npz").exists() and not (work / "pc.ply").exists(), "LEFTOVER: outputs of a refused run"


def test_matches_without_suffix_are_a_matches_file(work, capsys):
    assert run_cli(["match", "rec.npz", "-o", "mfile"])[0] == 0
    got, want = read_matches(work / "mfile"), read_matches(work / "m.npz")
    assert np.array_equal(got.matches, want.matches), "SILENT: the file holds other matches"


def test_point_cloud_into_a_device_is_written_whole(work, capsys):
    """The PLY goes into the device as a whole; the matches file beside it is published as usual."""
    pytest.importorskip("plyfile")
    code, out, _ = _run(_cmd("match rec.npz --point-cloud null.dev -o m2.npz", *DEPTH), capsys)
    assert code == 0 and (work / "m2.npz").exists(), f"SILENT: {out!r}"
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    staged = [p.name for p in Path(tempfile.gettempdir()).glob(f".null.dev.pid{os.getpid()}-*")]
    assert not staged, f"LEFTOVER: {staged} in the temporary folder"
