"""``cvstereo info`` and ``cvstereo convert`` run as a user runs them: ``python -m cvstereo`` in a subprocess."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from cvstereo.cli import main
from cvstereo.io import read_recording, write_recording
from cvstereo.model.recording import Recording
from tests._io_helpers import assert_same_events, random_events


def _cli(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cvstereo", *map(str, args)], capture_output=True, text=True,
                          timeout=120, cwd=cwd)


def _fails_cleanly(proc, code: int, *words: str) -> None:
    assert proc.returncode == code, proc.stderr
    assert "Traceback" not in proc.stderr
    if code == 1:
        assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    for word in words:
        assert word in proc.stderr


def _table_rows(out: str) -> list[list[str]]:
    """The per-camera rows of info's tables, split into cells."""
    return [line.split() for line in out.splitlines()
            if line.split()[:1] in (["left"], ["right"]) and "camera" not in line]


@pytest.fixture
def truth_npz(tmp_path, rng):
    left, right = random_events(rng, 4), random_events(rng, 2)
    rec = Recording(left, right, np.array([1, np.nan, 2, 3], np.float32), np.array([np.nan, np.nan], np.float32))
    path = tmp_path / "truth.npz"
    write_recording(path, rec)
    return path


def test_info_on_npz_with_ground_truth(truth_npz):
    proc = _cli("info", truth_npz)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert "npz, 128x128" in lines[0] and "ground truth" in lines[0] and "no ground truth" not in lines[0]
    header = next(line for line in lines if "events" in line and "ON" in line)
    assert "with truth" in header
    left, right = _table_rows(proc.stdout)
    assert left[:2] == ["left", "4"] and left[-2:] == ["3", "(75.0%)"]
    assert right[:2] == ["right", "2"] and right[-2:] == ["0", "(0.0%)"]


@pytest.mark.shared_data
def test_info_on_the_real_files(tum_dir):
    proc = _cli("info", tum_dir / "Fan_disp8.dat", tum_dir / "movingPersons.dat")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "left camera = retina 1 (detected" in out and "left camera = retina 0 (detected" in out
    assert "coordinates count from 1 (detected)" in out
    assert [r[1] for r in _table_rows(out)] == ["72,746", "63,487", "32,419", "29,528"]
    given = _cli("info", tum_dir / "NSTlogo_disp12-8-3.dat", "--left-retina", "0")
    assert "left camera = retina 0 (given)" in given.stdout
    assert [r[1] for r in _table_rows(given.stdout)] == ["1,310", "1,290"]


@pytest.mark.shared_data
def test_convert_real_file_to_every_format_and_back(tum_dir, tmp_path, capsys):
    src = tum_dir / "NSTlogo_disp12-8-3.dat"  # small: the point is the format matrix
    original = read_recording(src)
    outputs = {"npz": [tmp_path / "mp.npz"], "aedat2": [tmp_path / "mp.aedat"], "edvs-merged": [tmp_path / "mp.txt"],
               "edvs-text": [tmp_path / "l.txt", tmp_path / "r.txt"]}
    for fmt, outs in outputs.items():
        # In-process for the format matrix (a subprocess per format would only add start-up time).
        assert main(["convert", str(src), "-o", *map(str, outs)]) == 0, fmt
        assert "1,290 left and 1,310 right events" in capsys.readouterr().out
        back = read_recording(*outs)
        assert_same_events(back.left, original.left)
        assert_same_events(back.right, original.right)
    assert read_recording(tmp_path / "mp.npz").meta["converted_from"]["format"] == "edvs-merged"
    # A pair of text files back to one npz, the input format given explicitly.
    proc = _cli("convert", tmp_path / "l.txt", tmp_path / "r.txt", "--format", "edvs-text", "-o", tmp_path / "b.npz")
    assert proc.returncode == 0, proc.stderr
    assert_same_events(read_recording(tmp_path / "b.npz").right, original.right)


def test_convert_to_text_drops_truth_and_says_so(truth_npz, tmp_path):
    proc = _cli("convert", truth_npz, "-o", tmp_path / "m.dat", "--out-left-retina", "1")
    assert proc.returncode == 0, proc.stderr
    assert "ground truth dropped" in proc.stdout
    assert "# left_retina 1" in (tmp_path / "m.dat").read_text()


def test_user_errors_exit_1_with_one_line(tmp_path):
    _fails_cleanly(_cli("info", tmp_path / "missing.npz"), 1, "cvstereo info: error:", "missing.npz: no such file")
    bad = tmp_path / "bad.txt"
    bad.write_text("1 2 3 1\nfoo bar\n")
    _fails_cleanly(_cli("info", bad), 1, "bad.txt, line 2: 'foo bar'")
    _fails_cleanly(_cli("convert", bad, "-o", tmp_path / "x.npz"), 1, "line 2")
    assert not (tmp_path / "x.npz").exists()


def test_usage_errors_exit_2(tmp_path):
    _fails_cleanly(_cli("info"), 2, "usage:")
    _fails_cleanly(_cli("convert", "a.npz", "-o", "x", "y", "z"), 2, "at most two")
