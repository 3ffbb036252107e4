"""Hostile use of the streaming protocol (issue 27): packets after the end of the stream, nonsense ``until``.

``flush()`` ends a stream: a packet fed after it would be matched without the state ``flush`` emptied (for
event-time a match near the cut was lost), so every registered matcher and variant must refuse it in one line
that says to make a new matcher. ``until`` promises that no later event comes before it: it must be a whole
number of microseconds an int64 holds; anything else is refused in one line naming ``until``, as a bad packet
is, and leaves the matcher as it was.

Each failing case's message starts with its kind (``tests/_hostile.py``): SILENT (accepted), MESSAGE (refused
in words that do not name ``until`` / the end of the stream, or on several lines), TRACEBACK (an exception
that is no ValueError, which a caller catching bad input would not catch).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from cvstereo.matches import concat_matches
from cvstereo.pipeline import match
from cvstereo.recording import Recording
from cvstereo.registry import DEFAULT_METHOD, METHODS, available_methods, create_matcher, matcher_class

from tests._hostile_calls import refused as refused_by
from tests._io_helpers import textured_blobs

pytestmark = pytest.mark.timeout(120)

W = 40_000
#: Every registered matcher and variant that can be built here (an optional extra may be missing).
VARIANTS = [(m, v) for m in METHODS if m in available_methods() for v in matcher_class(m).variants]


@pytest.fixture(scope="module")
def blobs() -> Recording:
    """Four 40 ms windows of textured blobs at a disparity of 13 px (frame and event matchers answer)."""
    return textured_blobs(0, 4, window_us=W)


def _slice(rec: Recording, t0: int, t1: int) -> tuple[np.ndarray, np.ndarray]:
    return tuple(ev[(ev["t"] >= t0) & (ev["t"] < t1)] for ev in (rec.left, rec.right))


#: Every refusal here is a ValueError (StreamEndedError, the until check), as a bad packet is: anything else escaping
#: is a TRACEBACK.
refused = functools.partial(refused_by, errors=(ValueError,))


# ------------------------------------------------------------------------------------------- after flush

@pytest.mark.parametrize(("method", "variant"), VARIANTS, ids=[f"{m}-{v}" for m, v in VARIANTS])
def test_feed_after_flush_is_refused(blobs, method, variant):
    """The first two windows, flush, then the rest: refused, and what was returned is the whole stream's
    answer on those two windows (a fresh matcher on them alone)."""
    head, tail = _slice(blobs, 0, 2 * W), _slice(blobs, 2 * W, 4 * W)
    m = create_matcher(method, variant)
    got = concat_matches([m.feed(*head), m.flush()])
    refused(lambda: m.feed(*tail), "flush", "new matcher")
    want = match(Recording(*head), method=method, variant=variant).matches
    np.testing.assert_array_equal(got, want)
    assert m.flush().size == 0, "SILENT: a second flush returned matches again"


def test_empty_packet_after_flush_is_refused(blobs):
    m = create_matcher("event-time")
    m.feed(*_slice(blobs, 0, W))
    m.flush()
    refused(lambda: m.feed(blobs.left[:0], blobs.right[:0], until=5 * W), "flush", "new matcher")


def test_refused_feed_after_flush_changes_nothing(blobs):
    """event-time took packets after flush and lost a match near the cut; refused, it keeps its count and
    watermark (a later flush still returns nothing)."""
    m = create_matcher("event-time")
    m.feed(*_slice(blobs, 0, 2 * W))
    m.flush()
    seen, mark = m.input_events, m.watermark
    refused(lambda: m.feed(*_slice(blobs, 2 * W, 4 * W)), "flush")
    assert (m.input_events, m.watermark) == (seen, mark), "SILENT: the refused packet was counted"
    assert m.flush().size == 0, "SILENT: matches after the end"


# ------------------------------------------------------------------------------------------------ until

BAD_UNTIL = {
    "inf": float("inf"),
    "minus-inf": float("-inf"),
    "nan": float("nan"),
    "numpy-nan": np.float64("nan"),
    "string": "soon",
    "digits-string": "80000",
    "fraction": 80_000.5,
    "numpy-fraction": np.float64(80_000.25),
    "beyond-int64": 2**63,
    "below-int64": -(2**63) - 1,
    "numpy-uint64-max": np.uint64(2**64 - 1),
    "float-beyond-int64": 1e300,
    "bool": True,
    "bytes": b"80000",
    "list": [80_000],
}


@pytest.mark.parametrize("value", list(BAD_UNTIL.values()), ids=list(BAD_UNTIL))
def test_until_that_is_no_time_is_refused_and_changes_nothing(blobs, value):
    m = create_matcher(DEFAULT_METHOD)
    left, right = _slice(blobs, 0, W)
    refused(lambda: m.feed(left, right, until=value), "until")
    assert m.watermark is None and m.input_events == 0, "SILENT: the refused packet was taken"
    # Still usable: the same packet with a good until gives what a fresh matcher gives.
    fresh = create_matcher(DEFAULT_METHOD)
    np.testing.assert_array_equal(m.feed(left, right, until=W), fresh.feed(left, right, until=W))


GOOD_UNTIL = {"int": 2 * W, "numpy-int64": np.int64(2 * W), "numpy-uint32": np.uint32(2 * W),
              "whole-float": float(2 * W), "numpy-whole-float": np.float64(2 * W)}


@pytest.mark.parametrize("value", list(GOOD_UNTIL.values()), ids=list(GOOD_UNTIL))
def test_until_as_any_whole_number_closes_the_windows_before_it(blobs, value):
    """The events of the first window alone, with until at the end of the second: both windows are final
    (the second empty), so the answer is that of the whole stream's first window (independent run)."""
    m = create_matcher(DEFAULT_METHOD)
    got = m.feed(*_slice(blobs, 0, W), until=value)
    assert m.watermark == 2 * W and isinstance(m.watermark, int)
    whole = match(blobs, method=DEFAULT_METHOD).matches
    want = whole[whole["t"] <= W]
    assert want.size > 0
    np.testing.assert_array_equal(got, want)
