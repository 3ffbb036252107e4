"""``cvstereo plot`` and ``cvstereo video``: files written, exit codes, one-line errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

import cv2  # noqa: E402

from cvstereo.cli import main  # noqa: E402
from cvstereo.cli.plot import KINDS  # noqa: E402
from cvstereo.io import write_matches, write_recording  # noqa: E402
from cvstereo.model.events import make_events  # noqa: E402
from cvstereo.model.matches import make_matches  # noqa: E402
from cvstereo.model.recording import Recording  # noqa: E402

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A 0.2 s recording with ground truth (a bar at disparity 6 px, plus noise) and event-anchored matches."""
    rng = np.random.default_rng(0)
    n = 4000
    t = np.sort(rng.integers(0, 200_000, n))
    x = rng.integers(20, 40, n)
    y = rng.integers(10, 100, n)
    p = rng.integers(0, 2, n)
    truth = np.where(rng.random(n) < 0.1, np.nan, 6.0)
    rec = Recording(make_events(t, x, y, p), make_events(t, x - 6, y, p), truth, truth,
                    meta={"rig": {"focal_px": 165.0, "baseline_m": 0.1, "axis_offset_px": 0.0}})
    keep = rng.random(n) < 0.5
    m = make_matches(t[keep], x[keep], y[keep], p[keep], 0, 6.0 + rng.normal(0, 0.5, keep.sum()))
    folder = tmp_path_factory.mktemp("cli")
    write_recording(folder / "rec.npz", rec)
    write_matches(folder / "m.npz", m, {"method": "event-time", "variant": "shared", "params": {},
                                        "anchor": "event", "window_us": 0})
    return folder / "rec.npz", folder / "m.npz"


def _cvstereo(*args):
    return subprocess.run([sys.executable, "-m", "cvstereo", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def test_plot_subprocess(files, tmp_path):
    rec, _ = files
    out = tmp_path / "events.png"
    proc = _cvstereo("plot", "events", rec, "-o", out, "--dpi", "60")
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes()[:8] == PNG


def test_plot_needs_matches_subprocess(files, tmp_path):
    rec, _ = files
    proc = _cvstereo("plot", "disparity-time", rec, "-o", tmp_path / "x.png")
    assert proc.returncode == 1
    assert proc.stderr.count("\n") == 1 and "MATCHES" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "x.png").exists()


def test_video(files, tmp_path, capsys):
    rec, m = files
    out = tmp_path / "v.mp4"
    assert main(["video", str(rec), str(m), "-o", str(out), "--scale", "2", "--seconds", "0.1"]) == 0
    assert "3 frames" in capsys.readouterr().out
    cap = cv2.VideoCapture(str(out))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 3  # windows starting at 0, 40 and 80 ms
    assert int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) >= 2 * 128
    cap.release()


@pytest.mark.parametrize("kind", ["events", "filtered", "dynamic"])
def test_plot_recording_only_kinds(files, tmp_path, kind, capsys):
    rec, _ = files
    out = tmp_path / f"{kind}.png"
    assert main(["plot", kind, str(rec), "-o", str(out), "--t-start-ms", "40", "--window-ms", "20",
                 "--dpi", "60"]) == 0
    assert out.read_bytes()[:8] == PNG


def test_plot_disparity_map_with_start_and_metres(files, tmp_path):
    rec, m = files
    out = tmp_path / "map.svg"
    assert main(["plot", "disparity-map", str(rec), str(m), "-o", str(out), "--t-start-ms", "40",
                 "--windows", "1", "--depth", "16.5", "0"]) == 0
    text = out.read_text()
    # The window starts 40 ms after the recording's first event.
    assert "<svg" in text and "40 ms + 40 ms" in text and "distance (m)" in text


def test_plot_all_without_truth(files, tmp_path, capsys):
    from cvstereo.io import read_recording

    rec, m = files
    r = read_recording(rec)
    bare = tmp_path / "bare.npz"
    write_recording(bare, Recording(r.left, r.right))
    out = tmp_path / "out"
    assert main(["plot", "all", str(bare), str(m), "-o", str(out), "--no-metres", "--windows", "1",
                 "--dpi", "40"]) == 0
    assert "error-hist: skipped" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == sorted(f"{k}.png" for k in KINDS if k != "error-hist")
    assert all(p.read_bytes()[:8] == PNG for p in out.iterdir())
    assert main(["plot", "error-hist", str(bare), str(m), "-o", str(tmp_path / "e.png")]) == 1
    assert "ground truth" in capsys.readouterr().err


def test_plot_without_matplotlib_names_the_extra(files, tmp_path, monkeypatch, capsys):
    rec, _ = files
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)
    assert main(["plot", "events", str(rec), "-o", str(tmp_path / "e.png")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cvstereo[viz]" in err


def test_video_bad_options(files, tmp_path, capsys):
    rec, _ = files
    assert main(["video", str(rec), "-o", str(tmp_path / "v.mp4"), "--fps", "0"]) == 1
    assert "fps" in capsys.readouterr().err
    assert main(["video", str(rec), "-o", str(tmp_path / "missing" / "v.mp4")]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_depth_from_the_matches_file_wins_over_the_rig(files):
    import argparse

    from cvstereo.cli.plot import picture_depth
    from cvstereo.geometry.depth import DepthModel
    from cvstereo.io import read_matches, read_recording

    rec, m = files
    recording, result = read_recording(rec), read_matches(m)
    args = argparse.Namespace(metres=True, depth=None)
    assert picture_depth(args, recording, result) == DepthModel(a=16.5, c=0.0)  # the rig
    result.meta["depth"] = {"a": 20.0, "c": 1.0}
    assert picture_depth(args, recording, result) == DepthModel(a=20.0, c=1.0)
    assert picture_depth(argparse.Namespace(metres=True, depth=[5.0, 0.0]), recording, result) == DepthModel(5.0)
    assert picture_depth(argparse.Namespace(metres=False, depth=None), recording, result) is None
