"""Same matches on any number of threads (issue 28 item 1): every registered matcher and variant, threads 1, 2
and 3, whole streams and packet cuts, array equality against the one-thread run.

The methods come from the registry, so a matcher that gains a parallel path is covered without a change here;
one without a parallel path passes trivially. ``test_a_thread_dependent_matcher_is_caught`` shows the check
fails where the matches follow the thread count.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cvstereo.matchers.registry import available_methods, create_matcher, matcher_class
from cvstereo.model.events import make_events
from cvstereo.model.matches import concat_matches
from cvstereo.model.recording import Recording
from tests._io_helpers import textured_blobs

THREAD_COUNTS = (1, 2, 3)
COMBOS = [(m, v) for m in available_methods() for v in matcher_class(m).variants]


def _wide_scene(seed: int = 1) -> Recording:
    """346x260, 0.2 s: textured blobs shifted 20 px plus uniform noise over the whole sensor, so that every row
    band and chunk of a parallel kernel gets work."""
    rng = np.random.default_rng(seed)
    parts_l, parts_r = [], []
    for k in range(5):
        for _ in range(40):
            x0, y0 = rng.integers(30, 300), rng.integers(5, 250)
            xs, ys = x0 + rng.integers(0, 6, 30), y0 + rng.integers(0, 5, 30)
            t = k * 40_000 + rng.integers(0, 40_000, 30)
            p = rng.integers(0, 2, 30)
            parts_l.append((t, xs, ys, p))
            parts_r.append((t + rng.integers(0, 50, 30), xs - 20, ys, p))
    noise = 3000
    for parts in (parts_l, parts_r):
        parts.append((rng.integers(0, 200_000, noise), rng.integers(0, 346, noise), rng.integers(0, 260, noise),
                      rng.integers(0, 2, noise)))

    def events(parts):
        t, x, y, p = (np.concatenate(c) for c in zip(*parts, strict=True))
        order = np.argsort(t, kind="stable")
        return make_events(t[order], x[order], y[order], p[order])

    return Recording(events(parts_l), events(parts_r), resolution=(346, 260))


SCENES = {"blobs-128": textured_blobs(0, 6), "wide-346": _wide_scene()}


def run_cut(method: str, variant: str | None, rec: Recording, threads: int, cuts=()) -> np.ndarray:
    """All matches of ``method`` on ``rec`` fed as time slices ending at ``cuts`` (then the rest), then flushed."""
    m = create_matcher(method, variant, resolution=rec.resolution, threads=threads)
    bounds = [*sorted(set(int(c) for c in cuts)), None]
    parts, start = [], None
    for end in bounds:
        pick = [(ev["t"] >= (start if start is not None else np.iinfo(np.int64).min))
                & (ev["t"] < (end if end is not None else np.iinfo(np.int64).max)) for ev in (rec.left, rec.right)]
        parts.append(m.feed(rec.left[pick[0]], rec.right[pick[1]], until=end))
        start = end
    parts.append(m.flush())
    return concat_matches(parts)


def differences(method: str, variant: str | None, rec: Recording, counts=THREAD_COUNTS, cuts=()) -> list[str]:
    """The thread counts whose matches differ from one thread's (empty: all equal)."""
    one = run_cut(method, variant, rec, 1, cuts)
    return [f"threads={n}: {len(got)} matches vs {len(one)}" for n in counts if n != 1
            for got in [run_cut(method, variant, rec, n, cuts)] if not np.array_equal(got, one)]


@pytest.mark.parametrize("scene", list(SCENES))
@pytest.mark.parametrize(("method", "variant"), COMBOS, ids=[f"{m}-{v}" for m, v in COMBOS])
def test_same_matches_on_1_2_and_3_threads(method, variant, scene):
    rec = SCENES[scene]
    assert differences(method, variant, rec) == []


def test_the_scenes_give_every_thesis_matcher_work():
    """The equality above is not over empty results: each thesis matcher and fused answers on some scene."""
    for method in ("frame", "frame-area", "event-time", "event-area", "event-vector", "fused"):
        assert any(len(run_cut(method, None, rec, 1)) for rec in SCENES.values()), method


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(method=st.sampled_from(available_methods()), threads=st.integers(2, 4),
       cuts=st.lists(st.integers(0, 200_000), max_size=6))
def test_packet_cuts_and_thread_counts_give_the_one_thread_matches(method, threads, cuts):
    rec = SCENES["wide-346"]
    whole = run_cut(method, None, rec, 1)
    assert np.array_equal(run_cut(method, None, rec, threads, cuts), whole)


def test_a_thread_dependent_matcher_is_caught(monkeypatch):
    """A matcher whose matches follow ``threads`` (a band split that loses the rows at band edges, say) fails
    the check: the comparison is not vacuous."""
    cls = matcher_class("event-area")
    feed = cls._feed

    def lossy(self, left, right):
        found = feed(self, left, right)
        return found[: len(found) - (self.threads - 1)] if len(found) >= self.threads else found

    monkeypatch.setattr(cls, "_feed", lossy)
    assert differences("event-area", None, SCENES["blobs-128"]) != []
