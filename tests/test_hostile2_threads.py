"""Hostile ``--threads`` / ``threads=`` (issue 28 item 1): values no thread count is, more threads than cores, the
environment variable, and ``threads`` where a matcher parameter goes.

Every command that matches takes ``--threads N``: a value that is not a whole number from 1 to MAX_THREADS is one
line naming ``--threads`` and the value, exit 1, before any file is read or written; more threads than the
process has cores are taken with a note (numba's and OpenCV's pools run at most the cores; the matches are those
of one thread, checked against an in-process one-thread run).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import cvstereo as cvs
from cvstereo.io import read_matches, write_recording
from cvstereo.matchers.registry import create_matcher
from tests._hostile import case, check_case
from tests._io_helpers import textured_blobs

try:
    from cvstereo import _threads
except ImportError:  # tallied on a version without the knob (bench/hostile_tally.py --against): its CLI cases run
    _threads = None

pytestmark = pytest.mark.timeout(120)

MAX_THREADS = _threads.MAX_THREADS if _threads else 1024
OUT = "-o out.npz"


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hostile2-threads")
    write_recording(d / "rec.npz", textured_blobs(0, 4))
    return d


@pytest.fixture
def work(base, tmp_path, monkeypatch) -> Path:
    for p in base.iterdir():
        (tmp_path / p.name).write_bytes(p.read_bytes())
    monkeypatch.chdir(tmp_path)
    return tmp_path


def refused(cmd: str, value: str, absent=("out.npz",)):
    return case(f"{cmd} --threads {value}".split(), 1, ("--threads", value, "whole number"), absent=absent)


CASES = {
    "match-zero": refused(f"match rec.npz {OUT}", "0"),
    "match-negative": refused(f"match rec.npz {OUT}", "-1"),
    "match-fraction": refused(f"match rec.npz {OUT}", "2.5"),
    "match-word": refused(f"match rec.npz {OUT}", "abc"),
    "match-exponent": refused(f"match rec.npz {OUT}", "1e3"),
    "match-beyond-max": refused(f"match rec.npz {OUT}", str(MAX_THREADS + 1)),
    "match-huge": refused(f"match rec.npz {OUT}", "99999999999999999999999"),
    "match-event-area-zero": refused(f"match rec.npz -m event-area {OUT}", "0"),
    "live-zero": refused("live --simulate rec.npz --seconds 1", "0", absent=()),
    "live-word": refused("live --simulate rec.npz --seconds 1", "two", absent=()),
    "depth-fit-fraction": refused("depth-fit rec.npz:0.5 rec.npz:1.5 -o depth.json", "1.5", absent="depth.json"),
    "bench-zero": refused("bench --quick -o benchout", "0", absent="benchout"),
    "bench-word": refused("bench --quick -o benchout", "many", absent="benchout"),
    "threads-as-parameter": case(f"match rec.npz {OUT} -p threads=2".split(), 1, ("threads", "--threads N"),
                                 absent="out.npz"),
}


@pytest.mark.parametrize("hostile", list(CASES.values()), ids=list(CASES))
def test_hostile_threads(hostile, work, capsys):
    check_case(hostile, work, capsys)


@pytest.mark.parametrize("method", ["frame", "event-area"])
def test_more_threads_than_cores_noted_and_same_matches(method, work, capsys):
    """More threads than the process may use: taken, one note on stderr, the matches those of one thread."""
    many = (_threads.pool_size() if _threads else os.cpu_count()) + 3
    _, err = check_case(case(f"match rec.npz -m {method} {OUT} --threads {many}".split(), 0, writes="out.npz"),
                        work, capsys)
    notes = [line for line in err.splitlines() if line.startswith("note: --threads")]
    assert len(notes) == 1 and str(many) in notes[0], f"MESSAGE: no one-line note of the cap: {err!r}"
    one = cvs.match(work / "rec.npz", method=method, threads=1)
    got = read_matches(work / "out.npz")
    assert np.array_equal(got.matches, one.matches), "SILENT: other matches with more threads than cores"


@pytest.mark.parametrize("value", [0, -1, 2.5, 2.0, "2", "abc", True, None, MAX_THREADS + 1, float("nan")])
def test_api_refuses_what_is_no_thread_count(value):
    """``create_matcher(threads=...)`` and ``matcher.threads = ...``: a ValueError naming threads and the value
    (None is the default, only at create_matcher); the matcher keeps its threads after a refused assignment."""
    if value is not None:
        with pytest.raises(ValueError, match=r"threads=") as exc:
            create_matcher("frame", threads=value)
        assert repr(value) in str(exc.value) or str(value) in str(exc.value), f"MESSAGE: {exc.value}"
    m = create_matcher("frame", threads=2)
    with pytest.raises(ValueError, match=r"threads="):
        m.threads = value
    assert m.threads == 2, "SILENT: a refused value changed the matcher's threads"


def test_api_takes_numpy_integers_and_defaults_to_the_environment(monkeypatch):
    assert create_matcher("frame", threads=np.int64(3)).threads == 3
    assert type(create_matcher("frame", threads=np.int64(3)).threads) is int
    monkeypatch.setenv(_threads.THREADS_ENV, "2")
    _threads.default_threads.cache_clear()
    try:
        assert create_matcher("frame").threads == 2
        monkeypatch.setenv(_threads.THREADS_ENV, "")
        _threads.default_threads.cache_clear()
        assert create_matcher("frame").threads == _threads.available_cores()
    finally:
        monkeypatch.undo()
        _threads.default_threads.cache_clear()


@pytest.mark.parametrize("text", ["abc", "0", "-2", "2.5", "1e9"])
def test_bad_environment_variable_named(text, monkeypatch):
    monkeypatch.setenv(_threads.THREADS_ENV, text)
    _threads.default_threads.cache_clear()
    try:
        with pytest.raises(ValueError, match=_threads.THREADS_ENV) as exc:
            create_matcher("frame")
        assert len(str(exc.value).splitlines()) == 1, f"MESSAGE: {exc.value}"
    finally:
        monkeypatch.undo()
        _threads.default_threads.cache_clear()


def _keys(value) -> set[str]:
    if isinstance(value, dict):
        return set(value) | {k for v in value.values() for k in _keys(v)}
    if isinstance(value, list):
        return {k for v in value for k in _keys(v)}
    return set()


def test_threads_is_in_neither_params_nor_meta(work):
    """Not a parameter: the matches do not depend on it, so a file matched on 1 and one matched on 2 threads
    say the same (and a sweep's cell key, built from the params, is the same)."""
    one = cvs.match(work / "rec.npz", method="event-area", threads=1)
    two = cvs.match(work / "rec.npz", method="event-area", threads=2)
    assert "threads" not in _keys(one.meta), f"SILENT: threads in the meta: {one.meta}"
    assert "threads" not in one.meta["params"]
    def untimed(meta):  # what the run took differs: the matching's and the rig check's seconds
        return {k: ({**v, "seconds": None} if k == "rigcheck" else v) for k, v in meta.items()
                if k not in ("elapsed_s", "diagnostics")}

    assert untimed(one.meta) == untimed(two.meta)
    from cvstereo.matchers.registry import matcher_params

    with pytest.raises(ValueError, match="unknown parameter"):
        matcher_params("event-area", threads=2)
