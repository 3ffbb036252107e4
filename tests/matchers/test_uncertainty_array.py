"""A matcher that rates its matches (fused) gets an `uncertainty` array beside them, in the matches' order,
through match() and into the matches file (formats.md: optional per-match arrays)."""

from __future__ import annotations

import numpy as np

from cvstereo.io import read_matches, write_matches
from cvstereo.matchers.registry import create_matcher
from cvstereo.run import match
from cvstereo.simulate import simulate_preset


def test_uncertainty_follows_the_matches(tmp_path):
    rec = simulate_preset("1arm-100cm", seconds=0.4, seed=2)
    result = match(rec, method="fused", packet_us=7_000, rig_check=False)   # the matcher's own stream
    unc = result.arrays["uncertainty"]
    assert len(result) > 100 and unc.dtype == np.float32 and unc.shape == result.matches.shape
    # The same as feeding the matcher directly and sorting by time, values and order.
    m = create_matcher("fused", resolution=rec.resolution)
    found = [m.feed(rec.left, rec.right), m.flush()]
    direct = np.concatenate(found)
    order = np.argsort(direct["t"], kind="stable")
    np.testing.assert_array_equal(direct[order], result.matches)
    np.testing.assert_array_equal(m.take_uncertainty()[order], unc)
    write_matches(tmp_path / "m.npz", result.matches, result.meta, arrays=result.arrays)
    np.testing.assert_array_equal(read_matches(tmp_path / "m.npz").arrays["uncertainty"], unc)


def test_matchers_without_ratings_have_no_uncertainty():
    rec = simulate_preset("1arm-100cm", seconds=0.2, seed=2)
    assert "uncertainty" not in match(rec, method="event-area").arrays
