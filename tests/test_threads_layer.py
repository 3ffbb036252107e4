"""The threads context and numba's threading layer (:mod:`cvstereo._threads`): counts set and restored, a layer
that takes parallel kernels from several Python threads at once, and a forked child that can still run them."""

from __future__ import annotations

import os
import sys
import threading
import warnings

import numba
import numpy as np
import pytest
from numba import njit, prange

from cvstereo import _threads


@njit(parallel=True)
def _parallel_sum_of_squares(a):
    """A ``parallel=True`` kernel with a reduction over ``prange``: the launch that the threading layer runs."""
    total = 0
    for i in prange(a.size):
        total += a[i] * a[i]
    return total


def _expected(a) -> int:
    return int(np.sum(a.astype(np.int64) ** 2))


def test_layer_chosen_tolerates_threads():
    a = np.arange(10_000, dtype=np.int64)
    with _threads.using_threads(2):
        assert _parallel_sum_of_squares(a) == _expected(a)
    layer = _threads.threading_layer()
    assert layer in ("tbb", "omp"), layer
    if sys.platform.startswith("linux") and os.uname().machine == "x86_64":
        assert layer == "tbb", "the tbb wheel is a dependency here: its layer is the fork-safe one"


def test_two_python_threads_run_a_parallel_kernel_at_once():
    """Each Python thread launches the parallel kernel over and over while the other does: the right sums,
    no abort (numba's workqueue layer would end the process here)."""
    arrays = [np.arange(n, dtype=np.int64) for n in (200_001, 333_333)]
    results: list[list[int]] = [[], []]
    errors: list[BaseException] = []
    start = threading.Barrier(2)

    def work(k):
        try:
            start.wait()
            with _threads.using_threads(2):
                for _ in range(100):
                    results[k].append(int(_parallel_sum_of_squares(arrays[k])))
        except BaseException as exc:  # reported in the main thread
            errors.append(exc)

    workers = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(60)
    assert not errors and not any(w.is_alive() for w in workers)
    for k in range(2):
        assert results[k] == [_expected(arrays[k])] * 100


def _in_forked_child(check, what: str) -> None:
    """Run ``check()`` (True: passed) in a forked child that must exit within 10 s."""
    with warnings.catch_warnings():  # Python >= 3.12 warns of fork with threads: the point of the tests
        warnings.simplefilter("ignore", DeprecationWarning)
        pid = os.fork()
    if pid == 0:  # the child: no pytest machinery, just the check and the exit code
        ok = False
        try:
            ok = check()
        finally:
            os._exit(0 if ok else 3)
    for _ in range(100):
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        threading.Event().wait(0.1)
    else:
        os.kill(pid, 9)
        os.waitpid(pid, 0)
        pytest.fail(f"HANG: the forked child did not finish {what} within 10 s")
    assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, f"child status {status}"


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is POSIX")
def test_a_forked_child_runs_parallel_kernels_after_the_parent_did():
    """The parent has run a parallel kernel (its pool started); a forked child (the readers' watchdogs fork)
    runs one too and exits cleanly within 10 s (GNU OpenMP aborts the child here)."""
    a = np.arange(50_000, dtype=np.int64)
    with _threads.using_threads(2):
        assert _parallel_sum_of_squares(a) == _expected(a)

    def check():
        with _threads.using_threads(2):
            return _parallel_sum_of_squares(a) == _expected(a)

    _in_forked_child(check, "its parallel kernel")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork is POSIX")
def test_a_forked_child_has_a_side_thread_of_its_own():
    """The parent's side thread ran work; in a forked child, where that thread does not exist, work given to the
    side thread still runs (the parent's executor would wait for it forever)."""
    assert _threads.side_thread().submit(lambda: 6 * 7).result(timeout=10) == 42
    _in_forked_child(lambda: _threads.side_thread().submit(lambda: 6 * 7).result() == 42, "work on the side thread")


def test_counts_set_inside_and_restored_after():
    cv2 = pytest.importorskip("cv2")
    cv2_before = cv2.getNumThreads()
    with _threads.using_threads(2):
        numba_before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        with _threads.using_threads(2):
            assert numba.get_num_threads() == min(2, _threads.pool_size())
            assert cv2.getNumThreads() == min(2, _threads.pool_size())
        assert numba.get_num_threads() == 1 and cv2.getNumThreads() == cv2_before
        with _threads.using_threads(1):  # one thread: OpenCV's set, numba's left alone (serial kernels run)
            assert cv2.getNumThreads() == 1 and numba.get_num_threads() == 1
        with _threads.using_threads(_threads.pool_size() + 5):  # capped at the pool
            assert numba.get_num_threads() == _threads.pool_size()
        with pytest.raises(RuntimeError), _threads.using_threads(2):  # restored on the way out of an error too
            raise RuntimeError
        assert numba.get_num_threads() == 1 and cv2.getNumThreads() == cv2_before
    finally:
        numba.set_num_threads(numba_before)


def test_a_matcher_runs_feed_and_flush_with_its_threads(monkeypatch):
    """``StreamMatcher.feed``/``flush`` run ``_feed``/``_flush`` with numba's count at the matcher's threads."""
    from cvstereo.matchers.registry import create_matcher
    from cvstereo.model.events import make_events

    seen = []
    m = create_matcher("event-area", threads=2)
    cls = type(m)
    feed, flush = cls._feed, cls._flush
    monkeypatch.setattr(cls, "_feed", lambda self, a, b: (seen.append(numba.get_num_threads()), feed(self, a, b))[1])
    monkeypatch.setattr(cls, "_flush", lambda self: (seen.append(numba.get_num_threads()), flush(self))[1])
    ev = make_events([0, 10], [50, 51], [5, 5], [1, 1])
    m.feed(ev, ev)
    m.flush()
    assert seen == [min(2, _threads.pool_size())] * 2
