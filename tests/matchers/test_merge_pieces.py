"""The merged stream built in pieces at once (a matcher on several threads) is the one order of the references'
merge (a stable sort on time and camera), whatever the number of pieces, with dropped polarities left out."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cvstereo.matchers._shared.merge_order import ROW_CAM, ROW_INDEX, ROW_SLOT, ROW_T, merged_stream
from cvstereo.matchers._shared.reference_frames import merged_events
from cvstereo.model.events import make_events


def _events(rng, n, span):
    return make_events(np.sort(rng.integers(0, span, n)), rng.integers(0, 64, n), rng.integers(0, 8, n),
                       rng.integers(0, 2, n))


@settings(deadline=None, max_examples=60)
@given(nl=st.integers(0, 60), nr=st.integers(0, 60), span=st.integers(1, 40), pieces=st.integers(1, 9),
       slots=st.sampled_from([(0, 1), (0, 0), (-1, 0), (0, -1)]), seed=st.integers(0, 2**16))
def test_every_number_of_pieces_gives_the_references_order(nl, nr, span, pieces, slots, seed):
    rng = np.random.default_rng(seed)
    left, right = _events(rng, nl, span), _events(rng, nr, span)
    slot_of_p = np.array(slots, np.int64)
    columns = [ev[f] for ev in (left, right) for f in ("t", "x", "y", "p")]
    stream = merged_stream(*columns, slot_of_p, pieces=pieces)
    expected = [(cam, i, ev["t"], slot_of_p[int(ev["p"] > 0)]) for cam, i, ev in merged_events(left, right)
                if slot_of_p[int(ev["p"] > 0)] >= 0]
    got = list(zip(*(stream[row].tolist() for row in (ROW_CAM, ROW_INDEX, ROW_T, ROW_SLOT)), strict=True))
    assert got == [tuple(int(v) for v in e) for e in expected]
