"""Signals at any moment of the long commands (issue 27): Ctrl-C and SIGTERM during start-up, imports, reading,
matching, simulating, the Dask cluster's start, running cells and writing.

Each case runs the real command in a subprocess through a harness that marks the moment (a file appears) and
holds it for a few seconds (a patched import or function sleeps there), so that the signal lands exactly there
on a machine of any speed. A stop must end the command within :data:`PROMPT_S` with one last line ``cvstereo
CMD: stopped by SIGNAL``, exit 128 + signal, no traceback or Dask warning, no temporary file, no output of the
stopped run, no process left behind; inputs keep their bytes. ``record`` and ``live`` end normally (exit 0) on a
stop once the boards stream, and ``record`` keeps every event the boards sent.

Ctrl-C is sent as a terminal does, to the whole process group (Dask's worker processes included); SIGTERM as
``kill`` does, to the command alone.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from cvstereo.io import read_recording, write_matches, write_recording
from tests._hostile import leftovers, snapshot
from tests._io_helpers import textured_blobs

pytestmark = pytest.mark.timeout(240)  # a fresh interpreter on a busy machine takes seconds to import

REPO = Path(__file__).resolve().parent.parent
#: Seconds a stopped command may take to end.
PROMPT_S = 10
#: Seconds the processes a command started may take to end after it (they notice its pipes closed).
REAPED_S = 5
#: Seconds the harness holds a moment: long enough for the signal to land there, short enough that a command
#: that does not stop at once (a board being opened) goes on.
HOLD_S = 3

#: Runs the CLI; ``MOMENT`` marks when to signal: ``import:MODULE`` (while MODULE is imported), ``call:MODULE:
#: NAME`` (inside a call of NAME, e.g. ``numpy:load``; ``:N`` for the N-th call), ``enter:MODULE:NAME`` (marks the
#: call and runs it without holding: the real thing takes the time). The first module the command line imports
#: after ``cvstereo.cli`` is ``cvstereo.cli.info`` (its parser); before, the interpreter's own start-up and
#: ``import cvstereo.cli`` (standard library only) are too short to aim at.
_HARNESS = r"""
import importlib, importlib.abc, sys, time
marker, moment, hold, argv = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4:]


def reached():
    open(marker, "w").close()


def held():
    # Short sleeps: a signal that lands before the first (between the marker and the sleep, where Python
    # does not look at signals) is handled at the next, not after the whole hold.
    for _ in range(int(hold * 10)):
        time.sleep(0.1)


class HoldImport(importlib.abc.MetaPathFinder):
    def __init__(self, name):
        self.name = name

    def find_spec(self, fullname, path=None, target=None):
        if fullname == self.name:
            sys.meta_path.remove(self)
            reached()
            held()
        return None


def patch(spec, holding):
    module, name, *nth = spec.split(":")
    owner_path, _, attr = name.rpartition(".")
    owner = importlib.import_module(module)
    for part in filter(None, owner_path.split(".")):
        owner = getattr(owner, part)
    real, calls, nth = getattr(owner, attr), [0], int(nth[0]) if nth else 1

    def wrapper(*args, **kwargs):
        calls[0] += 1
        if calls[0] == nth:
            reached()
            if holding:
                held()
        return real(*args, **kwargs)

    setattr(owner, attr, wrapper)


kind, _, spec = moment.partition(":")
if kind == "import":
    sys.meta_path.insert(0, HoldImport(spec))
else:
    patch(spec, holding=kind == "call")
from cvstereo.cli import main
sys.exit(main(argv))
"""


@dataclass(frozen=True)
class Moment:
    """One command line, the moment to signal it at, the signal, and what the command must do then."""

    argv: tuple[str, ...]
    moment: str
    sig: int
    code: int | None = None  # None: 128 + sig, with the "stopped by" line
    out: tuple[str, ...] = ()  # files that must exist afterwards
    absent: tuple[str, ...] = ()  # outputs of the stopped run that must not exist
    err: tuple[str, ...] = ()  # what stderr must say (a normal end)
    prompt_s: float = PROMPT_S


def moment(cmd: str, when: str, sig: int, code=None, out=(), absent=(), err=(), prompt_s=PROMPT_S) -> Moment:
    return Moment(tuple(cmd.split()), when, sig, code, tuple(out), tuple(absent), tuple(err), prompt_s)


#: A local Dask cluster that is starting finishes its start before it can be closed (Dask waits for the worker
#: processes it spawned, whether closed or stopped): a few seconds on a quiet machine, more on a loaded one.
CLUSTER_PROMPT_S = 30


INT, TERM = signal.SIGINT, signal.SIGTERM
SIM = "--simulate src.npz"


def _prepare_feeds() -> int:
    """The feeds with which a process's first matcher of a method has its kernels made ready (the built-in clip of
    cvstereo._compile_watch, fed before the command opens or reads anything): counted feeds come after them."""
    from cvstereo._compile_watch import CLIP_PACKET_US, tiny_clip
    from cvstereo.model.events import iter_stereo_packets

    clip = tiny_clip()
    return sum(1 for _ in iter_stereo_packets([(clip.left, None)], [(clip.right, None)], CLIP_PACKET_US))


FEEDS = _prepare_feeds()
THRESHOLDS = "0.4,0.6,0.8,1.0"
SWEEP = f"sweep src.npz -m event-time -p threshold={THRESHOLDS} --workers 2 -o sw"
MOMENTS = {
    # --- record: before the boards stream, the stop ends it; once written, the journal is kept -----------
    "record-first-import": moment(f"record {SIM} -o rec.npz", "import:cvstereo.cli.sweep", INT,
                                  absent=("rec.npz", "rec.npz.journal")),
    "record-heavy-import": moment(f"record {SIM} -o rec.npz", "import:cvstereo.sensors.stereo", TERM,
                                  absent=("rec.npz", "rec.npz.journal")),
    "record-reading-source": moment(f"record {SIM} -o rec.npz", "call:numpy:load", INT,
                                    absent=("rec.npz", "rec.npz.journal")),
    "record-opening-boards": moment(f"record {SIM} -o rec.npz", "call:cvstereo.sensors.stereo:StereoEDVS.__init__",
                                    TERM, absent=("rec.npz", "rec.npz.journal")),
    "record-writing": moment(f"record {SIM} -o rec.npz", "call:numpy:savez_compressed", TERM,
                             out=("rec.npz.journal",), absent=("rec.npz",)),
    # --- live: a stop once the boards stream is its normal end -------------------------------------------
    "live-first-import": moment(f"live {SIM}", "import:cvstereo.cli.sweep", TERM),
    "live-heavy-import": moment(f"live {SIM}", "import:cvstereo.sensors.live", INT),
    "live-opening-boards": moment(f"live {SIM}", "call:cvstereo.sensors.stereo:StereoEDVS.__init__", INT),
    "live-matching": moment(f"live {SIM}", f"enter:cvstereo.matcher:StreamMatcher.feed:{FEEDS + 3}", INT, code=0,
                            err=("behind real time",)),
    "live-rerun-opening-boards": moment(f"live {SIM} --rerun=r.rrd", "call:cvstereo.sensors.stereo:StereoEDVS.__init__",
                                        TERM, absent=("r.rrd",)),
    "live-rerun-matching": moment(f"live {SIM} --rerun=r.rrd", f"enter:cvstereo.matcher:StreamMatcher.feed:{FEEDS + 3}",
                                  INT, code=0, out=("r.rrd",), err=("packets -> r.rrd",)),
    # --- match, video ----------------------------------------------------------------------------------------
    "match-first-import": moment("match src.npz -o m2.npz", "import:cvstereo.cli.info", TERM, absent=("m2.npz",)),
    "match-reading": moment("match src.npz -o m2.npz", "call:numpy:load", INT, absent=("m2.npz",)),
    "match-matching": moment("match src.npz -o m2.npz", f"call:cvstereo.matcher:StreamMatcher.feed:{FEEDS + 2}", TERM,
                             absent=("m2.npz",)),
    "match-writing": moment("match src.npz -o m2.npz", "call:numpy:savez_compressed", INT, absent=("m2.npz",)),
    "video-reading": moment("video src.npz m.npz -o v.mp4 --scale 1", "call:numpy:load", TERM, absent=("v.mp4",)),
    "video-drawing": moment("video src.npz m.npz -o v.mp4 --scale 1", "call:cvstereo.viz.video:_frame:3", INT,
                            absent=("v.mp4",)),
    # --- simulate, bench, demo -------------------------------------------------------------------------------
    "simulate-heavy-import": moment("simulate --preset 1arm-50cm --seconds 0.3 -o sim.npz", "import:cvstereo.simulate",
                                    TERM, absent=("sim.npz",)),
    "simulate-simulating": moment("simulate --preset 1arm-50cm --seconds 0.3 -o sim.npz",
                                  "call:cvstereo.simulate.presets:simulate", INT, absent=("sim.npz",)),
    "simulate-writing": moment("simulate --preset 1arm-50cm --seconds 0.3 -o sim.npz", "call:numpy:savez_compressed",
                               TERM, absent=("sim.npz",)),
    "bench-heavy-import": moment("bench --quick -m frame -o b", "import:cvstereo.benchmark", INT, absent=("b",)),
    "bench-simulating": moment("bench --quick -m frame -o b", "call:cvstereo.simulate.presets:simulate", TERM,
                               absent=("b",)),
    # The demo imports the experiment module by its 0.3 name (cvstereo.experiment is only an alias).
    "demo-heavy-import": moment("demo --seconds 0.3 --methods frame -o d",
                                "import:cvstereo.evaluation.experiment", TERM, absent=("d",)),
    "demo-simulating": moment("demo --seconds 0.3 --methods frame -o d", "call:cvstereo.simulate.presets:simulate", INT,
                              absent=("d",)),
    # --- sweep: the Dask cluster starting, cells running -------------------------------------------------
    "sweep-checking-grid": moment(SWEEP, "call:cvstereo.registry:matcher_class", TERM, absent=("sw",)),
    "sweep-cluster-starting-sigterm": moment(SWEEP, "enter:distributed:LocalCluster.__init__", TERM, absent=("sw",),
                                             prompt_s=CLUSTER_PROMPT_S),
    "sweep-cluster-starting-ctrl-c": moment(SWEEP, "enter:distributed:LocalCluster.__init__", INT, absent=("sw",),
                                            prompt_s=CLUSTER_PROMPT_S),
}
#: Stops while cells run (:func:`test_stopped_sweep_keeps_its_finished_cells_and_resumes`).
CELLS_RUNNING = {"sigterm": moment(SWEEP, "enter:cvstereo.io._atomic:write_text_atomic", TERM),
                 "ctrl-c": moment(SWEEP, "enter:cvstereo.io._atomic:write_text_atomic", INT)}


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    from calibration_free import match

    d = tmp_path_factory.mktemp("hostile2-signals")
    write_recording(d / "src.npz", textured_blobs(0, 25))  # 1 s, 18,000 events a camera
    result = match(d / "src.npz", method="frame")
    write_matches(d / "m.npz", result.matches, result.meta)
    return d


@pytest.fixture
def work(base, tmp_path) -> Path:
    for p in base.iterdir():
        (tmp_path / p.name).write_bytes(p.read_bytes())
    return tmp_path


def _env(work: Path) -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
            "CVSTEREO_CACHE": str(work / "cache"), "CVSTEREO_SHARED": str(work / "no-shared-data")}


def _session_processes(sid: int) -> list[str]:
    """Processes still in session ``sid`` (the command's own; its workers would be orphans)."""
    found = []
    for stat_file in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat_file.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            found.append(stat_file.parent.name)
    return found


def signal_at(m: Moment, work: Path) -> tuple[int, str, str]:
    """Run ``m``, send its signal at its moment; return (exit code, stdout, stderr)."""
    marker = work / ".moment"
    cmd = [sys.executable, "-c", _HARNESS, str(marker), m.moment, str(HOLD_S), *m.argv]
    proc = subprocess.Popen(cmd, cwd=work, env=_env(work), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert marker.exists(), f"the moment {m.moment} never came: {proc.communicate(timeout=60)[1][-2000:]}"
        if m.sig == INT:
            os.killpg(proc.pid, INT)  # as a terminal's Ctrl-C: the whole group
        else:
            proc.send_signal(m.sig)
        sent = time.monotonic()
        try:
            out, err = proc.communicate(timeout=m.prompt_s + 50)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"HANG: still running {m.prompt_s + 50:.0f} s after {signal.Signals(m.sig).name}") \
                from None
        took = time.monotonic() - sent
        assert "Traceback" not in err, f"TRACEBACK: {err[-3000:]}"
        assert took < m.prompt_s, f"HANG: took {took:.0f} s to stop"
        gone = time.monotonic() + REAPED_S  # helpers that end when the command's pipes close (resource tracker)
        while (left := _session_processes(proc.pid)) and time.monotonic() < gone:
            time.sleep(0.1)
        assert not left, f"LEFTOVER: processes {left} still running {REAPED_S} s after the command ended"
        return proc.returncode, out, err
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
        with_left = _session_processes(proc.pid)
        for pid in with_left:
            os.kill(int(pid), signal.SIGKILL)


def check_stopped(m: Moment, work: Path, code: int, err: str) -> None:
    """A stop's report: exit 128 + signal, the last line ``cvstereo CMD: stopped by SIG``, nothing alarming."""
    name = signal.Signals(m.sig).name
    lines = err.strip().splitlines()
    assert code == 128 + m.sig, f"MESSAGE: exit {code}, expected {128 + m.sig}: {err[-2000:]!r}"
    assert lines and lines[-1].startswith(f"cvstereo {m.argv[0]}: stopped by {name}"), f"MESSAGE: {err[-2000:]!r}"
    alarming = [line for line in lines if any(w in line for w in ("WARNING", "Error", "Exception", "error:"))]
    assert not alarming, f"MESSAGE: {alarming}"


@pytest.mark.parametrize("m", list(MOMENTS.values()), ids=list(MOMENTS))
def test_signal_at_any_moment(m: Moment, work: Path):
    before = snapshot(work)
    code, _, err = signal_at(m, work)
    if m.code is None:
        check_stopped(m, work, code, err)
    else:
        assert code == m.code, f"MESSAGE: exit {code}, expected {m.code}: {err[-2000:]!r}"
        missing = [fragment for fragment in m.err if fragment not in err]
        assert not missing, f"MESSAGE: {missing} not in {err[-2000:]!r}"
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    stray = [name for name in m.absent if (work / name).exists()]
    assert not stray, f"LEFTOVER: {stray} written by a stopped run"
    missing = [name for name in m.out if not (work / name).exists()]
    assert not missing, f"DATALOSS: {missing} missing after the stop"
    after = snapshot(work)
    changed = sorted(k for k, h in before.items() if after.get(k) != h)
    assert not changed, f"DATALOSS: {changed} changed or removed"


# ------------------------------------------------------------------------------------------------ effects

def test_record_stopped_while_writing_keeps_every_event_in_its_journal(work, capsys):
    """The recording is played in full, then a SIGTERM cuts its writing: the journal stays, the last line says
    how to convert it, and converting it gives every event of the source (the boards sent them all)."""
    from cvstereo.cli import main

    m = MOMENTS["record-writing"]
    code, _, err = signal_at(m, work)
    check_stopped(m, work, code, err)
    assert "rec.npz.journal" in err.strip().splitlines()[-1] and "--from-journal" in err, f"MESSAGE: {err!r}"
    assert main(["record", "--from-journal", str(work / "rec.npz.journal"), "-o", str(work / "rec.npz")]) == 0
    capsys.readouterr()
    got, src = read_recording(work / "rec.npz"), read_recording(work / "src.npz")
    for cam in ("left", "right"):
        mine, theirs = getattr(got, cam), getattr(src, cam)
        assert mine.size == theirs.size, f"DATALOSS: {cam} {mine.size} of {theirs.size} events"
        assert np.array_equal(np.diff(mine["t"]), np.diff(theirs["t"])), f"DATALOSS: {cam} times differ"
        for f in ("x", "y", "p"):
            assert np.array_equal(mine[f], theirs[f]), f"DATALOSS: {cam} {f} differs"


@pytest.mark.parametrize("which", list(CELLS_RUNNING))
def test_stopped_sweep_keeps_its_finished_cells_and_resumes(work, capsys, monkeypatch, which):
    """A sweep stopped while its first finished cell is written (its workers busy with others) ends as every stop
    does and keeps the cells that finished, that one included: the same sweep run again (here, without Dask)
    reuses each and runs only the others."""
    from cvstereo.cli import main

    m = CELLS_RUNNING[which]
    before = snapshot(work)
    code, _, err = signal_at(m, work)
    check_stopped(m, work, code, err)
    assert not leftovers(work), f"LEFTOVER: {leftovers(work)}"
    assert all(before[k] == h for k, h in snapshot(work).items() if k in before), "DATALOSS: an input changed"
    kept = sorted((work / "sw" / "cells").glob("*.json"))
    assert kept, "DATALOSS: the cell that had finished is gone"
    monkeypatch.chdir(work)
    cells = len(THRESHOLDS.split(","))
    assert main(["sweep", "src.npz", "-m", "event-time", "-p", f"threshold={THRESHOLDS}", "--workers", "0",
                 "-o", "sw"]) == 0
    out = capsys.readouterr().out
    assert f"{cells - len(kept)} run now, {len(kept)} from an earlier run, 0 failed" in out, f"DATALOSS: {out!r}"
