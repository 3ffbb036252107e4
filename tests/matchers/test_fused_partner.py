"""Fused's partner test against a direct computation: each band's median by np.median of its values."""

import numpy as np
import pytest

from cvstereo.matchers.fused._constants import CONSISTENT_MAX_UNCERTAINTY
from cvstereo.matchers.fused._partner import unpartnered, unpartnered_parallel
from cvstereo.matchers.fused.params import BORDER_MIN_ANSWERS


def _direct(x, y, disparity, uncertainty, rows):
    out = np.zeros(x.size, bool)
    consistent = uncertainty <= CONSISTENT_MAX_UNCERTAINTY
    for row in np.unique(y):
        band = consistent & (np.abs(y.astype(np.int64) - row) <= rows)
        if band.sum() >= BORDER_MIN_ANSWERS:
            out[y == row] = x[y == row] < np.median(disparity[band])
    return out


def _answers(seed, n, height=40, width=64, ties=False):
    rng = np.random.default_rng(seed)
    y = np.sort(rng.integers(0, height, n)).astype(np.int64)
    x = rng.integers(0, width, n).astype(np.int64)
    order = np.lexsort((x, y))  # raster order, as the kernel gives its answers
    disparity = rng.integers(0, 30, n).astype(np.float64) if ties else rng.uniform(0, 30, n)
    uncertainty = rng.choice([0.0, 0.25, 0.5, 0.75, 1.0], n)
    return x[order], y[order], disparity, uncertainty


@pytest.mark.parametrize("rows", [0, 1, 2, 5])
@pytest.mark.parametrize("ties", [False, True])  # many equal disparities: the merge's choice among equals
def test_the_band_median_is_the_sorted_bands_median(rows, ties):
    for seed in range(5):
        x, y, d, u = _answers(seed, 600, ties=ties)
        expected = _direct(x, y, d, u, rows)
        assert expected.any() and not expected.all()  # the case decides both ways
        assert np.array_equal(unpartnered(x, y, d, u, rows, 1), expected)
        for chunks in (1, 3):
            assert np.array_equal(unpartnered_parallel(x, y, d, u, rows, chunks), expected)


def test_sparse_bands_are_not_judged_and_no_answers_give_none():
    x, y, d, u = _answers(0, 40, height=40)  # about one answer a row: no band reaches the minimum at rows=0
    assert not unpartnered(x, y, d, u, 0, 1).any()
    empty = np.zeros(0, np.int64)
    assert unpartnered(empty, empty, np.zeros(0), np.zeros(0), 2, 1).size == 0
