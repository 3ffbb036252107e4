"""What the real-time serial tests may expect of event times on a loaded machine.

A reader descheduled for more than a 16-bit wrap (65.536 ms) cannot know how many wraps passed; the decoder
then counts the gap (``StreamDecoder.ambiguous``) instead of guessing silently. So: with nothing counted, every
time is exact; with gaps counted, every time before the first is exact and every later one is off by whole
wraps at most. Any silent error still fails.
"""

from __future__ import annotations

import numpy as np

WRAP = 1 << 16


def assert_times_exact_or_flagged(got_t, want_t, ambiguous):
    """``got_t`` equals ``want_t``, except from the first event listed in ``ambiguous`` on, where only whole
    wraps may differ."""
    got_t, want_t = np.asarray(got_t, np.int64), np.asarray(want_t, np.int64)
    assert got_t.shape == want_t.shape
    if not ambiguous:
        np.testing.assert_array_equal(got_t, want_t)
        return
    first = min(a[0] for a in ambiguous)
    err = got_t - want_t
    np.testing.assert_array_equal(err[:first], 0)
    np.testing.assert_array_equal(err % WRAP, 0)
