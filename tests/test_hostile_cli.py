"""Hostile and careless command lines (issue 13): outputs over inputs, devices, FIFOs, symlinks, signals,
nonsense values and lying files.

Every case runs ``cvstereo.cli.main`` in-process on files generated under ``tmp_path`` and asserts the exit
code, a fragment of the one-line error, that no traceback escapes, that every file present before the run
has the same bytes afterwards (unless the case writes it) and that no temporary ``.part`` file is left. A
few cases run as subprocesses: signals and a closed stdout.

A failing case says which kind of failure it is (TRACEBACK, DATALOSS, SILENT, MESSAGE, LEFTOVER), so that a
run against an older version gives the tally of the issue's closing note.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from cvstereo.recording import Recording

from cvstereo.cli import main
from cvstereo.io import read_matches, read_recording, write_matches, write_recording
from tests._hostile import Case, case, check_case, leftovers, null_device, snapshot
from tests._io_helpers import textured_blobs

pytestmark = pytest.mark.timeout(60)

W = 40_000
DISPARITY = 13


# ------------------------------------------------------------------------------------------------ files

def _blobs(seed: int = 0, windows: int = 4) -> Recording:
    """Textured blobs seen by the right camera 13 px to the left: frame matchers find them; truth 13."""
    return textured_blobs(seed, windows, disparity=DISPARITY, window_us=W)


def _with_meta(result, **changes):
    meta = {**result.meta}
    for k, v in changes.items():
        if v is _DROP:
            meta.pop(k, None)
        else:
            meta[k] = v
    return meta


_DROP = object()


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """Every file the cases read, made once; each case works on its own copy."""
    from calibration_free import match

    d = tmp_path_factory.mktemp("hostile-base")
    rec = _blobs()
    write_recording(d / "rec.npz", rec)
    write_recording(d / "bare.npz", Recording(rec.left, rec.right))
    write_recording(d / "l.txt", rec, right=d / "r.txt")
    write_recording(d / "other.npz", _blobs(seed=1, windows=2))
    write_recording(d / "rec240.npz", Recording(rec.left, rec.right, rec.left_disparity, rec.right_disparity,
                                                (240, 180)))
    result = match(d / "rec.npz", method="frame")
    assert len(result) > 20
    write_matches(d / "m.npz", result.matches, result.meta)
    write_matches(d / "m_copy.npz", result.matches, {**result.meta, "input": ["m_copy"]})
    m = result.matches
    variants = {
        "m_xout": (_set(m, "x", 0, 200), {}),
        "m_yout": (_set(m, "y", 3, -1), {}),
        "m_nan": (_set(m, "disparity", 1, np.nan), {}),
        "m_inf": (_set(m, "disparity", 2, np.inf), {}),
        "m_cams5": (m, {"anchor_cameras": [5]}),
        "m_camsabc": (m, {"anchor_cameras": "abc"}),
        "m_camsempty": (m, {"anchor_cameras": []}),
        "m_camsdup": (m, {"anchor_cameras": [0, 0]}),
        "m_wusabc": (m, {"window_us": "abc"}),
        "m_anchorfoo": (m, {"anchor": "foo"}),
        "m_evil": (m, {"method": "frame\x1b[2J\x1b]0;owned\x07"}),
        "m_far": (_scaled(m, 2.0), {}),
        "m_baddepth": (m, {"depth": {"a": 0.0, "c": 0.0}}),
    }
    for name, (matches, changes) in variants.items():
        write_matches(d / f"{name}.npz", matches, _with_meta(result, **changes))
    (d / "evil.txt").write_bytes(b"# fields t x y p\n0 1 2 1\n5 \x1b[31mEVIL\x1b[0m 3 1\n")
    (d / "cols3.txt").write_text("0 1 2\n1 2 3\n")
    return d


def _set(m: np.ndarray, field: str, i: int, value) -> np.ndarray:
    out = m.copy()
    out[field][i] = value
    return out


def _scaled(m: np.ndarray, k: float) -> np.ndarray:
    out = m.copy()
    out["disparity"] *= k
    return out


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    """A copy of the base files plus the hostile ones (links, a folder, FIFOs), as the working folder."""
    for p in base.iterdir():
        shutil.copy2(p, tmp_path / p.name)
    os.symlink("rec.npz", tmp_path / "link.npz")
    os.link(tmp_path / "rec.npz", tmp_path / "hard.npz")
    (tmp_path / "target.npz").write_bytes(b"old target")
    os.symlink("target.npz", tmp_path / "outlink.npz")
    (tmp_path / "dir").mkdir()
    (tmp_path / "dir.npz").mkdir()
    (tmp_path / "sub").mkdir()
    os.mkfifo(tmp_path / "fifo.npz")
    os.mkfifo(tmp_path / "fifo.txt")
    null_device(tmp_path / "null.dev")
    monkeypatch.chdir(tmp_path)
    return tmp_path


# ------------------------------------------------------------------------------------------------ cases

IS_INPUT = "is the input"
CASES = {
    # --- outputs over inputs (data loss) -------------------------------------------------------------
    "match-o-input": case("match rec.npz -o rec.npz", 1, IS_INPUT),
    "match-o-symlink-to-input": case("match rec.npz -o link.npz", 1, (IS_INPUT, "link.npz")),
    "match-o-hardlink-to-input": case("match rec.npz -o hard.npz", 1, (IS_INPUT, "hard.npz")),
    "match-o-dotdot-input": case("match rec.npz -o sub/../rec.npz", 1, IS_INPUT),
    "match-o-right-input": case("match l.txt r.txt -o r.txt", 1, "-o r.txt"),
    "match-input-via-symlink-o-real": case("match link.npz -o rec.npz", 1, IS_INPUT),
    "convert-o-input": case("convert rec.npz -o rec.npz", 1, IS_INPUT),
    "convert-o-symlink": case("convert rec.npz -o link.npz", 1, IS_INPUT),
    "convert-o-hardlink": case("convert rec.npz -o hard.npz", 1, IS_INPUT),
    "convert-pair-swapped": case("convert l.txt r.txt -o r.txt l.txt", 1, IS_INPUT),
    "convert-pair-o-left-input": case("convert l.txt r.txt -o l.txt x.txt", 1, IS_INPUT),
    "convert-two-outputs-same": case("convert rec.npz -o o.txt o.txt", 1, "the same file"),
    "convert-two-outputs-same-via-link": case("convert rec.npz -o rec.txt ./rec.txt", 1, "the same file"),
    "plot-o-input": case("plot events rec.npz -o rec.npz", 1, IS_INPUT),
    "plot-o-matches": case("plot disparity-time rec.npz m.npz -o m.npz", 1, IS_INPUT),
    "plot-o-hardlink": case("plot events rec.npz -o hard.npz", 1, IS_INPUT),
    "plot-all-o-file": case("plot all rec.npz m.npz -o rec.npz", 1, "not a folder"),
    "video-o-matches": case("video rec.npz m.npz -o m.npz", 1, IS_INPUT),
    "depth-fit-o-input": case("depth-fit m.npz:0.5 m_far.npz:1 -o m.npz", 1, IS_INPUT),
    "depth-fit-o-symlink": case("depth-fit rec.npz:0.5 m.npz:1 -o link.npz", 1, IS_INPUT),
    "demo-o-file": case("demo -o rec.npz --methods frame", 1, "not a folder"),
    "bench-o-file": case("bench -o rec.npz", 1, "not a folder"),
    # --- where outputs go: devices, FIFOs, symlinks, folders ------------------------------------------
    "match-o-null-device": case("match rec.npz -o null.dev", 0, out="matches from"),
    "convert-o-null-device": case("convert rec.npz --to npz -o null.dev", 0, out="wrote null.dev"),
    "convert-aedat-o-null-device": case("convert rec.npz --to aedat2 -o null.dev", 0, out="wrote null.dev"),
    "match-o-outlink": case("match rec.npz -o outlink.npz", 0, out="matches from", writes="target.npz"),
    "match-o-folder": case("match rec.npz -o dir", 1, "is a directory"),
    "match-o-folder-npz": case("match rec.npz -o dir.npz", 1, "is a directory"),
    "match-o-missing-folder": case("match rec.npz -o nofolder/m.npz", 1, "does not exist"),
    "convert-o-folder": case("convert rec.npz --to npz -o dir", 1, "is a directory"),
    "convert-o-missing-folder": case("convert rec.npz -o nofolder/x.npz", 1, "does not exist"),
    "match-o-new": case("match rec.npz -o new.npz", 0, out="matches from", writes="new.npz"),
    # --- output format follows the name ----------------------------------------------------------------
    "convert-two-aedat": case("convert rec.npz -o l.aedat r.aedat", 1, ("edvs-text", "l.aedat")),
    "convert-txt-and-aedat": case("convert rec.npz -o a.txt b.aedat", 1, "b.aedat"),
    "convert-to-npz-into-txt": case("convert rec.npz --to npz -o x.txt", 1, ("x.txt", "npz")),
    "convert-to-aedat-into-npz": case("convert rec.npz --to aedat2 -o x.npz", 1, "x.npz"),
    "convert-to-merged-into-aedat": case("convert rec.npz --to edvs-merged -o x.aedat", 1, "x.aedat"),
    "convert-to-text-into-npz": case("convert rec.npz --to edvs-text -o a.npz b.npz", 1, "a.npz"),
    "convert-unknown-suffix": case("convert rec.npz -o x.bin", 1, "cannot tell the output format"),
    "convert-to-npz-unknown-suffix": case("convert rec.npz --to npz -o x.bin", 0, out="wrote x.bin", writes="x.bin"),
    "convert-pair-ok": case("convert rec.npz -o a.txt b.txt", 0, out="wrote a.txt and b.txt",
                            writes=("a.txt", "b.txt")),
    "match-o-txt": case("match rec.npz -o m.txt", 1, ("m.txt", ".npz")),
    "match-o-aedat": case("match rec.npz -o m.aedat", 1, ("m.aedat", ".npz")),
    # --- inputs that are not regular files --------------------------------------------------------------
    "info-folder": case("info dir", 1, ("dir", "is a directory")),
    "info-folder-npz": case("info dir.npz", 1, "is a directory"),
    "info-fifo-npz": case("info fifo.npz", 1, ("fifo.npz", "not a regular file")),
    "info-fifo-txt": case("info fifo.txt", 1, "not a regular file"),
    "info-dev-zero": case("info /dev/zero --format npz", 1, "not a regular file"),
    "info-missing": case("info missing.npz", 1, ("missing.npz", "no such file")),
    "match-folder": case("match dir.npz -o m2.npz", 1, "is a directory"),
    "match-fifo": case("match fifo.npz -o m2.npz", 1, "not a regular file"),
    "match-right-fifo": case("match l.txt fifo.txt -o m2.npz", 1, ("fifo.txt", "not a regular file")),
    "convert-fifo": case("convert fifo.txt -o x.npz", 1, "not a regular file"),
    "convert-folder": case("convert dir.npz -o x.txt", 1, "is a directory"),
    "evaluate-folder-recording": case("evaluate dir.npz m.npz", 1, "is a directory"),
    "evaluate-fifo-matches": case("evaluate rec.npz fifo.npz", 1, "not a regular file"),
    "plot-folder": case("plot events dir.npz -o p.png", 1, "is a directory"),
    "plot-fifo-matches": case("plot disparity-time rec.npz fifo.npz -o p.png", 1, "not a regular file"),
    "video-fifo": case("video fifo.npz -o v.mp4", 1, "not a regular file"),
    "depth-fit-folder": case("depth-fit dir.npz:0.5 m.npz:1", 1, "is a directory"),
    "depth-fit-fifo": case("depth-fit fifo.npz:0.5 m.npz:1", 1, "not a regular file"),
    # --- distances ----------------------------------------------------------------------------------------
    "match-depth-zero": case("match rec.npz -o m2.npz --depth 0 0", 1, ("--depth", "> 0")),
    "match-depth-nan-inf": case("match rec.npz -o m2.npz --depth nan inf", 1, "--depth"),
    "match-depth-negative": case("match rec.npz -o m2.npz --depth -5 1", 1, "--depth"),
    "match-depth-c-inf": case("match rec.npz -o m2.npz --depth 10 inf", 1, ("--depth", "c (px)")),
    "match-depth-beyond-range": case("match rec.npz -o m2.npz --depth 1 -100", 0, out=("distance: median n/a",),
                                   writes="m2.npz", no_out=("nan", "inf")),
    "plot-depth-zero": case("plot disparity-time rec.npz m.npz -o p.png --depth 0 0", 1, "--depth"),
    "plot-stored-depth-bad": case("plot disparity-time rec.npz m_baddepth.npz -o p.png", 1, ("m_baddepth.npz",
                                                                                            "--no-metres")),
    "video-depth-nan": case("video rec.npz m.npz -o v.mp4 --depth nan 0", 1, "--depth"),
    "depth-fit-equal-medians": case("depth-fit m.npz:0.5 m_copy.npz:1.0", 1, ("every disparity", "m_copy.npz")),
    "depth-fit-growing": case("depth-fit m.npz:0.5 m_far.npz:1.0", 1, "grow with distance"),
    "depth-fit-inf-distance": case("depth-fit m.npz:0.5 m_far.npz:inf", 1, "finite distance"),
    "depth-fit-nan-distance": case("depth-fit m.npz:nan m_far.npz:1", 1, "FILE:DISTANCE"),
    "depth-fit-zero-distance": case("depth-fit m.npz:0 m_far.npz:1", 1, "FILE:DISTANCE"),
    "depth-fit-one-distance": case("depth-fit m.npz:1 m_far.npz:1", 1, "two or more"),
    "depth-fit-ok": case("depth-fit m_far.npz:0.5 m.npz:1.0 -o d.json", 0, out="--depth", writes="d.json"),
    # --- evaluate: lying matches files ------------------------------------------------------------------
    "evaluate-x-outside": case("evaluate rec.npz m_xout.npz", 1, ("m_xout.npz", "outside", "x=200")),
    "evaluate-y-outside": case("evaluate rec.npz m_yout.npz", 1, ("m_yout.npz", "outside")),
    "evaluate-nan-disparity": case("evaluate rec.npz m_nan.npz", 1, ("m_nan.npz", "NaN")),
    "evaluate-inf-disparity": case("evaluate rec.npz m_inf.npz", 1, ("m_inf.npz", "inf")),
    "evaluate-anchor-cameras-5": case("evaluate rec.npz m_cams5.npz", 1, ("m_cams5.npz", "anchor_cameras")),
    "evaluate-anchor-cameras-str": case("evaluate rec.npz m_camsabc.npz", 1, "anchor_cameras"),
    "evaluate-anchor-cameras-empty": case("evaluate rec.npz m_camsempty.npz", 1, "anchor_cameras"),
    "evaluate-anchor-cameras-dup": case("evaluate rec.npz m_camsdup.npz", 1, "anchor_cameras"),
    "evaluate-window-us-str": case("evaluate rec.npz m_wusabc.npz", 1, ("m_wusabc.npz", "window_us")),
    "evaluate-anchor-foo": case("evaluate rec.npz m_anchorfoo.npz", 1, ("m_anchorfoo.npz", "anchor")),
    "evaluate-other-recording": case("evaluate other.npz m.npz", 1, ("m.npz", "another recording", "--force",
                                                                   "rec.npz")),
    "evaluate-other-sensor": case("evaluate rec240.npz m.npz", 1, ("240x180", "--force")),
    "evaluate-other-forced": case("evaluate other.npz m.npz --force", 0, out="| other |"),
    "evaluate-ok": case("evaluate rec.npz m.npz", 0, out="| rec |"),
    "evaluate-no-truth-text": case("evaluate bare.npz m.npz", 0, out="no ground truth"),
    "evaluate-no-truth-json": case("evaluate bare.npz m.npz --json", 0, out='"mae": null'),
    "evaluate-recording-as-matches": case("evaluate rec.npz rec.npz", 1, ("rec.npz", "matches")),
    "evaluate-matches-as-recording": case("evaluate m.npz m.npz", 1, "m.npz"),
    # --- info on what is not a recording ---------------------------------------------------------------
    "info-matches-file": case("info m.npz", 0, out=("matches file", "frame", "computed on")),
    "info-matches-and-recording": case("info m.npz rec.npz", 0, out=("matches file", "npz, 128x128")),
    "info-three-columns": case("info cols3.txt", 1, ("cols3.txt", "3 columns")),
    # --- terminal escape codes from names and contents -------------------------------------------------
    "info-escape-in-name": case("info ev\x1b[31mil.npz", 1, ("\\x1b[31m", "no such file")),
    "info-escape-in-content": case("info evil.txt", 1, "evil.txt"),
    "info-escape-in-meta": case("info m_evil.npz", 0, out=("\\x1b[2J", "matches file")),
    "evaluate-escape-in-meta": case("evaluate rec.npz m_evil.npz", 0, out="\\x1b[2J"),
    # --- option limits -------------------------------------------------------------------------------
    "plot-dpi-huge": case("plot events rec.npz -o p.png --dpi 100000", 1, ("--dpi", "1200")),
    "plot-dpi-zero": case("plot events rec.npz -o p.png --dpi 0", 1, "--dpi"),
    "plot-dpi-nan": case("plot events rec.npz -o p.png --dpi nan", 1, "--dpi"),
    "plot-window-nan": case("plot events rec.npz -o p.png --window-ms nan", 1, "--window-ms"),
    "plot-window-inf": case("plot events rec.npz -o p.png --window-ms inf", 1, "--window-ms"),
    "plot-window-zero": case("plot events rec.npz -o p.png --window-ms 0", 1, "--window-ms"),
    "plot-start-nan": case("plot events rec.npz -o p.png --t-start-ms nan", 1, "--t-start-ms"),
    "plot-start-negative": case("plot events rec.npz -o p.png --t-start-ms -5", 1, "--t-start-ms"),
    "plot-start-huge": case("plot events rec.npz -o p.png --t-start-ms 1e300", 1, "--t-start-ms"),
    "plot-start-past-end": case("plot events rec.npz -o p.png --t-start-ms 3600000", 1,
                              ("--t-start-ms 3.6e+06 shows no event", "lie between")),
    "plot-map-start-past-end": case("plot disparity-map rec.npz m.npz -o p.png --t-start-ms 3600000", 1,
                                  "shows no event"),
    "plot-map-window-us-str": case("plot disparity-map rec.npz m_wusabc.npz -o p.png", 1, "m_wusabc.npz"),
    "plot-error-hist-no-truth": case("plot error-hist bare.npz m.npz -o p.png", 1, ("bare.npz", "ground truth")),
    "plot-windows-zero": case("plot disparity-map rec.npz m.npz -o p.png --windows 0", 1, "--windows"),
    "plot-windows-huge": case("plot disparity-map rec.npz m.npz -o p.png --windows 100000", 1, "--windows"),
    "video-fps-zero": case("video rec.npz -o v.mp4 --fps 0", 1, "--fps"),
    "video-fps-nan": case("video rec.npz -o v.mp4 --fps nan", 1, "--fps"),
    "video-fps-negative": case("video rec.npz -o v.mp4 --fps -25", 1, "--fps"),
    "video-scale-zero": case("video rec.npz -o v.mp4 --scale 0", 1, "--scale"),
    "video-scale-huge": case("video rec.npz -o v.mp4 --scale 100000", 1, ("--scale", "32")),
    "video-seconds-negative": case("video rec.npz -o v.mp4 --seconds -1", 1, "--seconds"),
    "video-seconds-nan": case("video rec.npz -o v.mp4 --seconds nan", 1, "--seconds"),
    "video-window-nan": case("video rec.npz -o v.mp4 --window-ms nan", 1, "--window-ms"),
    "match-packet-zero": case("match rec.npz -o m2.npz --packet-us 0", 1, "--packet-us"),
    "match-packet-negative": case("match rec.npz -o m2.npz --packet-us -5", 1, "--packet-us"),
    "match-row-offset-huge": case("match rec.npz -o m2.npz --row-offset 999999999999", 1, ("--row-offset", "127")),
    "match-row-offset-sensor": case("match rec.npz -o m2.npz --row-offset -128", 1, "--row-offset"),
    "match-time-offset-huge": case("match rec.npz -o m2.npz --time-offset-us 99999999999999999999", 1,
                                 "--time-offset-us"),
    "match-time-offset-negative-huge": case("match rec.npz -o m2.npz --time-offset-us -99999999999999999999", 1,
                                          "--time-offset-us"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_command_line(hostile: Case, work: Path, capsys):
    check_case(hostile, work, capsys)


# ------------------------------------------------------------------------------------------------ effects

def test_output_into_a_fifo_is_written_whole_and_the_fifo_stays(work):
    got = {}

    def reader():
        with open(work / "fifo.npz", "rb") as fh:
            got["bytes"] = fh.read()

    t = threading.Thread(target=reader, daemon=True)
    t.start()
    assert main(["match", "rec.npz", "-o", "fifo.npz"]) == 0
    t.join(30)
    assert stat.S_ISFIFO(os.lstat(work / "fifo.npz").st_mode)
    (work / "from-fifo.npz").write_bytes(got["bytes"])
    assert np.array_equal(read_matches(work / "from-fifo.npz").matches, read_matches(work / "m.npz").matches)


def test_output_through_a_symlink_replaces_its_target_and_keeps_the_link(work):
    assert main(["match", "rec.npz", "-o", "outlink.npz"]) == 0
    assert os.path.islink(work / "outlink.npz") and os.readlink(work / "outlink.npz") == "target.npz"
    assert np.array_equal(read_matches(work / "target.npz").matches, read_matches(work / "m.npz").matches)


def test_replaced_output_keeps_its_permissions(work):
    out = work / "m2.npz"
    out.write_bytes(b"old")
    out.chmod(0o640)
    assert main(["match", "rec.npz", "-o", str(out)]) == 0
    assert stat.S_IMODE(out.stat().st_mode) == 0o640 and read_matches(out).matches.size


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_temporaries_of_the_same_output_are_removed(work):
    dead, alive = _dead_pid(), subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        stale = work / f".m2.npz.pid{dead}-abcd1234.npz.part"
        live = work / f".m2.npz.pid{alive.pid}-abcd1234.npz.part"
        other = work / f".other.npz.pid{dead}-abcd1234.npz.part"
        legacy_old, legacy_new = work / ".m2.npz.k3j4h5g6.npz.part", work / ".m2.npz.z9y8x7w6.npz.part"
        for p in (stale, live, other, legacy_old, legacy_new):
            p.write_bytes(b"x" * 100)
        os.utime(legacy_old, (time.time() - 3600, time.time() - 3600))
        assert main(["match", "rec.npz", "-o", "m2.npz"]) == 0
        assert not stale.exists() and not legacy_old.exists()
        assert live.exists() and other.exists() and legacy_new.exists()  # maybe still being written
    finally:
        alive.kill()
        alive.wait()


def test_broken_pipe_in_process_is_quiet(work, monkeypatch, capsys):
    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(sys, "stdout", Closed())
    code = main(["info", "rec.npz", "m.npz"])
    monkeypatch.undo()
    assert code == 141 and capsys.readouterr().err == ""


# ------------------------------------------------------------------------------------------------ subprocesses

def _env() -> dict:
    root = str(Path(__file__).resolve().parent.parent)
    return {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}


@pytest.mark.timeout(240)
def test_info_into_head_exits_quietly(work):
    # More output than a pipe holds (64 KiB), so that writes fail once the reader has gone.
    cmd = [sys.executable, "-m", "cvstereo", "info", *["rec.npz", "m.npz"] * 300]
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env()) as proc:
        first = proc.stdout.readline()
        proc.stdout.close()  # like `| head -1`
        err = proc.stderr.read().decode()
        code = proc.wait(60)
    assert first.startswith(b"rec.npz")
    assert err == "" and code in (0, 141)


#: Runs the CLI with a writer that writes a little, says WRITING and stalls: a kill lands mid-write.
_SLOW_WRITER = r"""
import sys, time
import numpy as np
from cvstereo.viz import encode

def stall():
    print("WRITING", flush=True)
    for _ in range(1200):  # short sleeps: a signal that lands before the first is handled at the next
        time.sleep(0.1)

def slow_savez(fh, **arrays):
    fh.write(b"PK partial")
    fh.flush()
    stall()

np.savez_compressed = slow_savez
real_write = encode.VideoEncoder.write

def slow_write(self, frame):
    real_write(self, frame)
    if self.frames == 2:
        stall()

encode.VideoEncoder.write = slow_write
from cvstereo.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _start_slow(work: Path, *argv: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", _SLOW_WRITER, *argv], cwd=work, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=_env())
    line = proc.stdout.readline()  # blocks until the writer stalls (or the process ends)
    assert line.strip().endswith("WRITING"), (line, proc.stderr.read() if proc.poll() is not None else "")
    return proc


@pytest.mark.timeout(240)  # a fresh interpreter may compile the matcher's kernels first: slow on a busy machine
@pytest.mark.parametrize("argv", [("convert", "rec.npz", "-o", "out.npz"),
                                  ("match", "rec.npz", "-o", "out.npz"),
                                  ("video", "rec.npz", "m.npz", "-o", "out.mp4", "--scale", "1")],
                         ids=["convert", "match", "video"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP], ids=["SIGTERM", "SIGHUP"])
def test_signal_mid_write_leaves_no_temporary(work, argv, sig):
    before = snapshot(work)
    proc = _start_slow(work, *argv)
    assert leftovers(work), "the slow writer should have a temporary file open"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err and f"stopped by {signal.Signals(sig).name}" in err
    assert not leftovers(work)
    assert not (work / argv[argv.index("-o") + 1]).exists()
    assert snapshot(work) == before


@pytest.mark.timeout(240)
@pytest.mark.parametrize("argv", [("match", "rec.npz", "-o", "out.npz"),
                                  ("video", "rec.npz", "-o", "out.mp4", "--scale", "1")], ids=["match", "video"])
def test_sigkill_mid_write_is_cleaned_up_by_the_next_run(work, argv):
    proc = _start_slow(work, *argv)
    assert leftovers(work)
    proc.kill()
    proc.communicate(timeout=60)
    assert leftovers(work)  # SIGKILL cannot be caught: the temporary stays ...
    assert main(list(argv)) == 0
    assert not leftovers(work)  # ... until the next write of the same output
    assert (work / argv[3]).stat().st_size > 0


def test_info_summarises_a_matches_file(work, capsys):
    assert main(["info", "m.npz"]) == 0
    out = capsys.readouterr().out
    disparity = read_matches(work / "m.npz").disparity
    assert f"{disparity.size:,} matches" in out and "method frame" in out
    assert f"median {np.median(disparity):.2f} px" in out
    assert f"rec.npz ({read_recording(work / 'rec.npz').left.size * 2:,} events)" in out


def test_evaluate_accepts_a_renamed_copy_of_the_recording(work, capsys):
    # The refusal is about the recording (event count, sensor), not its file name.
    shutil.copy(work / "rec.npz", work / "renamed.npz")
    assert main(["evaluate", "renamed.npz", "m.npz", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)["figures"]
    assert figures["matches"] == read_matches(work / "m.npz").matches.size


def test_recording_read_back_unchanged_after_refusals(work):
    original = read_recording(work / "rec.npz")
    for argv in (["match", "rec.npz", "-o", "link.npz"], ["convert", "rec.npz", "-o", "hard.npz"]):
        assert main(argv) == 1
    again = read_recording(work / "rec.npz")
    assert np.array_equal(original.left, again.left) and np.array_equal(original.right, again.right)
