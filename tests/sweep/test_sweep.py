"""cvstereo.sweep: a grid over recordings on a 2-worker LocalCluster equals the serial run, a killed run
resumes without recomputing, a failing cell is isolated."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("dask.distributed")
pytest.importorskip("pyarrow")

from cvstereo.sweep import TIMING_COLUMNS, Cell, Grid, read_grid_file, run_sweep, summary_markdown, write_table
from tests._paths import REPO


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    """Two short simulated clips (the first 0.3 s of two presets) and one corrupt file."""
    from cvstereo.io.npz import write_recording_npz
    from cvstereo.simulate.presets import simulate_preset

    folder = tmp_path_factory.mktemp("sweep-clips")
    paths = []
    for name in ("1arm-100cm", "1arm-50cm"):
        path = folder / f"{name}.npz"
        write_recording_npz(path, simulate_preset(name, seconds=0.3, seed=3))
        paths.append(os.fspath(path))
    bad = folder / "corrupt.npz"
    bad.write_bytes(b"PK\x03\x04 this is not a zip file")
    return paths, os.fspath(bad)


def _grid():
    return [Grid(("event-time",), ("shared", "on"), (("threshold", (0.6, 0.8)),)), Grid(("frame",), ("separate",))]


def _cells(recordings):
    return [c for g in _grid() for c in g.cells(recordings)]


def _without_timing(rows):
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


def test_grid_expands_in_a_fixed_order():
    cells = Grid(("event-time",), ("shared", "on"), (("threshold", (0.6, 0.8)),)).cells(["a.npz", "b.npz"])
    assert [(Path(c.recording).name, c.variant, c.params) for c in cells] == [
        ("a.npz", "shared", (("threshold", 0.6),)), ("a.npz", "shared", (("threshold", 0.8),)),
        ("a.npz", "on", (("threshold", 0.6),)), ("a.npz", "on", (("threshold", 0.8),)),
        ("b.npz", "shared", (("threshold", 0.6),)), ("b.npz", "shared", (("threshold", 0.8),)),
        ("b.npz", "on", (("threshold", 0.6),)), ("b.npz", "on", (("threshold", 0.8),))]


@pytest.mark.parametrize(("grid", "message"), [
    (Grid(("no-such",)), "unknown method"),
    (Grid(("frame",), ("gaussian",)), "has no variant gaussian"),
    (Grid(("frame",), (), (("bogus", (1,)),)), "belong to none of the methods"),
])
def test_grid_errors(grid, message):
    with pytest.raises(ValueError, match=message):
        grid.cells(["a.npz"])


def test_grid_file(tmp_path):
    path = tmp_path / "grid.toml"
    path.write_text('recordings = ["x.npz"]\nfigure = "mae"\n[[grid]]\nmethods = ["event-area"]\n'
                    'variants = ["all"]\nparams = { threshold = [1.5, 2.5] }\n')
    grids, recordings, options = read_grid_file(path)
    assert recordings == ["x.npz"] and options == {"figure": "mae"}
    assert [(c.variant, c.params) for c in grids[0].cells(["x.npz"])] == [
        ("gaussian", (("threshold", 1.5),)), ("gaussian", (("threshold", 2.5),)),
        ("no-gaussian", (("threshold", 1.5),)), ("no-gaussian", (("threshold", 2.5),))]
    path.write_text("recordings = [")
    with pytest.raises(ValueError, match="not a valid TOML"):
        read_grid_file(path)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_local_cluster_equals_serial_and_isolates_failures(clips, tmp_path):
    paths, bad = clips
    cells = _cells([*paths, bad])
    serial = run_sweep(cells, tmp_path / "serial", workers=0)
    dask = run_sweep(cells, tmp_path / "dask", workers=2)
    assert _without_timing(dask.rows) == _without_timing(serial.rows)
    # The corrupt file fails its 5 cells (4 event-time + 1 frame) with its error; the others ran.
    failed = [r for r in serial.rows if r["error"] is not None]
    assert serial.failed == len(failed) == 5 and {r["recording"] for r in failed} == {bad}
    assert all("corrupt.npz" in r["error"] for r in failed)
    ok = [r for r in serial.rows if r["error"] is None]
    assert len(ok) == 10 and all(r["matches"] > 0 for r in ok)
    # Each row is what match + evaluate give for that cell on its own.
    from cvstereo.evaluation.metrics import evaluate
    from cvstereo.io import read_recording
    from cvstereo.run import match

    r = ok[1]
    res = match(r["recording"], method=r["method"], variant=r["variant"], **json.loads(r["params"]))
    assert evaluate(read_recording(r["recording"]), res)["matches"] == r["matches"]
    # Workers were other processes than this one.
    assert all(row["worker"].rsplit(":", 1)[1] != str(os.getpid()) for row in dask.rows)
    write_table(serial.rows, tmp_path / "t.parquet")
    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "t.parquet").to_pylist()
    assert [t["key"] for t in table] == [r["key"] for r in serial.rows]
    assert table[0]["param.threshold"] == 0.6 and table[-1]["param.threshold"] is None
    summary = summary_markdown(serial.rows)
    assert "| event-time | shared |" in summary and "| frame | separate |" in summary


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_killed_sweep_resumes_without_recomputing(clips, tmp_path):
    paths, _ = clips
    out = tmp_path / "out"
    script = ("import sys; from cvstereo.sweep import Grid, run_sweep\n"
              "cells = [c for g in [Grid(('event-time',), ('shared', 'on'), (('threshold', (0.6, 0.8)),)),"
              " Grid(('frame',), ('separate',))] for c in g.cells(sys.argv[2:])]\n"
              "run_sweep(cells, sys.argv[1], workers=0)\n")
    proc = subprocess.Popen([sys.executable, "-c", script, os.fspath(out), *paths], cwd=REPO)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and len(list((out / "cells").glob("*.json"))) < 2:
        if proc.poll() is not None:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.json")}
    assert 2 <= len(before) < 10, "the sweep was not interrupted mid-way; make the cells slower"
    ran: list[Cell] = []
    result = run_sweep(_cells(paths), out, workers=0, on_row=lambda cell, row: ran.append(cell))
    assert result.reused == len(before) and result.computed == len(ran) == 10 - len(before)
    assert {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.json") if p.name in before} == before
    full = run_sweep(_cells(paths), tmp_path / "fresh", workers=0)
    assert _without_timing(result.rows) == _without_timing(full.rows)


def test_cli_help_shows_a_grid_file_example(capsys):
    from cvstereo.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["sweep", "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "[[grid]]" in out and "--scheduler" in out and "params = { threshold" in out


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_cli_sweep_writes_table_and_summary(clips, tmp_path, capsys):
    import pyarrow.parquet as pq

    from cvstereo.cli import main

    paths, bad = clips
    grid = tmp_path / "grid.toml"
    grid.write_text('figure = "coverage"\n[[grid]]\nmethods = ["event-time"]\nparams = { threshold = [0.6, 0.8] }\n')
    out = tmp_path / "out"
    assert main(["sweep", paths[0], bad, "--grid", os.fspath(grid), "--workers", "0", "-o", os.fspath(out)]) == 0
    text = capsys.readouterr().out
    assert "4 cells: 4 run now, 0 from an earlier run, 2 failed" in text
    assert "best parameters by median coverage" in (out / "summary.md").read_text()
    rows = pq.read_table(out / "results.parquet").to_pylist()
    assert [r["param.threshold"] for r in rows] == [0.6, 0.8, 0.6, 0.8]
    assert [r["error"] is None for r in rows] == [True, True, False, False]
    # Run again: nothing recomputed.
    assert main(["sweep", paths[0], bad, "--grid", os.fspath(grid), "--workers", "0", "-o", os.fspath(out)]) == 0
    assert "0 run now, 4 from an earlier run" in capsys.readouterr().out


@pytest.mark.parametrize(("argv", "message"), [
    (["a.npz", "-o", "x"], "nothing to sweep"),
    (["--method", "frame", "-o", "x"], "no recordings"),
    (["missing.npz", "--method", "frame", "-o", "x"], "does not exist"),
    (["a.npz", "--param", "threshold=1", "-o", "x"], "need --method"),
    (["a.npz", "--method", "frame", "--param", "threshold", "-o", "x"], "is not KEY=V1,V2"),
    (["a.npz", "--method", "frame", "--param", "bogus=1", "-o", "x"], "none of the methods"),
    (["a.npz", "--method", "frame", "--workers", "-1", "-o", "x"], "--workers -1"),
])
def test_cli_sweep_errors(argv, message, capsys):
    from cvstereo.cli import main

    assert main(["sweep", *argv]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_grid_runs_the_thesis_matchers_under_each_parameter_set():
    # sgbm differs between the sets by the border rule; dv-semidense is the same under both: run once.
    cells = Grid(("event-time", "sgbm", "dv-semidense"), (), (), ("thesis", "adaptive")).cells(["a.npz"])
    assert [(c.method, c.param_set) for c in cells] == [("event-time", "thesis"), ("event-time", "adaptive"),
                                                        ("sgbm", "thesis"), ("sgbm", "adaptive"),
                                                        ("dv-semidense", None)]
    assert "(thesis set)" in cells[0].label


def test_suite_spec_resolves_to_the_suite_recordings(monkeypatch, tmp_path):
    """``suite:NAME`` names every recording of a simulated suite, in its order (generation mocked out)."""
    import cvstereo.simulate as simulate
    from cvstereo.sweep import resolve_recordings

    paths = [tmp_path / "a.npz", tmp_path / "b.npz"]
    def fake_suite(name, *, progress=False, only=None):  # only=[]: the up-front check, which generates nothing
        return [(n, p) for n, p in (("a", paths[0]), ("b", paths[1])) if only is None or n in only]

    monkeypatch.setattr(simulate, "suite_recordings", fake_suite)
    assert resolve_recordings(["suite:robustness"]) == [os.fspath(p) for p in paths]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_local_cluster_starts_while_another_program_holds_port_8787(clips, tmp_path):
    """The scheduler's HTTP server takes a free port: a Dask dashboard elsewhere on 8787 is no warning (an
    error under this suite's filterwarnings)."""
    import socket

    holder = socket.socket()
    try:
        holder.bind(("0.0.0.0", 8787))
        holder.listen()
    except OSError:
        pass  # another program holds it already: the case this test is about
    try:
        result = run_sweep(_cells(clips[0][:1])[:2], tmp_path, workers=1)
    finally:
        holder.close()
    assert result.failed == 0 and result.computed == 2
