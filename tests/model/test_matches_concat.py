"""concat_matches copies the matches' bytes: the same result as numpy's field-wise concatenation."""

from __future__ import annotations

import numpy as np

from cvstereo.model.matches import MATCH_DTYPE, concat_matches, empty_matches, make_matches


def _random_matches(rng, n):
    return make_matches(np.sort(rng.integers(-10**9, 10**12, n)), rng.integers(-300, 700, n),
                        rng.integers(0, 480, n), rng.integers(0, 2, n), rng.integers(0, 2, n),
                        rng.normal(20.0, 30.0, n).astype(np.float32))


def test_concat_equals_numpy_field_by_field(rng):
    a, b, c = (_random_matches(rng, n) for n in (1, 257, 1000))
    parts = [a, None, empty_matches(), b[::-3], c[5:900]]  # strided and offset views too
    got = concat_matches(parts)
    expected = np.concatenate([a, b[::-3], c[5:900]])
    assert got.dtype == MATCH_DTYPE and got.shape == expected.shape
    for name in MATCH_DTYPE.names:
        np.testing.assert_array_equal(got[name], expected[name])
    got["x"][0] += 1  # a copy, not a view of the inputs
    assert a["x"][0] == expected["x"][0]


def test_concat_of_nothing_is_empty():
    assert concat_matches([]).shape == (0,) and concat_matches([None, empty_matches()]).dtype == MATCH_DTYPE
