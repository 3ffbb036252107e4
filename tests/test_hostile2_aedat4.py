"""Hostile AEDAT4 files (issue 27): damaged files must end in one line within 10 s, and a read must stop on
Ctrl-C and SIGTERM.

Good files are written with dv-processing's own writers (60 packets of 500 events per camera), then damaged as
files are in practice: 4 KB overwritten in the middle of the stream (random bytes, zeros, a copy error), the
file data table at the end overwritten, truncation at several points, header bytes flipped, a stream
description that claims a sensor no camera has. dv-processing's reader spins for ever, at full CPU and deaf to
signals, on some of them, so those cases run the command in a subprocess that the test can kill: a run still
going 10 s after it began to read counts as a HANG.

Failures say their kind (``tests/_hostile.py``), so that ``bench/hostile_tally.py`` tallies old and new code.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tests._hostile import case, check_case
from tests._hostile_calls import FILE_ERRORS, accepted, refused, same_events, working_copy

dv = pytest.importorskip("dv_processing")

pytestmark = pytest.mark.timeout(120)

RES = (640, 480)
PACKETS, PER_PACKET = 60, 500
T0 = 1_700_000_000_000_000  # DV stamps microseconds since the UNIX epoch
#: A damaged file must be refused within this many seconds of the command starting to read it.
LIMIT_S = 10
REPO = Path(__file__).resolve().parent.parent


def _events(seed: int, resolution=RES, packets=PACKETS) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = packets * PER_PACKET
    t = T0 + np.repeat(np.arange(packets) * 1000, PER_PACKET) + np.sort(
        rng.integers(0, 1000, (packets, PER_PACKET)), axis=1).ravel()
    return {"t": t, "x": rng.integers(0, resolution[0], n), "y": rng.integers(0, resolution[1], n),
            "p": rng.integers(0, 2, n)}


def _write(writer, events: dict[str, np.ndarray]) -> None:
    columns = [events[k].tolist() for k in "txyp"]
    for lo in range(0, len(columns[0]), PER_PACKET):
        store = dv.EventStore()
        for t, x, y, p in zip(*(c[lo:lo + PER_PACKET] for c in columns), strict=True):
            store.push_back(t, x, y, bool(p))  # dv: True = ON
        writer.writeEvents(store)


def _mono(path: Path, events, resolution=RES) -> None:
    writer = dv.io.MonoCameraWriter(str(path), dv.io.MonoCameraWriter.EventOnlyConfig("cam", resolution))
    _write(writer, events)
    del writer  # closes the file


LEFT, RIGHT = _events(1), _events(2)


def _overwrite(raw: bytes, at: int, junk: bytes) -> bytes:
    return raw[:at] + junk + raw[at + len(junk):]


def _flip(raw: bytes, lo: int, hi: int) -> bytes:
    return raw[:lo] + bytes(b ^ 0xFF for b in raw[lo:hi]) + raw[hi:]


def _damaged(mono: bytes, stereo: bytes) -> dict[str, bytes]:
    rng = np.random.default_rng(5)
    junk = rng.integers(0, 256, 4096, dtype=np.uint8).tobytes()
    mid, end = len(mono) // 2, len(mono)
    return {
        "mid_random.aedat4": _overwrite(mono, mid, junk),
        "mid_zeros.aedat4": _overwrite(mono, mid, bytes(4096)),
        "quarter_random.aedat4": _overwrite(mono, end // 4, junk),
        "mid_copied.aedat4": _overwrite(mono, mid, mono[end // 8: end // 8 + 4096]),  # a copy error
        "stereo_mid_random.aedat4": _overwrite(stereo, len(stereo) // 2, junk),
        "table_random.aedat4": _overwrite(mono, end - 300, junk[:300]),
        "cut_10.aedat4": mono[: end // 10],
        "cut_50.aedat4": mono[: end // 2],
        "cut_90.aedat4": mono[: end * 9 // 10],
        "cut_10_bytes.aedat4": mono[:-10],
        "cut_header.aedat4": mono[:20],
        "flip_ioheader.aedat4": _flip(mono, 18, 40),
    }


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hostile2-aedat4")
    _mono(d / "good.aedat4", LEFT)
    _mono(d / "right.aedat4", RIGHT)
    cfg = [dv.io.MonoCameraWriter.EventOnlyConfig(name, RES) for name in ("L", "R")]
    writer = dv.io.StereoCameraWriter(str(d / "stereo.aedat4"), *cfg)
    _write(writer.left, LEFT)
    _write(writer.right, RIGHT)
    del writer
    for name, data in _damaged((d / "good.aedat4").read_bytes(), (d / "stereo.aedat4").read_bytes()).items():
        (d / name).write_bytes(data)
    _mono(d / "huge_sensor.aedat4", _events(3, packets=2), resolution=(4096, 4096))
    _mono(d / "wide_sensor.aedat4", _events(3, packets=2), resolution=(2049, 16))
    small = _events(4, resolution=(100, 100), packets=2)
    _mono(d / "outside.aedat4", small, resolution=(64, 64))  # dv writes what it is given
    good = (d / "good.aedat4").read_bytes()
    for name, value in (("size_abc", b"abc"), ("size_zero", b"000"), ("size_minus", b"-64")):
        (d / f"{name}.aedat4").write_bytes(good.replace(b'"sizeX" type="int">640<', b'"sizeX" type="int">' + value
                                                        + b"<", 1))
    (d / "empty.aedat4").write_bytes(b"")
    (d / "folder.aedat4").mkdir()
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    return working_copy(base, tmp_path, monkeypatch)


# ----------------------------------------------------------------------------- damaged files, in a subprocess

#: The CLI, saying READING on stdout when the AEDAT4 reader starts on a camera (so that a time limit and a
#: signal can be timed from the read, not from the interpreter's start on a busy machine). Its first argument
#: overrides the watchdog's stall limits where there is one ("-": as they are), so that a signal, not the
#: watchdog, is what stops a stuck read.
_CLI = r"""
import sys
import cvstereo.io.aedat4 as aedat4

stall = sys.argv.pop(1)
if stall != "-":
    import cvstereo.io._watchdog as watchdog
    watchdog.STALL_CPU_S = watchdog.STALL_WALL_S = float(stall)

opened = aedat4._camera_chunks

def reading(*args, **kwargs):
    print("READING", flush=True)
    return (yield from opened(*args, **kwargs))

aedat4._camera_chunks = reading
from cvstereo.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}


def _start(work: Path, *argv: str, stall: str = "-") -> tuple[subprocess.Popen, tuple | None]:
    """The command running; and (exit code, stdout, stderr) when it ended before reading (a refused header)."""
    proc = subprocess.Popen([sys.executable, "-c", _CLI, stall, *argv], cwd=work, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=_env())
    line = proc.stdout.readline()  # the interpreter's start is not timed: a busy machine may take long
    if "READING" in line:
        return proc, None
    out, err = proc.communicate(timeout=60)
    return proc, (proc.returncode, line + out, err)


def _finish(started: tuple[subprocess.Popen, tuple | None], limit: float = LIMIT_S) -> tuple[int, str, str]:
    proc, ended = started
    if ended is not None:
        return ended
    try:
        out, err = proc.communicate(timeout=limit)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise AssertionError(f"HANG: still running {limit} s after it began to read") from None
    return proc.returncode, out, err


def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (Linux /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_bytes()
            except OSError:
                continue
            if int(stat.rsplit(b")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        return (Path(f"/proc/{pid}") / "stat").read_bytes().rsplit(b")", 1)[1].split()[0] not in (b"Z", b"X")
    except OSError:
        return False


DAMAGED = ["mid_random", "mid_zeros", "quarter_random", "mid_copied", "table_random", "cut_10", "cut_50", "cut_90",
           "cut_10_bytes", "flip_ioheader"]


@pytest.mark.parametrize("name", DAMAGED)
def test_damaged_file_is_refused_within_the_limit(work, name):
    file = f"{name}.aedat4"
    code, out, err = _finish(_start(work, "info", file))
    assert "Traceback" not in err, f"TRACEBACK: {err[-400:]}"
    assert code != 0, f"SILENT: exit 0: {out[-300:]}"
    lines = err.strip().splitlines()
    assert code == 1 and len(lines) == 1 and lines[0].startswith("cvstereo info: error: "), f"MESSAGE: {code} {err!r}"
    assert file in err and "AEDAT4" in err, f"MESSAGE: the file or the format not named: {err!r}"


def test_damaged_stereo_file_is_refused_within_the_limit(work):
    code, _, err = _finish(_start(work, "match", "stereo_mid_random.aedat4", "-m", "frame", "-o", "m.npz"))
    assert "Traceback" not in err, f"TRACEBACK: {err[-400:]}"
    assert code == 1 and "stereo_mid_random.aedat4" in err and "AEDAT4" in err, f"MESSAGE: {code} {err!r}"
    assert not (work / "m.npz").exists(), "LEFTOVER: m.npz written by a refused run"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_during_a_stuck_read_ends_the_command(work, sig):
    started = _start(work, "match", "mid_random.aedat4", "right.aedat4", "-m", "frame", "-o", "m.npz", stall="3600")
    time.sleep(1.0)  # the reader is at the damaged packet by now, spinning on it
    children = _children(started[0].pid)
    started[0].send_signal(sig)
    code, _, err = _finish(started, limit=5)
    assert "Traceback" not in err, f"TRACEBACK: {err[-400:]}"
    expected = (128 + sig, f"stopped by {signal.Signals(sig).name}")
    assert (code, expected[1] in err) == (expected[0], True), f"MESSAGE: exit {code}: {err!r}"
    assert not (work / "m.npz").exists(), "LEFTOVER: m.npz written by a stopped run"
    alive = [pid for pid in children if _running(pid)]
    assert not alive, f"LEFTOVER: worker processes {alive} still running"


# ----------------------------------------------------------------------------- in-process: header and values

CASES = {
    "sensor-4096": case("info huge_sensor.aedat4", 1, ("huge_sensor.aedat4", "4096", "2048")),
    "sensor-2049-wide": case("info wide_sensor.aedat4", 1, ("wide_sensor.aedat4", "2049", "2048")),
    "size-not-a-number": case("info size_abc.aedat4", 1, ("size_abc.aedat4", "abc")),
    "size-zero": case("info size_zero.aedat4", 1, ("size_zero.aedat4", "(0, 480)")),
    "size-negative": case("info size_minus.aedat4", 1, ("size_minus.aedat4", "-64")),
    "cut-before-description": case("info cut_header.aedat4", 1, ("cut_header.aedat4", "AEDAT4")),
    "events-outside-stream-size": case("info outside.aedat4", 1, ("outside.aedat4", "outside the 64x64 sensor")),
    "empty-file": case("info empty.aedat4", 1, ("empty.aedat4", "AEDAT 4.0")),
    "folder": case("info folder.aedat4", 1, ("folder.aedat4", "directory")),
    "match-huge-sensor": case("match huge_sensor.aedat4 right.aedat4 -o m.npz", 1, ("4096", "2048"), absent="m.npz"),
    "good-mono": case("info good.aedat4", 0, out=f"{PACKETS * PER_PACKET:,}"),
    "good-stereo": case("info stereo.aedat4", 0, out=f"{PACKETS * PER_PACKET:,}"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_aedat4_command_line(hostile, work: Path, capsys):
    check_case(hostile, work, capsys)


def test_good_files_read_back_exactly(base):
    from cvstereo.io.aedat4 import open_aedat4

    rec = accepted(lambda: open_aedat4(base / "stereo.aedat4").read())
    same_events(rec.left, LEFT, "stereo left")
    same_events(rec.right, RIGHT, "stereo right")
    pair = accepted(lambda: open_aedat4(base / "good.aedat4", base / "right.aedat4").read())
    same_events(pair.left, LEFT, "mono pair left")
    same_events(pair.right, RIGHT, "mono pair right")


def test_worker_started_as_a_script_reads_the_same(base, monkeypatch):
    # Where the worker cannot be forked it runs as a script: the same frames, the same events.
    from cvstereo.io import _watchdog
    from cvstereo.io.aedat4 import open_aedat4

    monkeypatch.setattr(_watchdog, "FORK", False, raising=False)
    rec = accepted(lambda: open_aedat4(base / "stereo.aedat4").read())
    same_events(rec.left, LEFT, "script worker, left")
    refused(lambda: open_aedat4(base / "cut_50.aedat4").read_camera("mono"), "cut_50.aedat4", "AEDAT4",
            errors=FILE_ERRORS)


def test_a_fifo_is_refused_without_blocking(tmp_path):
    from cvstereo.io.aedat4 import open_aedat4

    os.mkfifo(tmp_path / "pipe.aedat4")
    refused(lambda: open_aedat4(tmp_path / "pipe.aedat4"), "pipe.aedat4", "not a regular file", errors=FILE_ERRORS)


def test_truncated_file_names_file_and_format_in_python(base):
    from cvstereo.io.aedat4 import open_aedat4

    refused(lambda: open_aedat4(base / "cut_90.aedat4").read_camera("mono"), "cut_90.aedat4", "AEDAT4",
            errors=FILE_ERRORS)


def test_stopping_early_leaves_no_worker(base):
    from cvstereo.io.aedat4 import open_aedat4

    before = set(_children(os.getpid()))
    chunks = open_aedat4(base / "good.aedat4").chunks("mono")
    next(chunks)
    started = set(_children(os.getpid())) - before
    chunks.close()
    alive = [pid for pid in started if _running(pid)]
    assert not alive, f"LEFTOVER: worker processes {alive} still running after the read stopped"
