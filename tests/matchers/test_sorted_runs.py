"""The sorted-runs history's quantiles equal np.quantile of the concatenated values, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from cvstereo.matchers._shared.sorted_runs import SortedRuns


def _values(rng, n, kind):
    if kind == "float32-like":  # filtered frame values: few distinct values, many ties
        return np.abs(rng.integers(-6, 7, n) * np.float32(0.40261996)).astype(np.float64)
    if kind == "zeros":
        return np.zeros(n)
    return rng.exponential(1.0, n)


@pytest.mark.parametrize("kind", ["continuous", "float32-like", "zeros"])
@pytest.mark.parametrize("q", [0.9, 0.5, 0.01, 0.999, 1.0, 1, 0.0])
def test_quantile_equals_numpy_of_the_live_runs(rng, kind, q):
    runs, live = SortedRuns(), []
    for step in range(60):
        v = _values(rng, int(rng.integers(0, 3000)), kind)  # runs on both sides of RADIX_MIN
        runs.append(v)
        live.append(v)
        while len(live) > 1 and rng.random() < 0.4:  # drop the oldest runs now and then
            runs.popleft()
            live.pop(0)
        assert len(runs) == len(live)
        assert runs.size == sum(x.size for x in live)
        if runs.size:
            expected = float(np.quantile(np.concatenate(live), q))
            got = runs.quantile(q)
            assert got == expected or (np.isnan(got) and np.isnan(expected)), (step, got, expected)
            assert np.signbit(got) == np.signbit(expected)


def test_runs_sorted_late_give_the_same_quantiles(rng):
    """Runs are sorted by the first quantile after they arrive: quantiles asked only now and then, after
    unsorted runs were dropped or moved to a larger buffer, still equal numpy's."""
    runs, live = SortedRuns(), []
    for step in range(300):
        v = _values(rng, int(rng.integers(0, 900)), "continuous")
        runs.append(v)
        live.append(v)
        while len(live) > 1 and rng.random() < 0.45:
            runs.popleft()
            live.pop(0)
        if rng.random() < 0.15 and runs.size:
            assert runs.quantile(0.9) == float(np.quantile(np.concatenate(live), 0.9)), step


@pytest.mark.parametrize("kind", ["continuous", "float32-like"])
def test_many_short_runs_and_every_quantile(rng, kind):
    """Up to 250 runs of 0-5 values (ties across runs, empty runs): every rank's pair of neighbours is right."""
    runs, live = SortedRuns(), []
    for _ in range(int(rng.integers(1, 250))):
        v = _values(rng, int(rng.integers(0, 6)), kind)
        runs.append(v)
        live.append(v)
    allv = np.concatenate(live)
    if allv.size == 0:
        return
    for q in np.linspace(0.0, 1.0, 41):
        assert runs.quantile(q) == float(np.quantile(allv, q)), q


def test_the_quantile_of_some_runs_is_that_of_their_values(rng):
    """``every``/``first``: the runs of one part, as a history of several parts per step keeps them."""
    runs, live = SortedRuns(), []
    for _ in range(3 * int(rng.integers(1, 40))):
        v = _values(rng, int(rng.integers(0, 1500)), "continuous")
        runs.append(v)
        live.append(v)
    for q in (0.0, 0.5, 0.9, 1.0):
        got = runs.part_quantiles(q, 3, 1)
        for first in range(3):
            part = np.concatenate(live[first::3])
            assert got[first] == float(np.quantile(part, q)) if part.size else np.isnan(got[first])
    sizes = [sum(v.size for v in live[first::3]) for first in range(3)]
    got = runs.part_quantiles(0.9, 3, sorted(sizes)[1])  # the smallest part is too small
    assert [np.isnan(g) for g in got] == [n < sorted(sizes)[1] for n in sizes]
    assert runs.first_size(3) == sum(v.size for v in live[:3])
    runs.popleft(3)
    assert runs.size == sum(v.size for v in live[3:])


def test_small_cases_by_hand():
    runs = SortedRuns()
    runs.append(np.array([5.0, 1.0, 3.0]))  # any order: the run is sorted on arrival
    runs.append(np.array([2.0, 4.0]))
    assert runs.quantile(0.9) == pytest.approx(4.6)  # 4 + 0.6 * (5 - 4)
    assert runs.quantile(0.5) == 3.0
    runs.popleft()
    assert runs.quantile(0.25) == 2.5  # 2 + 0.25 * (4 - 2)
    assert runs.first_size() == 2


def test_empty_history_says_so():
    with pytest.raises(ValueError, match="no values"):
        SortedRuns().quantile(0.9)


@pytest.mark.parametrize("kind", ["continuous", "float32-like", "zeros", "wide"])
def test_the_radix_sort_of_bit_patterns_equals_numpy_sort(rng, kind):
    from cvstereo.matchers._shared.sorted_runs import _sort_patterns

    for n in (0, 1, 2, 255, 256, 5000):
        if kind == "wide":  # subnormals to huge: every byte of the patterns varies
            v = np.abs(rng.normal(0, 1, n)) * 10.0 ** rng.integers(-320, 300, n)
        else:
            v = _values(rng, n, kind)
        bits = v.copy().view(np.int64)
        _sort_patterns(bits, np.empty(n, np.int64))
        assert np.array_equal(bits.view(np.float64), np.sort(v))
